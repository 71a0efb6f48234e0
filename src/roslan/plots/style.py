"""One look for every roslan figure: colours, fonts, resolution, atomic saving.

Figures are built on :class:`matplotlib.figure.Figure` directly (Agg canvas, no
pyplot state), so plotting is safe in worker processes and never opens a window.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "AXIS_COLORS",
    "DPI",
    "EVENT_NEG_RGB",
    "EVENT_POS_RGB",
    "GAP_COLORS",
    "MEASURED_ALPHA",
    "colormap_lut",
    "figure",
    "save_figure",
    "style",
    "velocity_arrows",
]

DPI = 150
"""Resolution of every saved figure (dots per inch)."""

AXIS_COLORS = ("#d62728", "#2ca02c", "#1f77b4")
"""x, y, z (and roll, pitch, yaw: rotations about x, y, z) - the RGB triad convention."""

GAP_COLORS = dict(zip(("x", "y", "z", "roll", "pitch", "yaw"), AXIS_COLORS * 2, strict=True))

EVENT_POS_RGB = (40, 110, 255)
"""ON (brightness increase) events: blue, as in ESIM / rpg_dvs_ros renderers."""
EVENT_NEG_RGB = (235, 45, 45)
"""OFF events: red."""

MEASURED_ALPHA = 0.45

_RC: Any = {
    "font.size": 9,
    "axes.titlesize": 10,
    "axes.labelsize": 9,
    "legend.fontsize": 8,
    "xtick.labelsize": 8,
    "ytick.labelsize": 8,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "grid.linewidth": 0.6,
    "lines.linewidth": 1.4,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "savefig.dpi": DPI,
    "figure.dpi": DPI,
    "image.interpolation": "nearest",
}


@contextmanager
def style() -> Iterator[None]:
    """The roslan rcParams, restored afterwards."""
    import matplotlib as mpl

    with mpl.rc_context(_RC):
        yield


def figure(width_in: float, height_in: float) -> Any:
    """A new Agg-backed Figure with constrained (tight) layout."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig: Any, path: Path, *, tight: bool = False) -> Path:
    """Save ``fig`` as PNG at :data:`DPI`, atomically (temp file + rename): never a
    half-written image under the final name. ``tight`` grows or shrinks the canvas to
    what is drawn (for 3-D axes, which the constrained layout cannot measure)."""
    from roslan.io.files import atomic_write

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_write(path, "wb") as fh:
        extra: dict[str, Any] = {"bbox_inches": "tight", "pad_inches": 0.08} if tight else {}
        fig.savefig(fh, dpi=DPI, format="png", **extra)
    return path


def colormap_lut(name: str) -> NDArray[np.uint8]:
    """(256, 3) uint8 RGB lookup table of a matplotlib colormap (for NumPy rasters)."""
    import matplotlib as mpl

    cmap = mpl.colormaps[name]
    return (np.asarray(cmap(np.linspace(0.0, 1.0, 256)))[:, :3] * 255.0 + 0.5).astype(np.uint8)


def nice_step(x: float) -> float:
    """Round ``x`` > 0 down to 1, 2 or 5 x 10^k (0 for 0, negative or non-finite)."""
    if x <= 0 or not math.isfinite(x):
        return 0.0
    mag = 10 ** math.floor(math.log10(x))
    for m in (5, 2, 1):
        if m * mag <= x:
            return float(m * mag)
    return float(mag)


def velocity_arrows(ax: Any, p: NDArray[np.float64], v: NDArray[np.float64], n: int = 12) -> None:
    """Velocity vectors on a 3-D path (the paper's Fig. 3): ``n`` arrows at evenly spaced
    samples of the path ``p`` (M, 3) with velocities ``v`` (M, 3), each the displacement
    of a round number of seconds at that velocity, the fastest about 0.3 of the path's
    extent, drawn thick in orange over the path (labelled with that time)."""
    if p.shape[0] < 2:
        return
    span = max(float(np.max(np.ptp(p, axis=0))), 1e-3)
    iv = np.unique(np.linspace(0, p.shape[0] - 1, n).round().astype(int))[:-1]
    vi = v[iv]
    vmax = float(np.max(np.linalg.norm(vi, axis=1), initial=0.0))
    dt = nice_step(0.3 * span / vmax) if vmax > 0 else 0.0
    if dt <= 0:
        return
    ax.quiver(
        p[iv, 0],
        p[iv, 1],
        p[iv, 2],
        vi[:, 0] * dt,
        vi[:, 1] * dt,
        vi[:, 2] * dt,
        color="darkorange",
        linewidth=2.0,
        arrow_length_ratio=0.25,
        label=f"velocity, max {vmax:.2f} m/s\n(arrow = {dt:g} s of travel)",
    )
