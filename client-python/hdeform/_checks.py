"""Argument checks done before any call: a mistake raises ValueError/TypeError naming the
argument instead of a numpy error or a server round trip."""
import math
import numbers
from typing import Collection, Mapping, Tuple, TypeVar, Union

import numpy as np
import numpy.typing as npt

T = TypeVar("T")


def number(value: object, what: str, finite: bool = True) -> float:
    """A float from a real number (not a bool, not a string)."""
    # bool is an int in Python: `beta=True` is a mistake, not 1.0
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise TypeError(f"{what}: expected a number, got {type(value).__name__}")
    v = float(value)
    if finite and not math.isfinite(v):
        raise ValueError(f"{what}: expected a finite number, got {v!r}")
    return v


def floats(value: object, what: str, shape: Tuple[int, ...], finite: bool = True
           ) -> npt.NDArray[np.float64]:
    """A float64 array of `shape` (e.g. (3,) or (4, 4)) from numbers."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{what}: expected numbers of shape {_shape(shape)}, got "
                        f"{type(value).__name__} {value!r:.60}") from None
    if a.shape != shape:
        if len(shape) == 1 and a.size == shape[0]:
            a = a.reshape(shape)  # e.g. a 1×3 row for 3 numbers
        else:
            raise ValueError(f"{what}: expected shape {_shape(shape)}, got {_shape(a.shape)}")
    if finite and not np.isfinite(a).all():
        raise ValueError(f"{what}: expected finite numbers, got {a.tolist()}")
    return a


def _shape(shape: Tuple[int, ...]) -> str:
    return "×".join(str(n) for n in shape) if shape else "scalar"


def beta(value: object, what: str = "beta") -> float:
    """A β value: finite, 0 ≤ β < 1 (either units)."""
    v = number(value, what)
    if not 0 <= v < 1:
        raise ValueError(f"{what}: must be in [0, 1), got {v!r}")
    return v


def choice(value: T, options: Union[Mapping[T, object], Collection[T]], what: str) -> T:
    """value if it is one of `options` (a dict or a collection) else a ValueError naming them."""
    try:
        ok = value in options
    except TypeError:  # unhashable
        ok = False
    if not ok:
        names = ", ".join(repr(o) for o in options)
        raise ValueError(f"{what}: one of {names}, got {value!r}")
    return value
