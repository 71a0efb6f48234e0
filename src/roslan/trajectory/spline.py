"""A recorded or planned flight read from a pose file, fitted with smooth splines.

Input: TUM text ``t x y z qx qy qz qw`` (``#`` comments; this project's groundtruth.txt,
whose ``t`` is in nanoseconds when it is an integer column larger than 1e12, is TUM), or
this project's trajectory.csv (gaps ``x y z roll pitch yaw`` in the goal frame F), with
poses of base_link in the frame ``trajectory.goal`` (default: the world). Trajectory
time 0 is the first sample's time.
Position: a quintic interpolating spline (C^4), or with ``smoothing > 0`` a smoothing
spline per axis; orientation: :class:`scipy.spatial.transform.RotationSpline` (C^2), whose
first and second derivatives are the body angular velocity and acceleration (in
base_link). Gaps (intervals over 4 median intervals) are first filled with minimum-jerk
samples (:mod:`roslan.trajectory.gaps`). After the last sample the robot rests at the
last pose for ``hold`` seconds.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from roslan.errors import TrajectoryError
from roslan.frames import matrix_to_rpy, rpy_to_matrix
from roslan.trajectory.base import State, Trajectory, check_duration
from roslan.trajectory.config import TrajectoryConfig
from roslan.trajectory.gaps import bridge_gaps
from roslan.trajectory.generator import TauTrajectory
from roslan.trajectory.vibration import VibratingTrajectory

__all__ = ["FileTrajectory", "make_trajectory", "read_pose_file"]

F64 = NDArray[np.float64]

QUAT_TOL = 1e-3
"""Quaternions whose norm differs from 1 by at most this are normalized; others refused."""
MAX_FILE_BYTES = 512 * 1024 * 1024
ORDER = 5


TABLE_COLUMNS = ("t", "x", "y", "z", "roll", "pitch", "yaw")
"""First columns of roslan's trajectory.csv (its header line); the rates and accelerations
that follow are not read (the spline recomputes them)."""


def read_pose_file(path: Path, max_gap: float) -> tuple[F64, F64, F64]:
    """Read and check a pose file: (t (s), positions (N, 3), quaternions xyzw (N, 4)).

    Two formats: TUM ``t x y z qx qy qz qw`` (space or comma separated, optional header
    line starting with ``t``; this project's groundtruth.txt), and roslan's
    trajectory.csv (header ``t,x,y,z,roll,pitch,yaw,...``, 19 columns; poses as ZYX
    roll, pitch, yaw). Positions and orientations are those of the file's frame.
    """
    from roslan.frames import rpy_to_quat_xyzw
    from roslan.io.safe_read import read_bytes

    raw = read_bytes(path, MAX_FILE_BYTES, TrajectoryError)
    rows: list[list[float]] = []
    lines: list[int] = []
    stamps: list[str] = []  # the time column as written (for messages)
    ns_stamps = False
    table = False
    width, what = 8, "t x y z qx qy qz qw"
    # utf-8-sig: a leading byte-order mark (spreadsheet exports) is not part of the data
    text = raw.decode("utf-8-sig", errors="replace")
    for lineno, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        parts = s.replace(",", " ").split()
        if not rows and parts and parts[0].lower() == "t":
            table = tuple(p.lower() for p in parts[: len(TABLE_COLUMNS)]) == TABLE_COLUMNS
            if table:
                width, what = 19, "roslan trajectory.csv: t, 6 gaps, 6 rates, 6 accelerations"
            continue  # a header line
        if len(parts) != width:
            msg = f"{path}:{lineno}: {len(parts)} columns; expected {width} ({what})"
            raise TrajectoryError(msg)
        try:
            vals = [float(p) for p in parts]
        except ValueError:
            msg = f"{path}:{lineno}: not a number in {s!r}"
            raise TrajectoryError(msg) from None
        if not all(math.isfinite(v) for v in vals):
            msg = f"{path}:{lineno}: NaN or infinite value; all {width} columns must be finite"
            raise TrajectoryError(msg)
        if not rows and "." not in parts[0] and abs(vals[0]) > 1e12:
            ns_stamps = True
        rows.append(vals)
        lines.append(lineno)
        stamps.append(parts[0])
    if len(rows) < ORDER + 1:
        msg = f"{path}: {len(rows)} poses; the spline needs at least {ORDER + 1}"
        raise TrajectoryError(msg)
    a = np.asarray(rows, dtype=np.float64)
    t = a[:, 0] * (1e-9 if ns_stamps else 1.0)
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        msg = (
            f"{path}:{lines[i]}: time {stamps[i]} is not after the previous line's "
            f"({stamps[i - 1]}); times must strictly increase"
        )
        raise TrajectoryError(msg)
    big = np.flatnonzero(dt > max_gap)
    if big.size:
        i = int(big[0]) + 1
        msg = (
            f"{path}:{lines[i]}: gap of {dt[i - 1]:.6g} s since the previous pose; "
            f"at most trajectory.max_gap = {max_gap:g} s"
        )
        raise TrajectoryError(msg)
    if table:
        return t - t[0], a[:, 1:4].copy(), rpy_to_quat_xyzw(a[:, 4:7]).reshape(-1, 4)
    q = a[:, 4:8]
    norm = np.linalg.norm(q, axis=1)
    off = np.flatnonzero(np.abs(norm - 1.0) > QUAT_TOL)
    if off.size:
        i = int(off[0])
        msg = f"{path}:{lines[i]}: quaternion norm {norm[i]:.6g}; must be 1 within {QUAT_TOL:g}"
        raise TrajectoryError(msg)
    return t - t[0], a[:, 1:4].copy(), q / norm[:, None]


class FileTrajectory(Trajectory):
    """Spline fit of a pose file: the second implementation of :class:`Trajectory`.

    The goal frame F of the tau landing is here the world axes translated to the last
    pose's position: ``gaps[:, :3]`` = position - last position, ``gaps[:, 3:]`` = ZYX
    roll, pitch, yaw of base_link in the world.
    """

    def __init__(self, config: TrajectoryConfig, *, base_dir: Path | None = None) -> None:
        from scipy.interpolate import make_interp_spline, make_smoothing_spline
        from scipy.spatial.transform import Rotation, RotationSpline

        assert config.file is not None
        self.config = config
        path = Path(config.file)
        if not path.is_absolute() and base_dir is not None:
            path = base_dir / path
        self.path = path
        t, p, q = read_pose_file(path, float(config.max_gap))
        if config.goal != type(config.goal)():  # the file's poses are in the frame `goal`
            R_goal = rpy_to_matrix(np.asarray(config.goal.rpy, dtype=np.float64))
            p = p @ R_goal.T + np.asarray(config.goal.position, dtype=np.float64)
            q = (Rotation.from_matrix(R_goal) * Rotation.from_quat(q)).as_quat()
        self.samples_t, self.samples_p, self.samples_q = t, p, q
        # gaps are bridged by minimum-jerk samples (trajectory/gaps.py); the splines pass
        # through the poses and those samples
        tf, pf, qf, self.gaps = bridge_gaps(t, p, q)
        lam = float(config.smoothing)
        if lam > 0:
            self._pos = [make_smoothing_spline(tf, pf[:, i], lam=lam) for i in range(3)]
        else:
            self._pos = [make_interp_spline(tf, pf[:, i], k=ORDER) for i in range(3)]
        self._rot = RotationSpline(tf, Rotation.from_quat(qf))
        self.T = float(t[-1])
        self.hold = float(config.hold)
        self.duration = self.T + self.hold
        check_duration(self.duration, float(config.sample_dt), self.T)
        self.p_world_goal: F64 = p[-1].copy()
        self.R_world_goal: F64 = np.eye(3)

    def warnings(self) -> list[str]:
        return []

    def table_times(self) -> F64:
        """The input sample times, then every ``sample_dt`` through the hold."""
        parts = [self.samples_t]
        if self.hold > 0.0:
            dt = self.config.sample_dt
            m = math.floor(self.hold / dt + 1e-9)
            after = self.T + np.arange(1, m + 1, dtype=np.float64) * dt
            after = after[after < self.duration - 1e-9 * max(1.0, self.T)]
            parts += [after, np.array([self.duration])]
        return np.concatenate(parts)

    def gaps_at(self, t: ArrayLike) -> tuple[F64, F64, F64, F64]:
        st = self.state(t)
        return st.t, st.gaps, st.rates, st.accels

    def residual(self) -> dict[str, float]:
        """Fit residual at the input samples: max and RMS position (m), max angle (rad)."""
        st = self.state(self.samples_t)
        dp = np.linalg.norm(st.position - self.samples_p, axis=1)
        dot = np.abs(np.sum(st.quat_xyzw * self.samples_q, axis=1)).clip(0.0, 1.0)
        ang = 2.0 * np.arccos(dot)
        return {
            "position_max_m": float(dp.max()),
            "position_rms_m": float(np.sqrt(np.mean(dp * dp))),
            "angle_max_rad": float(ang.max()),
        }

    def summary(self) -> dict[str, Any]:
        t = np.linspace(0.0, self.T, 20001)
        st = self.state(t)
        speed = np.linalg.norm(st.velocity, axis=1)
        return {
            "source": "file",
            "file": str(self.path),
            "goal": self.config.goal.model_dump(mode="json"),
            "samples": int(self.samples_t.shape[0]),
            "smoothing": float(self.config.smoothing),
            "T": self.T,
            "touchdown_time": self.T,
            "duration": self.duration,
            "tau0": None,
            "k": None,
            "fit_residual": self.residual(),
            "gaps": [list(g) for g in self.gaps],
            "initial_speed": float(speed[0]),
            "peak_speed": float(speed.max()),
            "peak_acceleration_norm": float(np.linalg.norm(st.acceleration, axis=1).max()),
            "flapping": False,
            "warnings": [],
        }

    def state(self, t: ArrayLike) -> State:
        tt = np.atleast_1d(np.asarray(t, dtype=np.float64)).ravel()
        tc = np.clip(tt, 0.0, self.T)
        moving = ((tt >= 0.0) & (tt <= self.T)).astype(np.float64)[:, None]
        position = np.column_stack([s(tc) for s in self._pos])
        velocity = np.column_stack([s(tc, 1) for s in self._pos]) * moving
        acceleration = np.column_stack([s(tc, 2) for s in self._pos]) * moving
        rot = self._rot(tc)
        # RotationSpline's first and second derivatives are already the body angular
        # velocity and acceleration (in base_link; checked against closed forms in
        # tests/trajectory/test_file_imu.py): no rotation by R^T
        omega = self._rot(tc, 1) * moving
        alpha = self._rot(tc, 2) * moving
        R = rot.as_matrix()
        quat = rot.as_quat()
        quat = np.where(quat[:, 3:4] < 0, -quat, quat)
        rpy = matrix_to_rpy(R).reshape(-1, 3)
        gaps = np.concatenate([position - self.p_world_goal, rpy], axis=1)
        rpy_dot = _euler_rates(rpy, omega)
        h = 1e-6
        rpy_ddot = (_euler_rates(rpy, omega + h * alpha) - rpy_dot) / h
        rates = np.concatenate([velocity, rpy_dot], axis=1)
        accels = np.concatenate([acceleration, rpy_ddot * moving], axis=1)
        return State(
            t=tt,
            gaps=gaps,
            rates=rates,
            accels=accels,
            position=position,
            velocity=velocity,
            acceleration=acceleration,
            R_world_body=R,
            quat_xyzw=quat,
            omega_body=omega,
            alpha_body=alpha,
        )


def _euler_rates(rpy: F64, omega: F64) -> F64:
    """ZYX Euler rates from body rates (approximate for the angle part of the accels)."""
    r, p = rpy[:, 0], rpy[:, 1]
    wx, wy, wz = omega[:, 0], omega[:, 1], omega[:, 2]
    sr, cr, cp = np.sin(r), np.cos(r), np.cos(p)
    cp = np.where(np.abs(cp) < 1e-9, 1e-9, cp)
    a = wy * sr + wz * cr
    return np.column_stack([wx + a * np.tan(p), wy * cr - wz * sr, a / cp])


def make_trajectory(
    config: TrajectoryConfig, *, base_dir: Path | None = None, warn: bool = True
) -> Trajectory:
    """The trajectory a ``trajectory:`` block asks for: a pose file's spline or a tau landing,
    with the block's ``vibration`` superimposed when it has one."""
    inner: Trajectory
    if config.file is not None:
        inner = FileTrajectory(config, base_dir=base_dir)
    else:
        inner = TauTrajectory(config, warn=warn)
    if config.vibration is None:
        return inner
    return VibratingTrajectory(inner, config.vibration)
