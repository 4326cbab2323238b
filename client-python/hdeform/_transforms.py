"""Handle transforms: x' = p + R S (x - p) + t, or a 4×4 matrix (see deform.proto)."""
import os
from dataclasses import dataclass
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

from ._checks import floats, number
from ._proto import pb

_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


Float64Array = npt.NDArray[np.float64]


def _named_axis(text: str) -> Float64Array:
    t = text.strip().lower()
    sign = -1.0 if t[:1] == "-" else 1.0
    t = t[1:] if t[:1] in ("-", "+") else t
    if t not in _AXES:
        raise ValueError("axis_angle axis: 'x', 'y', 'z' (or '-x', …) or 3 numbers, "
                         f"got {text!r}")
    a: Float64Array = sign * np.asarray(_AXES[t]) + 0.0  # + 0.0: no -0 components
    return a


def axis_angle(axis: Union[str, npt.ArrayLike], degrees: Optional[Union[float, str]] = None
               ) -> Float64Array:
    """The unit quaternion (w, x, y, z) of a rotation by `degrees` about `axis`: 3 numbers or
    "x", "y", "z", "-x", …; or the CLI's text, axis_angle("x,30") / axis_angle("1,0,0,30")."""
    if isinstance(axis, str) and degrees is None:
        text = axis
        parts = [p.strip() for p in text.split(",")]
        if len(parts) == 2:
            axis, degrees = parts[0], parts[1]
        elif len(parts) == 4:
            axis, degrees = parts[:3], parts[3]
        else:
            raise ValueError(f"axis_angle: expected 'AXIS,DEG' or 'X,Y,Z,DEG', got {text!r}")
        try:
            degrees = float(degrees)
            if not isinstance(axis, str):
                axis = [float(v) for v in parts[:3]]
        except ValueError:
            raise ValueError("axis_angle: expected 'AXIS,DEG' or 'X,Y,Z,DEG' with numbers, "
                             f"got {text!r}") from None
    if degrees is None:
        raise TypeError("axis_angle: missing degrees (axis_angle('x', 30))")
    a = _named_axis(axis) if isinstance(axis, str) else floats(axis, "axis_angle axis", (3,))
    norm = np.linalg.norm(a)
    if not norm > 0:
        raise ValueError("axis_angle axis: must be non-zero")
    if not np.isfinite(norm):
        raise ValueError("axis_angle axis: too long")
    # fmod(…, 720) as the CLI does, so huge angles lose no precision in the half angle
    half = np.radians(np.fmod(number(degrees, "axis_angle degrees"), 720.0)) / 2
    q: Float64Array = np.concatenate([[np.cos(half)], np.sin(half) * a / norm])
    return q


