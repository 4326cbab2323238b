# The generated stubs deform_pb2.py and deform_pb2_grpc.py go here (pip install generates
# them; they are not in git). In the build tree CMake writes them to another hdeform/v1
# folder on PYTHONPATH, which this package's __path__ takes in.
from pkgutil import extend_path

__path__ = extend_path(__path__, __name__)
