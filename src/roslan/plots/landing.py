"""``trajectory.png``: a landing's 3-D path in the goal frame F with velocity vectors
(the paper's Fig. 3) and each gap against time, from the trajectory itself (written by
``roslan simulate``, in a background process, and by ``roslan trajectory``; the run
folder's own figure of a finished run is :mod:`roslan.plots.trajectory`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from roslan.io.files import atomic_write
from roslan.plots.style import DPI, GAP_COLORS, velocity_arrows
from roslan.trajectory.base import GAPS, Trajectory
from roslan.trajectory.generator import TauTrajectory

__all__ = ["write_trajectory_plot"]


def write_trajectory_plot(traj: Trajectory, path: Path) -> None:
    """Render the 3-D path in F with velocity vectors (12 evenly spaced instants of the
    landing), and the six gaps against time, to a PNG at ``path`` (atomic,
    deterministic)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    dense = traj.state(np.linspace(0.0, traj.T, 600))
    fig = Figure(figsize=(12.0, 6.0), dpi=DPI)
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(3, 4, width_ratios=[1.0, 1.0, 0.8, 0.8])
    ax3 = fig.add_subplot(grid[:, :2], projection="3d")
    p = dense.gaps[:, :3]
    ax3.plot(p[:, 0], p[:, 1], p[:, 2], color="tab:blue", lw=1.2, label="path")
    # arrows at evenly spaced instants of the landing: each the travel of a round number
    # of seconds at that velocity (the table rows crowd the arrows onto the path)
    velocity_arrows(ax3, p, dense.rates[:, :3])
    ax3.plot([p[0, 0]], [p[0, 1]], [p[0, 2]], "o", color="k", ms=5, label="start")
    ax3.plot([0.0], [0.0], [0.0], "*", color="gold", mec="k", ms=11, label="goal")
    ax3.set_xlabel("x [m]")
    ax3.set_ylabel("y [m]")
    ax3.set_zlabel("z [m]")
    if isinstance(traj, TauTrajectory):
        ax3.set_title(f"path in goal frame F (k = {traj.k:g}, T = {traj.T:.3f} s)")
    else:
        ax3.set_title(f"path relative to the last pose (file, {traj.T:.3f} s)")
    ax3.legend(loc="upper right", fontsize=8)  # the start is usually upper left
    units = {"x": "m", "y": "m", "z": "m", "roll": "rad", "pitch": "rad", "yaw": "rad"}
    for i, name in enumerate(GAPS):
        ax = fig.add_subplot(grid[i % 3, 2 + i // 3])
        ax.plot(dense.t, dense.gaps[:, i], color=GAP_COLORS[name], lw=1.2)
        ax.axvline(traj.T, color="0.6", lw=0.8, ls="--")
        ax.set_title(name, fontsize=9)
        ax.set_ylabel(f"{name} [{units[name]}]", fontsize=8)
        ax.tick_params(labelsize=7)
        if i % 3 == 2:
            ax.set_xlabel("t [s]", fontsize=8)
    fig.tight_layout()
    with atomic_write(path, "wb") as fh:
        fig.savefig(fh, format="png", metadata={"Software": None})
