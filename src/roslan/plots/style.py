"""One look for every roslan figure: colours, fonts, resolution, atomic saving.

Figures are built on :class:`matplotlib.figure.Figure` directly (Agg canvas, no
pyplot state), so plotting is safe in worker processes and never opens a window.
"""

from __future__ import annotations

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
