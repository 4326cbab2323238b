"""Frames and measures as numpy arrays and dataclasses."""
from dataclasses import asdict, dataclass, fields
from typing import Optional

import numpy as np

from ._proto import pb


@dataclass
class Measures:
    """The seven measures of a deformation (hdeform.v1.Measures; SPEC.md)."""
    e: float
    e_iso_n: float
    e_conf_n: float
    e_area_pct: float
    max_e_iso: float
    max_e_conf: float
    max_ef2: float
    flips: int

    @classmethod
    def from_proto(cls, m):
        return cls(**{f.name: getattr(m, f.name) for f in fields(cls)})

    def as_dict(self):
        return asdict(self)


@dataclass
class Frame:
    """One solved deformation. V, N: n×3 float64 (frame order = file order for OFF/PLY/OBJ/STL
    and library meshes); energies: per-triangle float64 or None; measures: None on a drag frame
    that skipped them."""
    session: str
    sequence: int
    version: int
    V: Optional[np.ndarray]
    N: Optional[np.ndarray]
    energies: Optional[np.ndarray]
    measures: Optional[Measures]
    beta: float
    beta_automatic: bool
    beta_units: str
    exact: bool
    solve_ms: float
    encoding: str
    superseded: bool = False


_ENCODINGS = {"float32": pb.FRAME_ENCODING_FLOAT32, "quantized": pb.FRAME_ENCODING_QUANTIZED}


def encoding_value(name):
    if name not in _ENCODINGS:
        raise ValueError(f"encoding: one of {sorted(_ENCODINGS)} (MESHOPT and MESHOPT_DELTA are "
                         f"not supported by the Python client), got {name!r}")
    return _ENCODINGS[name]


def _float32s(data, width):
    a = np.frombuffer(data, dtype="<f4").astype(np.float64)
    return a.reshape(-1, width) if width > 1 else a


def _octahedral(o):
    u = np.maximum(o[:, 0] / 127.0, -1.0)
    v = np.maximum(o[:, 1] / 127.0, -1.0)
    z = 1.0 - np.abs(u) - np.abs(v)
    fold = z < 0
    su = np.where(u >= 0, 1.0, -1.0)
    sv = np.where(v >= 0, 1.0, -1.0)
    x = np.where(fold, (1.0 - np.abs(v)) * su, u)
    y = np.where(fold, (1.0 - np.abs(u)) * sv, v)
    n = np.stack([x, y, z], axis=1)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def _dequantize(frame):
    raw = np.frombuffer(frame.vertices, dtype=np.uint8)
    if raw.size % 8:
        raise ValueError(f"QUANTIZED frame: {raw.size} vertex bytes is not a multiple of 8")
    raw = raw.reshape(-1, 8)
    q = np.ascontiguousarray(raw[:, :6]).view("<u2").astype(np.float64)
    lo = np.array([frame.position_box.min.x, frame.position_box.min.y, frame.position_box.min.z])
    hi = np.array([frame.position_box.max.x, frame.position_box.max.y, frame.position_box.max.z])
    V = lo + q * ((hi - lo) / 65535.0)
    N = _octahedral(np.ascontiguousarray(raw[:, 6:8]).view(np.int8).astype(np.float64))
    return V, N


def decode(frame):
    """A Frame from an hdeform.v1.Frame (FLOAT32 or QUANTIZED buffers)."""
    V = N = E = None
    if frame.encoding == pb.FRAME_ENCODING_FLOAT32:
        enc = "float32"
        if frame.positions:
            V = _float32s(frame.positions, 3)
        if frame.normals:
            N = _float32s(frame.normals, 3)
        if frame.energies:
            E = _float32s(frame.energies, 1)
    elif frame.encoding == pb.FRAME_ENCODING_QUANTIZED:
        enc = "quantized"
        if frame.vertices:
            V, N = _dequantize(frame)
        if frame.energies:
            E = np.frombuffer(frame.energies, dtype="<u2").astype(np.float64) * (
                frame.energies_max / 65535.0)
    else:
        raise ValueError(f"frame encoding {frame.encoding} is not supported by the Python client")
    return Frame(
        session=frame.session, sequence=frame.sequence, version=frame.version, V=V, N=N,
        energies=E,
        measures=Measures.from_proto(frame.measures) if frame.HasField("measures") else None,
        beta=frame.beta.value, beta_automatic=frame.beta.automatic,
        beta_units="raw" if frame.beta.units == pb.BETA_UNITS_RAW else "area",
        exact=frame.exact, solve_ms=frame.solve_ms, encoding=enc, superseded=frame.superseded)
