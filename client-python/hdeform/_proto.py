"""The generated hdeform.v1 stubs, with a message that says how to make them when missing."""
import importlib
from typing import Any

try:
    # By name: the modules are generated at build time (mypy checks the package without them)
    _pb = importlib.import_module("hdeform.v1.deform_pb2")
    _pb_grpc = importlib.import_module("hdeform.v1.deform_pb2_grpc")
except ImportError as e:  # pragma: no cover - depends on the installation
    raise ImportError(
        "hdeform: the generated gRPC stubs hdeform/v1/deform_pb2.py are missing. Install the "
        "package (pip install --no-build-isolation --no-deps ./client-python generates them), "
        "or generate them into DIR and put DIR on PYTHONPATH: protoc -I proto --python_out=DIR "
        "--grpc_out=DIR --plugin=protoc-gen-grpc=$(which grpc_python_plugin) "
        "proto/hdeform/v1/deform.proto (" + str(e) + ")") from e

# Generated at build time and untyped (protobuf builds the message classes at import): the
# hand-written modules see them as Any and convert what they return to typed values.
pb: Any = _pb
pb_grpc: Any = _pb_grpc
