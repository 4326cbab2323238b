"""hdeform — Python client of hdeform-server (harmonic surface deformation over gRPC).

    import hdeform
    with hdeform.connect() as hd:            # a private local hdeform-server
        with hd.open("cactus") as s:
            s.constrain(fixed=hdeform.sel_file("cactus.sel", 0),
                        handles=[hdeform.sel_file("cactus.sel", 2)])
            s.set_beta(0.1)                  # an RPC and a factorization
            frame = s.update(translate=(0, 0, 0.1))
            frame.V, frame.N, frame.measures  # V, N: the solve's doubles

See docs/python.md.
"""
import importlib
import sys
from pkgutil import extend_path

try:  # the three apt packages, checked first so that a missing one names the fix
    for _module in ("grpc", "google.protobuf", "numpy"):
        importlib.import_module(_module)
except ImportError as _e:
    raise ImportError(
        f"hdeform needs grpc, protobuf and numpy, and {sys.executable} has no "
        f"{_e.name or _e}: use Debian's /usr/bin/python3 with "
        "`apt-get install python3-grpcio python3-protobuf python3-numpy` (or a venv made by "
        "`/usr/bin/python3 -m venv --system-site-packages`); a pyenv or other python3 first "
        "on PATH does not see the apt packages (docs/python.md, Install)", name=_e.name) from _e

# The generated stubs (hdeform/v1/deform_pb2*.py) live inside the installed package, or, in the
# build tree, in another sys.path entry's hdeform/ folder (CMake writes them to the build dir).
__path__ = extend_path(__path__, __name__)

from ._errors import (  # noqa: E402
    Error, ServerStartError, Cancelled, Unknown, InvalidArgument, DeadlineExceeded, NotFound,
    AlreadyExists, PermissionDenied, ResourceExhausted, FailedPrecondition, Aborted, OutOfRange,
    Unimplemented, Internal, Unavailable, DataLoss, Unauthenticated)
from ._selectors import (  # noqa: E402
    Selector, ids, base_ids, box, sphere, half_space, sel, sel_file, FIXED, HANDLE)
from ._transforms import Transform, transform, axis_angle, read_def  # noqa: E402
from ._frames import Encoding, Frame, FrameDecodeError, Measures  # noqa: E402
from ._records import (  # noqa: E402
    Beta, HistoryStep, Keyframe, RepairReport, RigExport, RigPoseError, Snapshot, Timeline)
from ._client import Client, Session, Watch, SweepRow, SweepResult, LibraryMesh, connect  # noqa: E402
from ._server import LocalServer, find_server  # noqa: E402
from ._meshio import ply_bytes, parse_off, stl_bytes, triangulate  # noqa: E402
from ._interop import from_meshio  # noqa: E402

__version__ = "0.1.0"

__all__ = [
    "connect", "Client", "Session", "Watch", "Frame", "FrameDecodeError", "Encoding",
    "Measures", "SweepRow", "SweepResult", "LibraryMesh", "LocalServer", "find_server",
    "Beta", "HistoryStep", "Keyframe", "Snapshot", "Timeline", "RigExport", "RigPoseError",
    "RepairReport", "from_meshio",
    "Selector", "ids", "base_ids", "box", "sphere", "half_space", "sel", "sel_file", "FIXED",
    "HANDLE", "Transform", "transform", "axis_angle", "read_def", "ply_bytes", "parse_off",
    "stl_bytes", "triangulate",
    "Error", "ServerStartError", "Cancelled", "Unknown", "InvalidArgument", "DeadlineExceeded",
    "NotFound", "AlreadyExists", "PermissionDenied", "ResourceExhausted", "FailedPrecondition",
    "Aborted", "OutOfRange", "Unimplemented", "Internal", "Unavailable", "DataLoss",
    "Unauthenticated",
]
