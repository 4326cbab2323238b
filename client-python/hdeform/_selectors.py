"""Selectors: which vertices a region holds (a region is the union of its selectors)."""
import os

import numpy as np

from ._proto import pb

FIXED = 0   # .sel label of the fixed region
HANDLE = 2  # .sel label of the handle region


class Selector:
    """One hdeform.v1.Selector; build with ids(), base_ids(), box(), sphere(), half_space(),
    sel(), sel_file()."""

    def __init__(self, **fields):
        self._msg = pb.Selector(**fields)

    def to_proto(self):
        return self._msg

    def __repr__(self):
        kind = self._msg.WhichOneof("kind")
        return f"hdeform.Selector({kind})"


def _vec3(v, what):
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.shape != (3,):
        raise ValueError(f"{what}: expected 3 numbers, got {a.size}")
    return pb.Vec3(x=a[0], y=a[1], z=a[2])


def _ids(values, what):
    a = np.asarray(values)
    if a.size and not np.issubdtype(a.dtype, np.integer):
        raise TypeError(f"{what}: vertex ids must be integers, got {a.dtype}")
    a = a.reshape(-1).astype(np.int64)
    if a.size and (a.min() < -2**31 or a.max() >= 2**31):
        raise ValueError(f"{what}: vertex id out of int32 range")
    return pb.VertexIds(ids=a.tolist())


def ids(values):
    """Engine vertex ids (OBJ/OFF/PLY file order; equal to frame order except for glTF)."""
    return Selector(ids=_ids(values, "ids"))


def base_ids(values):
    """Base-GLB vertex ids (the order of Frame.V)."""
    return Selector(base_ids=_ids(values, "base_ids"))


def box(min, max):  # noqa: A002 - the proto's names
    """Vertices in the closed axis-aligned box [min, max]."""
    return Selector(box=pb.Box(min=_vec3(min, "box min"), max=_vec3(max, "box max")))


def sphere(center, radius):
    """Vertices with |x - center| <= radius."""
    return Selector(sphere=pb.Sphere(center=_vec3(center, "sphere center"), radius=float(radius)))


def half_space(normal, offset):
    """Vertices with dot(normal, x) >= offset."""
    return Selector(half_space=pb.HalfSpace(normal=_vec3(normal, "half_space normal"),
                                            offset=float(offset)))


def sel(content, label):
    """A Botsch–Sorkine .sel file's content (bytes or str) and the label to select
    (FIXED = 0, HANDLE = 2)."""
    if isinstance(content, str):
        content = content.encode()
    return Selector(sel=pb.SelFile(content=bytes(content), label=int(label)))


def sel_file(path, label):
    """A .sel file read from `path` (on this machine) and the label to select."""
    with open(os.fspath(path), "rb") as f:
        return sel(f.read(), label)


_DICT_KINDS = {
    "ids": lambda v: ids(v),
    "base_ids": lambda v: base_ids(v),
    "box": lambda v: box(*v),
    "sphere": lambda v: sphere(*v),
    "half_space": lambda v: half_space(*v),
    "sel_file": lambda v: sel_file(*v),
}


def _from_dict(d):
    if len(d) != 1 or next(iter(d)) not in _DICT_KINDS:
        raise ValueError(f"selector dict: expected one key of {sorted(_DICT_KINDS)}, got {d!r}")
    k, v = next(iter(d.items()))
    return _DICT_KINDS[k](v)


def selector(spec):
    """A Selector from a Selector, a dict ({'box': (min, max)}, …) or an id array."""
    if isinstance(spec, Selector):
        return spec
    if isinstance(spec, dict):
        return _from_dict(spec)
    return ids(spec)


def region(spec):
    """An hdeform.v1.Region: a selector, a dict, an id array, or a list of selectors/dicts
    (their union)."""
    if isinstance(spec, (Selector, dict)):
        parts = [selector(spec)]
    elif isinstance(spec, (list, tuple)) and spec and all(
            isinstance(s, (Selector, dict)) for s in spec):
        parts = [selector(s) for s in spec]
    else:
        parts = [ids(spec)]
    return pb.Region(selectors=[p.to_proto() for p in parts])
