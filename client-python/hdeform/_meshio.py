"""In-memory mesh files: binary PLY out (doubles, exact), binary STL out, OFF in (GetMesh's
text); polygons to triangles."""
import struct
from typing import Any, List, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

Int64Array = npt.NDArray[np.int64]
Float64Array = npt.NDArray[np.float64]
# Faces: an m×k array (k ≥ 3) or a list of polygons of any sizes.
FacesLike = Union[npt.ArrayLike, Sequence[Sequence[int]]]


def _face_ids(f: Any, what: str) -> Int64Array:
    a = np.asarray(f)
    if a.size and not np.issubdtype(a.dtype, np.integer):
        raise TypeError(f"{what}: vertex ids must be integers, got {a.dtype}")
    out: Int64Array = a.astype(np.int64, copy=False)
    return out


def triangulate(F: FacesLike) -> Int64Array:
    """Triangles (m'×3 int64) from faces: an m×k array (k ≥ 3: triangles, quads, …) or a list
    of polygons of any sizes. A polygon (p0, p1, …, pk-1) becomes the fan (p0, pi, pi+1), as
    the server's OBJ/OFF/PLY readers triangulate: right for convex polygons; a concave one
    gets overlapping triangles, so triangulate those yourself."""
    if isinstance(F, np.ndarray) or (isinstance(F, (list, tuple)) and F and
                                     all(np.ndim(f) == 1 and len(f) == len(F[0]) for f in F)):
        a = _face_ids(F, "F")
        if a.ndim != 2 or (a.size and a.shape[1] < 3):
            raise ValueError(f"F: expected an m×3 array of triangles (or m×k polygons, k ≥ 3), "
                             f"got shape {a.shape}")
        if a.size == 0:
            return a.reshape(0, 3)
        k = a.shape[1]
        fan: Int64Array = np.stack([a[:, [0, c, c + 1]] for c in range(1, k - 1)],
                                   axis=1).reshape(-1, 3)
        return fan
    tris: List[Tuple[Any, Any, Any]] = []
    for i, f in enumerate(F):  # type: ignore[arg-type]  # a sequence of polygons here
        p = _face_ids(f, f"F[{i}]").reshape(-1)
        if p.size < 3:
            raise ValueError(f"F[{i}]: a face needs at least 3 vertices, got {p.size}")
        tris.extend((p[0], p[c], p[c + 1]) for c in range(1, p.size - 1))
    out: Int64Array = np.asarray(tris, dtype=np.int64).reshape(-1, 3)
    return out


def ply_bytes(V: npt.ArrayLike, F: FacesLike) -> bytes:
    """A binary little-endian PLY of V (n×3, written as float64) and F (m×3 vertex ids;
    quads and other polygons are fan-triangulated, see triangulate()); the server keeps the
    vertex order, so ids and frame rows are V's rows."""
    try:
        P = np.ascontiguousarray(V, dtype="<f8")
    except (TypeError, ValueError):
        raise TypeError(f"V: expected an n×3 array of numbers, got {type(V).__name__}") from None
    if P.ndim != 2 or P.shape[1] != 3:
        raise ValueError(f"V: expected an n×3 array, got shape {P.shape}")
    T = triangulate(F)
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment hdeform python client\n"
        f"element vertex {len(P)}\nproperty double x\nproperty double y\nproperty double z\n"
        f"element face {len(T)}\nproperty list uchar int vertex_indices\nend_header\n")
    faces = np.empty(len(T), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    faces["n"] = 3
    faces["i"] = T
    return header.encode("ascii") + P.tobytes() + faces.tobytes()


def parse_off(text: Union[str, bytes]) -> Tuple[Float64Array, Int64Array]:
    """(V float64 n×3, F int64 m×3) from an OFF file's text. The server writes an upload's
    polygons back as they were; each becomes the fan the server solved on (triangulate()), so F
    is the session's triangles in frame order."""
    if isinstance(text, bytes):
        text = text.decode("ascii")
    tokens = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            tokens.extend(line.split())
    if not tokens or tokens[0] != "OFF":
        raise ValueError("not an OFF file")
    n, m = int(tokens[1]), int(tokens[2])
    pos = 4
    V = np.asarray(tokens[pos:pos + 3 * n], dtype=np.float64).reshape(n, 3)
    pos += 3 * n
    ids = np.asarray(tokens[pos:], dtype=np.int64)
    faces: List[Int64Array] = []
    at = 0
    for f in range(m):
        if at >= ids.size:
            raise ValueError(f"OFF: face {f} of {m} is missing")
        k = int(ids[at])
        if k < 3 or at + 1 + k > ids.size:
            raise ValueError(f"OFF: face {f} has {k} corners (at least 3, all present)")
        faces.append(ids[at + 1:at + 1 + k])
        at += 1 + k
    if all(len(f) == 3 for f in faces):
        F: Int64Array = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
        return V, F
    return V, triangulate(faces)


def stl_bytes(V: npt.ArrayLike, F: npt.ArrayLike) -> bytes:
    """A binary STL of V (n×3) and F (m×3): float32 corners (STL's own precision) and facet
    normals. STL has no vertex ids: a reader welds equal positions, in order of first use."""
    P = np.asarray(V, dtype=np.float64)
    T = np.asarray(F, dtype=np.int64)
    tri = P[T]  # m×3×3
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, length, out=np.zeros_like(n), where=length > 0)
    rec = np.zeros(len(T), dtype=[("n", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    rec["n"] = n
    rec["v"] = tri
    header = b"hdeform python client".ljust(80, b" ")  # not "solid": never mistaken for ASCII
    return header + struct.pack("<I", len(T)) + rec.tobytes()
