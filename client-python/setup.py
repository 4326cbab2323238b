"""Generates the gRPC stubs (hdeform/v1/deform_pb2*.py) from ../proto at build time with
protoc and grpc_python_plugin (Debian: protobuf-compiler, protobuf-compiler-grpc); the rest of
the metadata is in pyproject.toml. HDEFORM_PROTO_DIR overrides the proto folder (one holding
hdeform/v1/deform.proto)."""
import os
import shutil
import subprocess

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = os.path.dirname(os.path.abspath(__file__))


class BuildWithStubs(build_py):
    def run(self):
        proto_dir = os.environ.get("HDEFORM_PROTO_DIR", os.path.join(HERE, "..", "proto"))
        proto = os.path.join(proto_dir, "hdeform", "v1", "deform.proto")
        protoc = shutil.which("protoc")
        plugin = shutil.which("grpc_python_plugin")
        if not (os.path.exists(proto) and protoc and plugin):
            raise SystemExit(f"hdeform: need {proto}, protoc and grpc_python_plugin "
                             "(apt-get install protobuf-compiler protobuf-compiler-grpc)")
        out = os.path.join(self.build_lib)
        os.makedirs(os.path.join(out, "hdeform", "v1"), exist_ok=True)
        subprocess.check_call([protoc, "-I", proto_dir, f"--python_out={out}",
                               f"--grpc_out={out}", f"--plugin=protoc-gen-grpc={plugin}",
                               proto])
        super().run()


setup(cmdclass={"build_py": BuildWithStubs})
