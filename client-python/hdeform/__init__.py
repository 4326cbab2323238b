"""hdeform — Python client of hdeform-server (harmonic surface deformation over gRPC).

    import hdeform
    with hdeform.connect() as hd:            # a private local hdeform-server
        with hd.open("cactus") as s:
            s.constrain(fixed=hdeform.sel_file("cactus.sel", 0),
                        handles=[hdeform.sel_file("cactus.sel", 2)])
            s.beta = 0.1
            frame = s.update(translate=(0, 0, 0.1))
            frame.V, frame.N, frame.measures

See docs/python.md.
"""
from pkgutil import extend_path

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
from ._frames import Frame, Measures  # noqa: E402
from ._client import Client, Session, Watch, SweepRow, SweepResult, LibraryMesh, connect  # noqa: E402
from ._server import LocalServer, find_server  # noqa: E402
from ._meshio import ply_bytes, parse_off  # noqa: E402

__version__ = "0.1.0"

__all__ = [
    "connect", "Client", "Session", "Watch", "Frame", "Measures", "SweepRow", "SweepResult",
    "LibraryMesh", "LocalServer", "find_server",
    "Selector", "ids", "base_ids", "box", "sphere", "half_space", "sel", "sel_file", "FIXED",
    "HANDLE", "Transform", "transform", "axis_angle", "read_def", "ply_bytes", "parse_off",
    "Error", "ServerStartError", "Cancelled", "Unknown", "InvalidArgument", "DeadlineExceeded",
    "NotFound", "AlreadyExists", "PermissionDenied", "ResourceExhausted", "FailedPrecondition",
    "Aborted", "OutOfRange", "Unimplemented", "Internal", "Unavailable", "DataLoss",
    "Unauthenticated",
]