def _matrix_to_quaternion(m: Float64Array) -> Float64Array:
    # Shepperd's method on a proper rotation matrix.
    t = np.trace(m)
    if t > 0:
        s = 2 * np.sqrt(1 + t)
        q = [s / 4, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2 * np.sqrt(1 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [(m[2, 1] - m[1, 2]) / s, s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2 * np.sqrt(1 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s]
    else:
        s = 2 * np.sqrt(1 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4]
    return np.asarray(q)


def quaternion(rotate: npt.ArrayLike) -> Float64Array:
    """A unit quaternion (w, x, y, z) from 4 numbers (w, x, y, z) or a 3×3 rotation matrix."""
    try:
        a = np.asarray(rotate, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError("rotate: expected a quaternion (w, x, y, z) or a 3×3 rotation matrix "
                        f"(use hdeform.axis_angle(axis, degrees)), got {rotate!r:.60}") from None
    if not np.isfinite(a).all():
        raise ValueError("rotate: expected finite numbers")
    if a.shape == (4,):
        q = a
    elif a.shape == (3, 3):
        q = _matrix_to_quaternion(a)
    else:
        raise ValueError("rotate: expected a quaternion (w, x, y, z) or a 3×3 rotation matrix "
                         f"(use hdeform.axis_angle(axis, degrees)), got shape {a.shape}")
    n = np.linalg.norm(q)
    if not n > 0:
        raise ValueError("rotate: zero quaternion")
    out: Float64Array = q / n
    return out


@dataclass
class Transform:
    """One handle's transform. rotate: quaternion (w, x, y, z) or 3×3 matrix; translate: 3
    numbers; scale: a number, 3 numbers (per axis) or a symmetric positive definite 3×3;
    pivot: 3 numbers (default: the handle's rest centroid); matrix: 4×4 homogeneous (replaces
    rotate/scale/translate)."""
    rotate: Optional[npt.ArrayLike] = None
    translate: Optional[npt.ArrayLike] = None
    scale: Optional[npt.ArrayLike] = None
    pivot: Optional[npt.ArrayLike] = None
    matrix: Optional[npt.ArrayLike] = None

    @classmethod
    def from_proto(cls, t: Any) -> "Transform":
        """A Transform from an hdeform.v1.HandleTransform: tuples of floats (unset parts
        None; scale a float, 3 floats or 3 rows of 3)."""
        def vec(v: Any) -> Tuple[float, ...]:
            return (float(v.x), float(v.y), float(v.z))

        scale: Any = None
        kind = t.WhichOneof("scale")
        if kind == "uniform_scale":
            scale = float(t.uniform_scale)
        elif kind == "axis_scale":
            scale = vec(t.axis_scale)
        elif kind == "stretch":
            m = [float(x) for x in t.stretch.m]
            scale = tuple(tuple(m[3 * i:3 * i + 3]) for i in range(3))
        matrix = None
        if len(t.matrix):
            m = [float(x) for x in t.matrix]
            matrix = tuple(tuple(m[4 * i:4 * i + 4]) for i in range(4))
        r = t.rotation
        return cls(
            rotate=(float(r.w), float(r.x), float(r.y), float(r.z)) if t.HasField("rotation")
            else None,
            translate=vec(t.translation) if t.HasField("translation") else None,
            scale=scale, pivot=vec(t.pivot) if t.HasField("pivot") else None, matrix=matrix)

    def to_proto(self) -> Any:
        t = pb.HandleTransform()
        if self.pivot is not None:
            p = floats(self.pivot, "pivot", (3,))
            t.pivot.CopyFrom(pb.Vec3(x=p[0], y=p[1], z=p[2]))
        if self.matrix is not None:
            m = floats(self.matrix, "matrix", (4, 4))
            t.matrix.extend(m.reshape(-1).tolist())
        if self.rotate is not None:
            q = quaternion(self.rotate)
            t.rotation.CopyFrom(pb.Quaternion(w=q[0], x=q[1], y=q[2], z=q[3]))
        if self.translate is not None:
            v = floats(self.translate, "translate", (3,))
            t.translation.CopyFrom(pb.Vec3(x=v[0], y=v[1], z=v[2]))
        if self.scale is not None:
            try:
                s = np.asarray(self.scale, dtype=np.float64)
            except (TypeError, ValueError):
                raise TypeError(f"scale: expected 1, 3 or 3×3 numbers, got {self.scale!r:.60}") \
                    from None
            if not np.isfinite(s).all():
                raise ValueError("scale: expected finite numbers")
            if s.size == 1:
                t.uniform_scale = float(s.reshape(-1)[0])
            elif s.shape == (3,):
                t.axis_scale.CopyFrom(pb.Vec3(x=s[0], y=s[1], z=s[2]))
            elif s.shape == (3, 3):
                t.stretch.m.extend(s.reshape(-1).tolist())
            else:
                raise ValueError(f"scale: expected 1, 3 or 3×3 numbers, got shape {s.shape}")
        return t


def transform(rotate: Optional[npt.ArrayLike] = None,
              translate: Optional[npt.ArrayLike] = None,
              scale: Optional[npt.ArrayLike] = None, pivot: Optional[npt.ArrayLike] = None,
              matrix: Optional[npt.ArrayLike] = None) -> Transform:
    """A Transform (see its fields)."""
    return Transform(rotate, translate, scale, pivot, matrix)


TransformLike = Union[Transform, Dict[str, Any], npt.ArrayLike, None]


def to_transform(spec: TransformLike) -> Transform:
    """A Transform from a Transform, a dict of its fields, a 4×4 matrix or None (identity)."""
    if spec is None:
        return Transform()
    if isinstance(spec, Transform):
        return spec
    if isinstance(spec, dict):
        unknown = set(spec) - {"rotate", "translate", "scale", "pivot", "matrix"}
        if unknown:
            raise ValueError(f"transform dict: unknown keys {sorted(unknown)} (rotate, "
                             "translate, scale, pivot, matrix)")
        return Transform(**spec)
    return Transform(matrix=spec)


def read_def(path: Union[str, "os.PathLike[str]"]) -> Float64Array:
    """A Botsch–Sorkine .def file's 4×4 matrix (16 numbers; '#' lines are comments)."""
    numbers: List[float] = []
    with open(os.fspath(path)) as f:
        for line in f:
            line = line.split("#", 1)[0]
            numbers.extend(float(x) for x in line.split())
    if len(numbers) != 16:
        raise ValueError(f"{path}: expected 16 numbers (a 4×4 matrix), found {len(numbers)}")
    m: Float64Array = np.asarray(numbers, dtype=np.float64).reshape(4, 4)
    return m
