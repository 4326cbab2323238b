"""In-memory mesh files: binary PLY out (doubles, exact), binary STL out, OFF in (GetMesh's
text); polygons to triangles."""
import struct

import numpy as np


def _face_ids(f, what):
    a = np.asarray(f)
    if a.size and not np.issubdtype(a.dtype, np.integer):
        raise TypeError(f"{what}: vertex ids must be integers, got {a.dtype}")
    return a.astype(np.int64, copy=False)


def triangulate(F):
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
        return np.stack([a[:, [0, c, c + 1]] for c in range(1, k - 1)], axis=1).reshape(-1, 3)
    tris = []
    for i, f in enumerate(F):
        p = _face_ids(f, f"F[{i}]").reshape(-1)
        if p.size < 3:
            raise ValueError(f"F[{i}]: a face needs at least 3 vertices, got {p.size}")
        tris.extend((p[0], p[c], p[c + 1]) for c in range(1, p.size - 1))
    return np.asarray(tris, dtype=np.int64).reshape(-1, 3)


def ply_bytes(V, F):
    """A binary little-endian PLY of V (n×3, written as float64) and F (m×3 vertex ids;
    quads and other polygons are fan-triangulated, see triangulate()); the server keeps the
    vertex order, so ids and frame rows are V's rows."""
    try:
        V = np.ascontiguousarray(V, dtype="<f8")
    except (TypeError, ValueError):
        raise TypeError(f"V: expected an n×3 array of numbers, got {type(V).__name__}") from None
    if V.ndim != 2 or V.shape[1] != 3:
        raise ValueError(f"V: expected an n×3 array, got shape {V.shape}")
    F = triangulate(F)
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment hdeform python client\n"
        f"element vertex {len(V)}\nproperty double x\nproperty double y\nproperty double z\n"
        f"element face {len(F)}\nproperty list uchar int vertex_indices\nend_header\n")
    faces = np.empty(len(F), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    faces["n"] = 3
    faces["i"] = F
    return header.encode("ascii") + V.tobytes() + faces.tobytes()


def parse_off(text):
    """(V float64 n×3, F int64 m×3) from an OFF file's text (triangles only)."""
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
    rows = np.asarray(tokens[pos:pos + 4 * m], dtype=np.int64).reshape(m, 4)
    if m and not (rows[:, 0] == 3).all():
        raise ValueError("OFF: only triangles are parsed")
    return V, rows[:, 1:]


def stl_bytes(V, F):
    """A binary STL of V (n×3) and F (m×3): float32 corners (STL's own precision) and facet
    normals. STL has no vertex ids: a reader welds equal positions, in order of first use."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    tri = V[F]  # m×3×3
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, length, out=np.zeros_like(n), where=length > 0)
    rec = np.zeros(len(F), dtype=[("n", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    rec["n"] = n
    rec["v"] = tri
    header = b"hdeform python client".ljust(80, b" ")  # not "solid": never mistaken for ASCII
    return header + struct.pack("<I", len(F)) + rec.tobytes()
