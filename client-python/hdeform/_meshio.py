"""In-memory mesh files: binary PLY out (doubles, exact), OFF in (GetMesh's text)."""
import numpy as np


def ply_bytes(V, F):
    """A binary little-endian PLY of V (n×3, written as float64) and F (m×3 vertex ids); the
    server keeps the vertex order, so ids and frame rows are V's rows."""
    V = np.ascontiguousarray(V, dtype="<f8")
    F = np.asarray(F)
    if V.ndim != 2 or V.shape[1] != 3:
        raise ValueError(f"V: expected an n×3 array, got shape {V.shape}")
    if F.ndim != 2 or F.shape[1] != 3:
        raise ValueError(f"F: expected an m×3 array of triangles, got shape {F.shape}")
    if F.size and not np.issubdtype(F.dtype, np.integer):
        raise TypeError(f"F: vertex ids must be integers, got {F.dtype}")
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
