"""Selectors: which vertices a region holds (a region is the union of its selectors)."""
import os
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from ._checks import floats, number
from ._proto import pb

FIXED = 0   # .sel label of the fixed region
HANDLE = 2  # .sel label of the handle region


def _num(v: float) -> str:
    return repr(float(v))


def _vec_text(v: Any) -> str:
    return f"({_num(v.x)}, {_num(v.y)}, {_num(v.z)})"


class Selector:
    """One hdeform.v1.Selector; build with ids(), base_ids(), box(), sphere(), half_space(),
    sel(), sel_file(). `mask_size` is the length of the boolean mask it was made from (None
    for ids): Session checks it against the vertex count."""

    def __init__(self, mask_size: Optional[int] = None, **fields: Any) -> None:
        self._msg = pb.Selector(**fields)
        self.mask_size = mask_size
        self._source: Optional[str] = None  # sel_file's path, for repr

    def to_proto(self) -> Any:
        """The hdeform.v1.Selector message."""
        return self._msg

    def __repr__(self) -> str:
        m = self._msg
        kind = m.WhichOneof("kind")
        if kind in ("ids", "base_ids"):
            a = list(getattr(m, kind).ids)
            shown = ", ".join(map(str, a[:8])) + (f", … {len(a)} ids" if len(a) > 8 else "")
            mask = f", from a mask of {self.mask_size}" if self.mask_size is not None else ""
            return f"hdeform.{kind}([{shown}]{mask})"
        if kind == "box":
            return f"hdeform.box(min={_vec_text(m.box.min)}, max={_vec_text(m.box.max)})"
        if kind == "sphere":
            return (f"hdeform.sphere(center={_vec_text(m.sphere.center)}, "
                    f"radius={_num(m.sphere.radius)})")
        if kind == "half_space":
            return (f"hdeform.half_space(normal={_vec_text(m.half_space.normal)}, "
                    f"offset={_num(m.half_space.offset)})")
        if kind == "sel":
            label = {FIXED: "hdeform.FIXED", HANDLE: "hdeform.HANDLE"}.get(m.sel.label,
                                                                           str(m.sel.label))
            if self._source is not None:
                return f"hdeform.sel_file({self._source!r}, {label})"
            return f"hdeform.sel(<{len(m.sel.content)} bytes>, {label})"
        return "hdeform.Selector()"


def _vec3(v: npt.ArrayLike, what: str) -> Any:
    a = floats(v, what, (3,))
    return pb.Vec3(x=a[0], y=a[1], z=a[2])


def _ids(values: npt.ArrayLike, what: str) -> Tuple[Any, Optional[int]]:
    """(VertexIds, mask size or None) from integer ids or a boolean mask (its True rows)."""
    a = np.asarray(values)
    mask_size: Optional[int] = None
    if a.dtype == np.bool_:
        if a.ndim != 1:
            raise ValueError(f"{what}: a boolean mask must be 1-D (one entry per vertex), "
                             f"got shape {a.shape}")
        mask_size = a.size
        a = np.flatnonzero(a)
    elif a.size and not np.issubdtype(a.dtype, np.integer):
        raise TypeError(f"{what}: vertex ids must be integers or a boolean mask, got {a.dtype}")
    a = a.reshape(-1).astype(np.int64)
    if a.size and (a.min() < -2**31 or a.max() >= 2**31):
        raise ValueError(f"{what}: vertex id out of int32 range")
    return pb.VertexIds(ids=a.tolist()), mask_size


def _id_selector(kind: str, values: npt.ArrayLike, what: str) -> "Selector":
    v, mask_size = _ids(values, what)
    return Selector(mask_size=mask_size, **{kind: v})


def ids(values: npt.ArrayLike) -> Selector:
    """Engine vertex ids (OBJ/OFF/PLY file order; equal to frame order except for glTF), or
    a boolean mask with one entry per vertex (its True rows)."""
    return _id_selector("ids", values, "ids")


def base_ids(values: npt.ArrayLike) -> Selector:
    """Base-GLB vertex ids (the order of Frame.V), or a boolean mask over Frame.V's rows."""
    return _id_selector("base_ids", values, "base_ids")


def box(min: npt.ArrayLike, max: npt.ArrayLike) -> Selector:  # noqa: A002 - the proto's names
    """Vertices in the closed axis-aligned box [min, max]."""
    return Selector(box=pb.Box(min=_vec3(min, "box min"), max=_vec3(max, "box max")))


def sphere(center: npt.ArrayLike, radius: float) -> Selector:
    """Vertices with |x - center| <= radius."""
    r = number(radius, "sphere radius")
    if r < 0:
        raise ValueError(f"sphere radius: must be >= 0, got {r!r}")
    return Selector(sphere=pb.Sphere(center=_vec3(center, "sphere center"), radius=r))


