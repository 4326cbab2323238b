"""meshio (optional, Debian python3-meshio): any mesh meshio reads can be uploaded, any frame
written in a format meshio writes."""
import os
from typing import TYPE_CHECKING, Any, List, Tuple, Union

import numpy as np

from ._meshio import Float64Array, Int64Array, triangulate
from ._optional import require

if TYPE_CHECKING:  # pragma: no cover - types only
    from ._frames import Frame

PathLike = Union[str, "os.PathLike[str]"]

# meshio's cell types without a surface to deform: dropped (a .obj's lines, a .vtk's points)
_SKIPPED = ("vertex", "line")


def require_meshio(what: str) -> Any:
    """The meshio module, or an ImportError naming the fix."""
    return require("meshio", what)


def _blocks(mesh: Any) -> List[Tuple[str, Any]]:
    out = []
    for block in mesh.cells:
        if hasattr(block, "type") and hasattr(block, "data"):
            out.append((str(block.type), block.data))
        else:  # (type, data) pairs
            kind, data = block
            out.append((str(kind), data))
    return out


def from_meshio(mesh: Any) -> Tuple[Float64Array, Int64Array]:
    """(V float64 n×3, F int64 m×3) of a meshio.Mesh (or of a file meshio reads, given its
    path), for Client.upload(V, F) — or use Client.upload_meshio(mesh). V is mesh.points
    (same rows, so frame rows are the mesh's points); F: its "triangle" cells, and its
    "quad" and "polygon" cells fan-triangulated as hdeform.triangulate does (right for convex
    polygons), block after block. "vertex" and "line" cells are dropped; volume cells
    (tetra, hexahedron, …) and higher-order ones (triangle6, quad9, …) are refused with a
    hint."""
    if isinstance(mesh, (str, os.PathLike)):
        mesh = require_meshio("hdeform.from_meshio(path)").read(os.fspath(mesh))
    if not hasattr(mesh, "points") or not hasattr(mesh, "cells"):
        raise TypeError(f"mesh: expected a meshio.Mesh (points and cells) or a path, got "
                        f"{type(mesh).__name__}")
    try:
        V = np.ascontiguousarray(mesh.points, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError("mesh.points: expected an n×3 array of numbers") from None
    if V.ndim != 2 or V.shape[1] != 3:
        hint = (" (a 2-D mesh: add a z column, mesh.points = numpy.c_[mesh.points, "
                "numpy.zeros(len(mesh.points))])" if V.ndim == 2 and V.shape[1] == 2 else "")
        raise ValueError(f"mesh.points: expected an n×3 array, got shape {V.shape}{hint}")
    parts = []
    kinds = []
    for kind, data in _blocks(mesh):
        kinds.append(kind)
        if kind in ("triangle", "quad") or kind.startswith("polygon"):
            parts.append(triangulate(np.asarray(data)))
        elif kind in _SKIPPED or kind.startswith("line"):
            continue
        elif kind.startswith(("triangle", "quad")):
            corners = 3 if kind.startswith("triangle") else 4
            raise ValueError(
                f"mesh.cells: {kind!r} cells are higher-order; hdeform takes linear surface "
                f"cells: keep their corners, e.g. meshio.CellBlock("
                f"{'triangle' if corners == 3 else 'quad'!r}, block.data[:, :{corners}])")
        else:
            raise ValueError(
                f"mesh.cells: {kind!r} cells are not surface cells; hdeform deforms triangle "
                "surfaces (triangle, quad, polygon cells): extract the boundary surface first")
    if not parts:
        raise ValueError("mesh.cells: no triangle, quad or polygon cells (cell types: "
                         f"{', '.join(kinds) or 'none'})")
    F = np.concatenate(parts) if len(parts) > 1 else parts[0]
    if F.size and (F.min() < 0 or F.max() >= len(V)):
        raise ValueError(f"mesh.cells: vertex ids must be in [0, {len(V)}), got "
                         f"{int(F.min())} … {int(F.max())}")
    return V, F


def frame_to_meshio(frame: "Frame", normals: bool = True, energies: bool = True) -> Any:
    """Frame.to_meshio()."""
    meshio = require_meshio("Frame.to_meshio()")
    if frame.V is None:
        raise ValueError("this frame has no positions (a superseded frame): nothing to convert")
    point_data = {"normals": frame.N} if normals and frame.N is not None else {}
    cell_data = ({"energies": [frame.energies]}
                 if energies and frame.energies is not None else {})
    return meshio.Mesh(frame.V, [("triangle", frame.F)], point_data=point_data,
                       cell_data=cell_data)
