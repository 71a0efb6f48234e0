"""Trajectory export: the sampled table (CSV), TUM ground truth and summary.

Files written into ``outdir`` (each atomically, see :mod:`roslan.io.files`):

* ``trajectory.csv``: the 18 components in the goal frame F (m, rad, s), one row at
  every instant of :meth:`Trajectory.table_times` (every ``sample_dt`` from 0, the
  last landing row exactly at T, then the hold).
* ``groundtruth.txt``: TUM ``t px py pz qx qy qz qw`` of base_link in the world frame
  at the ground-truth rate (``output.ground_truth_rate``, default 200 Hz): the instants
  of the bag's ``/ground_truth/pose`` (:func:`~roslan.trajectory.base.ground_truth_times_ns`,
  every ``1 / rate`` from 0 plus the end of the run), not the table's.
* ``summary.json``: :meth:`Trajectory.summary`.

The figure beside them, ``trajectory.png``, is drawn by
:func:`roslan.plots.landing.write_trajectory_plot` (figures sit above the trajectory).
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
    Trajectory,
    ground_truth_times_ns,
)

__all__ = [
    "CSV_HEADER",
    "TUM_HEADER",
    "table_times_ns",
    "write_groundtruth",
    "write_trajectory_files",
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
    ground_truth_rate: float = DEFAULT_GROUND_TRUTH_RATE,
) -> None:
    """Write trajectory.csv, groundtruth.txt and summary.json.

    Args:
        traj: the trajectory to sample (closed form, evaluated at the table instants).
        outdir: existing folder; files of the same names are replaced atomically.
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
