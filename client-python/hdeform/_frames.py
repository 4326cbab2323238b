"""Frames and measures as numpy arrays and dataclasses; decoding the frame buffers."""
from dataclasses import asdict, dataclass, field, fields
import os
from typing import Any, Callable, Dict, Literal, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from ._proto import pb

Float64Array = npt.NDArray[np.float64]
Int64Array = npt.NDArray[np.int64]
PathLike = Union[str, "os.PathLike[str]"]  # a str or a pathlib.Path

# The frame encodings the client decodes. "float64" (the default of a client's own frames):
# the solve's doubles; "float32" / "quantized": fewer bytes (and what watchers get).
Encoding = Literal["float64", "float32", "quantized"]


@dataclass(frozen=True)
class Measures:
    """The seven measures of a deformation (hdeform.v1.Measures; SPEC.md): e (E(x), model
    units²), e_iso_n, e_conf_n (normalized), e_area_pct (percent), max_e_iso, max_e_conf,
    max_ef2, flips (inverted triangles)."""
    e: float
    e_iso_n: float
    e_conf_n: float
    e_area_pct: float
    max_e_iso: float
    max_e_conf: float
    max_ef2: float
    flips: int

    @classmethod
    def from_proto(cls, m: Any) -> "Measures":
        return cls(e=float(m.e), e_iso_n=float(m.e_iso_n), e_conf_n=float(m.e_conf_n),
                   e_area_pct=float(m.e_area_pct), max_e_iso=float(m.max_e_iso),
                   max_e_conf=float(m.max_e_conf), max_ef2=float(m.max_ef2),
                   flips=int(m.flips))

    def as_dict(self) -> Dict[str, Union[float, int]]:
        return asdict(self)


MEASURE_NAMES: Tuple[str, ...] = tuple(f.name for f in fields(Measures))


@dataclass
class Frame:
    """One solved deformation.

    V, N: n×3 float64, in frame order (the base GLB's; = file order for OFF/PLY/OBJ/STL and
    library meshes). Under the default encoding "float64" they are the server's doubles,
    exactly; "float32" / "quantized" frames are within that encoding's rounding. None when
    the frame carries no buffers (a superseded frame). energies: per-triangle float64 (sent
    as float32) or None unless asked; measures: None on a drag frame that skipped them."""
    session: str
    sequence: int
    version: int
    V: Optional[Float64Array]
    N: Optional[Float64Array]
    energies: Optional[Float64Array]
    measures: Optional[Measures]
    beta: float
    beta_automatic: bool
    beta_units: str
    exact: bool
    solve_ms: float
    encoding: str
    superseded: bool = False
    # The session's triangles in frame order, fetched on first use (to_meshio()).
    _triangles: Optional[Callable[[], Int64Array]] = field(default=None, repr=False,
                                                           compare=False)

    @property
    def F(self) -> Int64Array:
        """The session's triangles (m×3 int64) in frame order: the base GLB's
        (GetMesh(rest=True, GLB)), read once per Session and kept."""
        if self._triangles is None:
            raise ValueError("this Frame has no session to read its triangles from (frames "
                             "from Session.update() and Session.watch() have one)")
        return self._triangles()

    def to_meshio(self, normals: bool = True, energies: bool = True) -> Any:
        """A meshio.Mesh: points = V, one "triangle" cell block = F (frame order), with
        point_data["normals"] = N and cell_data["energies"] when the frame has them (and
        `normals` / `energies` are true). Needs meshio (apt-get install python3-meshio)."""
        from ._interop import frame_to_meshio
        return frame_to_meshio(self, normals=normals, energies=energies)

    def plot_measures(self, ax: Any = None, path: Optional[PathLike] = None,
                      energies: bool = True) -> Any:
        """A matplotlib Figure of this frame's measures: horizontal bars of the dimensionless
        ones (e_iso_n, e_conf_n, max_e_iso, max_e_conf, max_ef2) and e_area_pct, E and flips
        in the title; with per-triangle energies (update(energies=True)) and `energies`, a
        second panel with their histogram. `ax`: draw the bars there (no histogram panel);
        `path`: also save the figure (PNG, SVG, PDF by extension). Needs matplotlib (apt-get
        install python3-matplotlib)."""
        from ._plot import plot_frame_measures
        return plot_frame_measures(self, ax=ax, path=path, energies=energies)


_ENCODINGS: Dict[str, int] = {
    "float64": pb.FRAME_ENCODING_FLOAT64, "float32": pb.FRAME_ENCODING_FLOAT32,
    "quantized": pb.FRAME_ENCODING_QUANTIZED}
_NAMES = {v: k for k, v in _ENCODINGS.items()}


def encoding_value(name: object, what: str = "encoding",
                   allowed: Sequence[str] = ("float64", "float32", "quantized")) -> int:
    """The FrameEncoding of a name, checked before any call."""
    if not isinstance(name, str) or name not in allowed:
        extra = (" (MESHOPT and MESHOPT_DELTA are not supported by the Python client)"
                 if name in ("meshopt", "meshopt_delta") else "")
        if name == "float64" and "float64" not in allowed:
            extra = (" (float64 is for a client's own frames: a watch stream shares float32 "
                     "or quantized frames with every watcher)")
        raise ValueError(f"{what}: one of {', '.join(repr(a) for a in allowed)}, "
                         f"got {name!r}{extra}")
    return _ENCODINGS[name]


