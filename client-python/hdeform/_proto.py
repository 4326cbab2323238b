"""The generated hdeform.v1 stubs, with a message that says how to make them when missing."""
try:
    from hdeform.v1 import deform_pb2 as pb  # noqa: F401
    from hdeform.v1 import deform_pb2_grpc as pb_grpc  # noqa: F401
except ImportError as e:  # pragma: no cover - depends on the installation
    raise ImportError(
        "hdeform: the generated gRPC stubs hdeform/v1/deform_pb2.py are missing. Install the "
        "package (pip install --no-build-isolation --no-deps ./client-python generates them), "
        "or generate them into DIR and put DIR on PYTHONPATH: protoc -I proto --python_out=DIR "
        "--grpc_out=DIR --plugin=protoc-gen-grpc=$(which grpc_python_plugin) "
        "proto/hdeform/v1/deform.proto (" + str(e) + ")") from e