def half_space(normal: npt.ArrayLike, offset: float) -> Selector:
    """Vertices with dot(normal, x) >= offset."""
    return Selector(half_space=pb.HalfSpace(normal=_vec3(normal, "half_space normal"),
                                            offset=number(offset, "half_space offset")))


def sel(content: Union[bytes, bytearray, memoryview, str], label: int) -> Selector:
    """A Botsch–Sorkine .sel file's content (bytes or str) and the label to select
    (FIXED = 0, HANDLE = 2)."""
    if isinstance(content, str):
        content = content.encode()
    if not isinstance(content, (bytes, bytearray, memoryview)):
        raise TypeError(f"sel content: expected bytes or str, got {type(content).__name__}")
    if isinstance(label, (bool, np.bool_)) or not isinstance(label, (int, np.integer)):
        raise TypeError(f"sel label: expected an integer (hdeform.FIXED = 0, hdeform.HANDLE = 2), "
                        f"got {type(label).__name__}")
    return Selector(sel=pb.SelFile(content=bytes(content), label=int(label)))


def sel_file(path: Union[str, "os.PathLike[str]"], label: int) -> Selector:
    """A .sel file read from `path` (on this machine) and the label to select."""
    with open(os.fspath(path), "rb") as f:
        s = sel(f.read(), label)
    s._source = os.fspath(path)
    return s


_DICT_KINDS: Dict[str, Callable[[Any, str], Selector]] = {
    "ids": lambda v, what: _id_selector("ids", v, what),
    "base_ids": lambda v, what: _id_selector("base_ids", v, what),
    "box": lambda v, what: box(*v),
    "sphere": lambda v, what: sphere(*v),
    "half_space": lambda v, what: half_space(*v),
    "sel_file": lambda v, what: sel_file(*v),
}


def _from_dict(d: Dict[str, Any], what: str) -> Selector:
    if len(d) != 1 or next(iter(d)) not in _DICT_KINDS:
        raise ValueError(f"{what}: a selector dict has one key of {sorted(_DICT_KINDS)}, "
                         f"got {d!r}")
    k, v = next(iter(d.items()))
    return _DICT_KINDS[k](v, f"{what} {k}")


def _is_mask(spec: object) -> bool:
    if isinstance(spec, np.ndarray):
        return bool(spec.dtype == np.bool_)
    return (isinstance(spec, (list, tuple)) and len(spec) > 0 and
            all(isinstance(x, (bool, np.bool_)) for x in spec))


# A selection: a Selector, a dict ({"box": (min, max)}, …), vertex ids or a boolean mask.
SelectorLike = Union[Selector, Dict[str, Any], npt.ArrayLike]
# A region: one selection, or a list of Selectors / dicts (their union).
RegionLike = Union[SelectorLike, Sequence[Union[Selector, Dict[str, Any]]]]


def selector(spec: Any, what: str = "selector") -> Selector:
    """A Selector from a Selector, a dict ({'box': (min, max)}, …), an id array, or a
    boolean mask (sent as base_ids: a mask is over Frame.V's rows)."""
    if isinstance(spec, Selector):
        return spec
    if isinstance(spec, dict):
        return _from_dict(spec, what)
    if _is_mask(spec):
        return _id_selector("base_ids", spec, what)
    if isinstance(spec, (str, bytes)) or spec is None:
        raise TypeError(f"{what}: expected a selector, a dict, vertex ids or a boolean mask, "
                        f"got {type(spec).__name__}")
    return _id_selector("ids", spec, what)


def region(spec: Any, what: str = "region", vertex_count: Optional[int] = None) -> Any:
    """An hdeform.v1.Region: a selector, a dict, an id array, a boolean mask, or a list of
    selectors/dicts (their union). With `vertex_count`, a mask's length is checked against it."""
    if isinstance(spec, (list, tuple)) and spec and all(
            isinstance(s, (Selector, dict)) for s in spec):
        named: List[Tuple[Selector, str]] = [(selector(s, f"{what}[{i}]"), f"{what}[{i}]")
                                             for i, s in enumerate(spec)]
    else:
        named = [(selector(spec, what), what)]
    for p, name in named:
        if vertex_count is not None and p.mask_size is not None and p.mask_size != vertex_count:
            raise ValueError(f"{name}: a boolean mask of {p.mask_size} entries, but the session "
                             f"has {vertex_count} vertices (one entry per row of Frame.V)")
    return pb.Region(selectors=[p.to_proto() for p, _ in named])
