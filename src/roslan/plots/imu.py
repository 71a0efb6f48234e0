"""``roslan plot imu``: accelerometer and gyroscope samples against the noise-free truth.

The truth is computed, not read: the run's resolved config in ``run.json`` gives the
trajectory (closed form, :mod:`roslan.trajectory`) and the IMU's extrinsics and
gravity, and :func:`roslan.sensors.imu.imu_measurements` evaluates the exact specific
force and angular velocity in the IMU frame at the sample instants (lever-arm terms
included). Runs without a resolved config fall back to ``groundtruth.txt``: the
truth is then differentiated numerically from the TUM poses (cubic spline for the
acceleration, log map of consecutive rotations for the rate), assuming the IMU
sits at base_link with identity rotation; the figure says which truth it shows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from roslan.errors import PlotError
from roslan.plots.style import AXIS_COLORS, MEASURED_ALPHA, figure, save_figure, style
from roslan.rundir.readers import ImuData, load_groundtruth, load_imu, load_run, resolved_config

__all__ = ["ImuTruth", "imu_truth", "plot_imu"]

F64 = NDArray[np.float64]
COMMAND = "roslan plot imu"
MEASURED_WIDTH = 1.4
TRUTH_WIDTH = 0.6
"""Line widths (pt): the truth thinner than the measurement under it."""
DEFAULT_GRAVITY = 9.81


@dataclass(frozen=True, slots=True)
class ImuTruth:
    """Noise-free IMU readings at the measured instants.

    Attributes:
        acc: (N, 3) specific force in the IMU frame, m/s^2.
        gyro: (N, 3) angular velocity in the IMU frame, rad/s.
        source: how it was obtained (shown in the figure).
        touchdown: touchdown time, s (None if unknown).
    """

    acc: F64
    gyro: F64
    source: str
    touchdown: float | None


def _imu_name(outdir: Path, path: Path, imus: list[dict[str, Any]]) -> dict[str, Any] | None:
    """The config of the IMU that wrote ``path`` (imu.txt: the first; imu_<name>.txt)."""
    if not imus:
        return None
    stem = path.stem
    for cfg in imus:
        if stem in (f"imu_{cfg.get('name')}", str(cfg.get("name"))):
            return cfg
    return imus[0] if path == outdir / "imu.txt" else None


def imu_truth(outdir: Path, data: ImuData) -> ImuTruth:
    """The noise-free truth of ``data`` (see the module docstring for the two sources)."""
    cfg = resolved_config(load_run(outdir))
    # a file trajectory's spline needs its pose file: use groundtruth.txt instead
    if (
        cfg is not None
        and isinstance(cfg.get("trajectory"), dict)
        and cfg["trajectory"].get("file") is None
    ):
        from pydantic import ValidationError

        from roslan.config.base import Pose
        from roslan.errors import RoslanError
        from roslan.sensors.imu import imu_measurements
        from roslan.trajectory import TrajectoryConfig, make_trajectory

        imus = [
            s for s in cfg.get("sensors") or [] if isinstance(s, dict) and s.get("type") == "imu"
        ]
        icfg = _imu_name(outdir, data.path, imus) or {}
        try:
            # the run's motion, vibration included (make_trajectory wraps it)
            traj = make_trajectory(TrajectoryConfig.model_validate(cfg["trajectory"]), warn=False)
            pose = Pose.model_validate(icfg.get("pose") or {})
        except (ValidationError, RoslanError, ValueError) as err:
            msg = f"{outdir / 'run.json'}: cannot rebuild the trajectory / IMU pose: {err}"
            raise PlotError(msg) from err
        gravity = float(icfg.get("gravity", DEFAULT_GRAVITY))
        t_ns = np.rint(data.t * 1e9).astype(np.int64)
        f, w, _ = imu_measurements(traj, t_ns, pose.matrix(), gravity)
        name = icfg.get("name", "imu")
        return ImuTruth(f, w, f"closed form (run.json: trajectory + pose of '{name}')", traj.T)
    gt = load_groundtruth(outdir)
    if gt is None:
        msg = (
            f"{COMMAND}: {outdir} has neither run.json (resolved config) nor groundtruth.txt; "
            "one of them is needed for the noise-free truth"
        )
        raise PlotError(msg)
    acc, gyro = _truth_from_poses(*gt, data.t)
    return ImuTruth(acc, gyro, "groundtruth.txt, differentiated (IMU at base_link)", None)


def _truth_from_poses(t: F64, p: F64, q: F64, t_query: F64) -> tuple[F64, F64]:
    """Specific force and body rate (base_link) from TUM poses, at ``t_query``."""
    from scipy.interpolate import CubicSpline

    from roslan.frames import quat_xyzw_to_matrix, rotation_log

    if t.shape[0] < 4:
        msg = "groundtruth.txt: at least 4 poses are needed to differentiate the truth"
        raise PlotError(msg)
    a_w = CubicSpline(t, p, axis=0)(t_query, 2)
    R = quat_xyzw_to_matrix(q)
    # omega_body at interval midpoints: log(R_k^T R_{k+1}) / dt
    rel = np.einsum("nji,njk->nik", R[:-1], R[1:])
    w_mid = rotation_log(rel) / np.diff(t)[:, None]
    t_mid = 0.5 * (t[:-1] + t[1:])
    w = np.stack([np.interp(t_query, t_mid, w_mid[:, i]) for i in range(3)], axis=1)
    Rq = quat_xyzw_to_matrix(np.stack([np.interp(t_query, t, q[:, i]) for i in range(4)], axis=1))
    g_w = np.array([0.0, 0.0, -DEFAULT_GRAVITY])
    f = np.einsum("nji,nj->ni", Rq, a_w - g_w)
    return np.asarray(f, dtype=np.float64), np.asarray(w, dtype=np.float64)


def plot_imu(outdir: Path, out: Path | None = None, imu_file: Path | None = None) -> Path:
    """Draw measured vs true IMU readings of the run in ``outdir``; returns the PNG path
    (default ``OUTDIR/plots/imu.png``)."""
    outdir = Path(outdir)
    data = load_imu(outdir, COMMAND, imu_file)
    truth = imu_truth(outdir, data)
    out = Path(out) if out is not None else outdir / "plots" / "imu.png"
    rows = (
        ("accelerometer", data.acc, truth.acc, "m/s²", 1.0),
        ("gyroscope", data.gyro, truth.gyro, "deg/s", 180.0 / math.pi),
    )
    with style():
        fig = figure(11.0, 5.6)
        axes = fig.subplots(2, 3, sharex=True)
        for r, (what, meas, true, unit, scale) in enumerate(rows):
            for i in range(3):
                ax = axes[r, i]
                # the measurement wider than the truth drawn over it: where the noise is
                # below a line's width (a_z, w_y: large signals), it still shows beside
                # the truth instead of hiding under it
                ax.plot(
                    data.t,
                    meas[:, i] * scale,
                    color=AXIS_COLORS[i],
                    alpha=MEASURED_ALPHA + 0.2,
                    linewidth=MEASURED_WIDTH,
                    label=f"measured ({data.path.name})",
                )
                ax.plot(
                    data.t,
                    true[:, i] * scale,
                    color="k",
                    linewidth=TRUTH_WIDTH,
                    zorder=3,
                    label="noise-free truth (thin, on top)",
                )
                err = (meas[:, i] - true[:, i]) * scale
                ax.set_title(
                    f"{what} {'xyz'[i]}\nerror: mean {err.mean():+.2g}, std {err.std():.2g}",
                    fontsize=9,
                )
                symbol = "a" if r == 0 else "ω"
                ax.set_ylabel(f"{symbol}_{'xyz'[i]} [{unit}]")
                if truth.touchdown is not None:
                    ax.axvline(
                        truth.touchdown,
                        color="0.4",
                        linestyle="-.",
                        linewidth=0.9,
                        label="touchdown",
                    )
                if r == 1:
                    ax.set_xlabel("trajectory time t [s]")
        axes[0, 0].legend(loc="upper left", fontsize=7)
        fig.suptitle(f"IMU in its own frame - truth: {truth.source}", fontsize=10)
        return save_figure(fig, out)
