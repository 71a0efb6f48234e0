"""Trajectory export: the sampled table (CSV), TUM ground truth, summary and a figure.

Files written into ``outdir`` (each atomically, see :mod:`roslan.io.files`):

* ``trajectory.csv``: the 18 components in the goal frame F (m, rad, s), one row at
  every instant of :meth:`Trajectory.table_times` (every ``sample_dt`` from 0, the
  last landing row exactly at T, then the hold).
* ``groundtruth.txt``: TUM ``t px py pz qx qy qz qw`` of base_link in the world frame
  at the ground-truth rate (``output.ground_truth_rate``, default 200 Hz): the instants
  of the bag's ``/ground_truth/pose`` (:func:`~roslan.trajectory.base.ground_truth_times_ns`,
  every ``1 / rate`` from 0 plus the end of the run), not the table's.
* ``summary.json``: :meth:`Trajectory.summary`.
* ``trajectory.png``: 3-D path with velocity vectors (the paper's Fig. 3) and each gap
  against time.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from roslan.io.files import atomic_write, atomic_write_text
from roslan.io.text import write_columns
from roslan.trajectory.base import (
    COMPONENTS,
    DEFAULT_GROUND_TRUTH_RATE,
    GAPS,
    Trajectory,
    ground_truth_times_ns,
)
from roslan.trajectory.generator import TauTrajectory
from roslan.trajectory.vibration import VibratingTrajectory

__all__ = [
    "CSV_HEADER",
    "TUM_HEADER",
    "plot_trajectory",
    "table_times_ns",
    "write_groundtruth",
    "write_trajectory_files",
    "write_trajectory_plot",
]

CSV_HEADER = "t," + ",".join(COMPONENTS)
"""``t,x,y,z,roll,pitch,yaw,vx,...,ayaw``: the documented trajectory.csv header."""

TUM_HEADER = "# t px py pz qx qy qz qw"
"""The TUM columns (documentation only: groundtruth.txt has no header line, as TUM's own
files and the Event Camera Dataset's have none)."""

_FMT = "%.12g"  # 12 significant digits: far below any sensor's noise, compact


def table_times_ns(traj: Trajectory) -> NDArray[np.int64]:
    """Integer-nanosecond stamps of :meth:`Trajectory.table_times` (rounded)."""
    return np.round(traj.table_times() * 1e9).astype(np.int64)


def write_trajectory_files(
    traj: Trajectory,
    outdir: Path,
    *,
    plot: bool = True,
    ground_truth_rate: float = DEFAULT_GROUND_TRUTH_RATE,
) -> None:
    """Write trajectory.csv, groundtruth.txt, summary.json and (if ``plot``) trajectory.png.

    Args:
        traj: the trajectory to sample (closed form, evaluated at the table instants).
        outdir: existing folder; files of the same names are replaced atomically.
        plot: also render trajectory.png (matplotlib Agg, deterministic).
        ground_truth_rate: Hz of groundtruth.txt (``output.ground_truth_rate``).
    """
    outdir = Path(outdir)
    t = traj.table_times()
    t_ns = table_times_ns(traj)
    st = traj.state(t)  # at the float instants: the landing row is evaluated at exactly T
    comps = st.components()
    with atomic_write(outdir / "trajectory.csv") as fh:
        fh.write(CSV_HEADER + "\n")
        write_columns(fh, t_ns, *comps.T, fmt=_FMT, sep=",")
    write_groundtruth(traj, outdir / "groundtruth.txt", ground_truth_rate)
    summary = traj.summary()
    atomic_write_text(outdir / "summary.json", json.dumps(summary, indent=2) + "\n")
    if plot:
        plot_trajectory(traj, outdir / "trajectory.png")


def write_groundtruth(traj: Trajectory, path: Path, rate: float) -> None:
    """TUM ``t px py pz qx qy qz qw`` (t in integer ns of trajectory time) at the
    ground-truth instants: the rows are the bag's ``/ground_truth/pose`` messages (stamp
    minus ``output.start_time``), written chunk by chunk (memory bounded)."""
    times = ground_truth_times_ns(rate, traj.duration_ns)
    step = max(1, round(rate * 10.0))  # ten seconds of poses per chunk
    with atomic_write(path) as fh:
        for i0 in range(0, times.size, step):
            t = times[i0 : i0 + step]
            st = traj.state_ns(t)
            write_columns(fh, t, *st.position.T, *st.quat_xyzw.T, fmt="%.9f", sep=" ")


def write_trajectory_plot(traj: Trajectory, path: Path) -> None:
    """trajectory.png alone (the simulation renders it in a background process)."""
    plot_trajectory(traj, path)


def plot_trajectory(traj: Trajectory, path: Path) -> None:
    """Render the 3-D path in F with velocity vectors (12 evenly spaced instants of the
    landing), and the six gaps against time, to a PNG at ``path`` (atomic,
    deterministic)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from roslan.plots.style import DPI, GAP_COLORS, velocity_arrows

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
    base = traj.inner if isinstance(traj, VibratingTrajectory) else traj
    shaken = " + vibration" if base is not traj else ""
    if isinstance(base, TauTrajectory):
        ax3.set_title(f"path in goal frame F (k = {base.k:g}, T = {traj.T:.3f} s{shaken})")
    else:
        ax3.set_title(f"path relative to the last pose (file, {traj.T:.3f} s{shaken})")
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
