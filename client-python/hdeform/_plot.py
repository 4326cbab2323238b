"""Pictures with matplotlib (optional, Debian python3-matplotlib): a sweep's measures over β
and one frame's measures."""
import os
from typing import TYPE_CHECKING, Any, List, Optional, Sequence, Tuple, Union

import numpy as np

from ._frames import MEASURE_NAMES
from ._optional import require

if TYPE_CHECKING:  # pragma: no cover - types only
    from ._client import SweepResult
    from ._frames import Frame

PathLike = Union[str, "os.PathLike[str]"]

# The dimensionless measures a frame's bar chart shows (E is in model units², e_area_pct in
# percent and flips a count: those go in the title).
_FRAME_BARS = ("e_iso_n", "e_conf_n", "max_e_iso", "max_e_conf", "max_ef2")


def require_matplotlib(what: str) -> Any:
    """The matplotlib module, or an ImportError naming the fix."""
    return require("matplotlib", what)


def _axes(what: str, ax: Any, path: Optional[PathLike], ncols: int,
          figsize: Tuple[float, float]) -> Tuple[Any, List[Any]]:
    """(figure, axes): `ax` and its figure; else a new figure — without pyplot when it is
    only saved (no window, no global state), with pyplot otherwise (plt.show() shows it)."""
    require_matplotlib(what)
    if ax is not None:
        return ax.figure, [ax]
    if path is not None:
        from matplotlib.figure import Figure  # noqa: PLC0415
        fig = Figure(figsize=figsize)
        axes = fig.subplots(1, ncols, squeeze=False)[0]
    else:
        import matplotlib.pyplot as plt  # noqa: PLC0415
        fig, grid = plt.subplots(1, ncols, figsize=figsize, squeeze=False)
        axes = grid[0]
    return fig, list(axes)


def _save(fig: Any, path: Optional[PathLike]) -> None:
    if path is not None:
        fig.savefig(os.fspath(path), dpi=150)


def plot_sweep(rows: "SweepResult", ax: Any = None, path: Optional[PathLike] = None,
               measures: Sequence[str] = ("e_iso_n", "e_conf_n", "max_e_iso", "max_e_conf"),
               logy: bool = True) -> Any:
    """SweepResult.plot()."""
    if isinstance(measures, str):
        measures = (measures,)
    for i, name in enumerate(measures):
        if name not in MEASURE_NAMES:
            raise ValueError(f"measures[{i}]: one of {', '.join(MEASURE_NAMES)}, got {name!r}")
    if not measures:
        raise ValueError("measures: no names")
    if len(rows) == 0:
        raise ValueError("SweepResult.plot(): the sweep has no rows")
    fig, (axis,) = _axes("SweepResult.plot()", ax, path, 1, (6.4, 4.2))
    order = np.argsort([r.beta for r in rows], kind="stable")
    betas = np.array([rows[i].beta for i in order])
    flipped = np.array([rows[i].measures.flips > 0 for i in order])
    all_positive = True
    for name in measures:
        y = np.array([float(getattr(rows[i].measures, name)) for i in order])
        all_positive = all_positive and bool((y > 0).all())
        line = axis.plot(betas, y, marker="o", markersize=3, label=name)[0]
        if flipped.any():
            axis.plot(betas[flipped], y[flipped], linestyle="none", marker="x", markersize=8,
                      color=line.get_color())
    if flipped.any():
        axis.plot([], [], linestyle="none", marker="x", color="black",
                  label="× flipped triangles")
    if logy and all_positive:
        axis.set_yscale("log")
    axis.set_xlabel(f"β ({getattr(rows, 'units', 'area')} units)")
    axis.set_ylabel("measure")
    axis.set_title("Measures over β")
    axis.grid(True, alpha=0.3)
    axis.legend()
    _save(fig, path)
    return fig


def plot_frame_measures(frame: "Frame", ax: Any = None, path: Optional[PathLike] = None,
                        energies: bool = True) -> Any:
    """Frame.plot_measures()."""
    m = frame.measures
    if m is None:
        raise ValueError("Frame.plot_measures(): this frame has no measures (a drag frame "
                         "that skipped them)")
    histogram = energies and ax is None and frame.energies is not None
    fig, axes = _axes("Frame.plot_measures()", ax, path, 2 if histogram else 1,
                      (10.0, 4.0) if histogram else (6.4, 4.0))
    bars = axes[0]
    values = [float(getattr(m, name)) for name in _FRAME_BARS]
    positions = np.arange(len(values))
    bars.barh(positions, values, color="tab:blue")
    bars.set_yticks(positions)
    bars.set_yticklabels(list(_FRAME_BARS))
    bars.invert_yaxis()
    top = max(values)
    bars.set_xlim(0, 1.25 * top if top > 0 else 1.0)  # room for the value labels
    for y, v in zip(positions, values):
        bars.annotate(f" {v:.3g}", (v, y), va="center", fontsize=8)
    bars.set_title(f"β = {frame.beta:.4g} ({frame.beta_units}): E = {m.e:.4g}, "
                   f"E_area = {m.e_area_pct:.3g} %, flips = {m.flips}", fontsize=9)
    bars.grid(True, axis="x", alpha=0.3)
    if histogram:
        assert frame.energies is not None
        h = axes[1]
        h.hist(frame.energies, bins=60, log=True, color="tab:orange")
        h.set_xlabel("per-triangle energy ‖r‖²_F")
        h.set_ylabel("triangles")
        h.set_title(f"{len(frame.energies)} triangles", fontsize=9)
    if ax is None:
        fig.tight_layout()
    _save(fig, path)
    return fig