class FrameDecodeError(ValueError):
    """A frame whose buffers do not have the sizes its encoding and the session imply."""


def _check_size(data: bytes, unit: int, count: Optional[int], what: str, layout: str,
                enc: str) -> int:
    """The number of items in `data` (items of `unit` bytes), checked against `count`."""
    n = len(data)
    if n % unit:
        raise FrameDecodeError(f"{enc} frame: {what} holds {n} bytes, not a multiple of {unit} "
                               f"({layout})")
    if count is not None and n // unit != count:
        raise FrameDecodeError(f"{enc} frame: {what} holds {n} bytes = {n // unit} items of "
                               f"{layout}, but the session has {count}")
    return n // unit


def _vectors(data: bytes, dtype: str, count: Optional[int], what: str, enc: str
             ) -> Float64Array:
    size = np.dtype(dtype).itemsize
    _check_size(data, 3 * size, count, what, f"3 × {np.dtype(dtype).name} per vertex", enc)
    return np.frombuffer(data, dtype=dtype).astype(np.float64).reshape(-1, 3)


def _octahedral(o: Float64Array) -> Float64Array:
    u = np.maximum(o[:, 0] / 127.0, -1.0)
    v = np.maximum(o[:, 1] / 127.0, -1.0)
    z = 1.0 - np.abs(u) - np.abs(v)
    fold = z < 0
    su = np.where(u >= 0, 1.0, -1.0)
    sv = np.where(v >= 0, 1.0, -1.0)
    x = np.where(fold, (1.0 - np.abs(v)) * su, u)
    y = np.where(fold, (1.0 - np.abs(u)) * sv, v)
    n = np.stack([x, y, z], axis=1)
    out: Float64Array = n / np.linalg.norm(n, axis=1, keepdims=True)
    return out


def _dequantize(frame: Any, vertex_count: Optional[int]) -> Tuple[Float64Array, Float64Array]:
    data = bytes(frame.vertices)
    _check_size(data, 8, vertex_count, "vertices", "8 bytes per vertex", "QUANTIZED")
    raw = np.frombuffer(data, dtype=np.uint8).reshape(-1, 8)
    q = np.ascontiguousarray(raw[:, :6]).view("<u2").astype(np.float64)
    lo = np.array([frame.position_box.min.x, frame.position_box.min.y, frame.position_box.min.z])
    hi = np.array([frame.position_box.max.x, frame.position_box.max.y, frame.position_box.max.z])
    V: Float64Array = lo + q * ((hi - lo) / 65535.0)
    N = _octahedral(np.ascontiguousarray(raw[:, 6:8]).view(np.int8).astype(np.float64))
    return V, N


def decode(frame: Any, vertex_count: Optional[int] = None,
           triangle_count: Optional[int] = None,
           triangles: Optional[Callable[[], Int64Array]] = None) -> Frame:
    """A Frame from an hdeform.v1.Frame (FLOAT64, FLOAT32 or QUANTIZED buffers). With
    `vertex_count` / `triangle_count` (the session's), the buffers' sizes are checked against
    them; FrameDecodeError (a ValueError) says which buffer is wrong and how."""
    V = N = E = None
    code = frame.encoding
    if code not in _NAMES:
        raise FrameDecodeError(f"frame encoding {code} is not supported by the Python client "
                               f"(it asks for {', '.join(_ENCODINGS)})")
    enc = _NAMES[code]
    if code in (pb.FRAME_ENCODING_FLOAT64, pb.FRAME_ENCODING_FLOAT32):
        dtype = "<f8" if code == pb.FRAME_ENCODING_FLOAT64 else "<f4"
        name = enc.upper()
        if frame.positions:
            V = _vectors(bytes(frame.positions), dtype, vertex_count, "positions", name)
        if frame.normals:
            N = _vectors(bytes(frame.normals), dtype, vertex_count, "normals", name)
            if V is not None and len(N) != len(V):
                raise FrameDecodeError(f"{name} frame: {len(V)} positions but {len(N)} normals")
        if frame.energies:
            data = bytes(frame.energies)
            _check_size(data, 4, triangle_count, "energies", "float32 per triangle", name)
            E = np.frombuffer(data, dtype="<f4").astype(np.float64)
    else:
        if frame.vertices:
            V, N = _dequantize(frame, vertex_count)
        if frame.energies:
            data = bytes(frame.energies)
            _check_size(data, 2, triangle_count, "energies", "uint16 per triangle",
                        "QUANTIZED")
            E = np.frombuffer(data, dtype="<u2").astype(np.float64) * (
                float(frame.energies_max) / 65535.0)
    return Frame(
        session=str(frame.session), sequence=int(frame.sequence), version=int(frame.version),
        V=V, N=N, energies=E,
        measures=Measures.from_proto(frame.measures) if frame.HasField("measures") else None,
        beta=float(frame.beta.value), beta_automatic=bool(frame.beta.automatic),
        beta_units="raw" if frame.beta.units == pb.BETA_UNITS_RAW else "area",
        exact=bool(frame.exact), solve_ms=float(frame.solve_ms), encoding=enc,
        superseded=bool(frame.superseded), _triangles=triangles)
