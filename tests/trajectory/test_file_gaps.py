"""Pose files with gaps, a byte-order mark, or times out of order."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.interpolate import make_interp_spline
from scipy.spatial.transform import Rotation, Slerp

from roslan.errors import TrajectoryError
from roslan.trajectory import TrajectoryConfig
from roslan.trajectory.gaps import bridge_gaps
from roslan.trajectory.spline import FileTrajectory

GAP = (1.7, 2.6)  # s: the poses strictly inside are removed (a 0.91 s gap at 100 Hz)


def _truth(t: np.ndarray) -> tuple[np.ndarray, Rotation]:
    """Hand-held-like motion (sums of sines), positions in m and ZYX angles in rad."""
    p = np.column_stack(
        [
            0.3 * np.sin(1.1 * t) + 0.1 * np.sin(3.1 * t),
            0.25 * np.cos(0.8 * t) + 0.05 * np.sin(2.3 * t),
            1.0 + 0.1 * np.sin(1.9 * t),
        ]
    )
    ypr = np.column_stack(
        [0.5 * np.sin(0.6 * t) + 0.1 * np.sin(2.2 * t), 0.15 * np.sin(1.4 * t), 0.2 * np.cos(t)]
    )
    return p, Rotation.from_euler("ZYX", ypr)


def _gappy_file(path: Path, noise: float, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """100 Hz poses over 5 s with GAP removed, noise (m; half as many rad) added."""
    t = np.arange(0.0, 5.0, 0.01)
    t = t[~((t > GAP[0] + 1e-9) & (t < GAP[1] - 1e-9))]
    p, R = _truth(t)
    rng = np.random.default_rng(seed)
    p = p + rng.normal(0.0, noise, p.shape)
    R = Rotation.from_rotvec(rng.normal(0.0, noise / 2, (t.size, 3))) * R
    np.savetxt(path, np.column_stack([t, p, R.as_quat()]), fmt="%.9f")
    return t, p


def _errors(traj: FileTrajectory, tg: np.ndarray) -> tuple[float, float]:
    """Largest position (m) and angle (rad) error against the truth at instants tg."""
    st = traj.state(tg)
    p, R = _truth(tg)
    dp = np.linalg.norm(st.position - p, axis=1).max()
    da = (Rotation.from_matrix(st.R_world_body).inv() * R).magnitude().max()
    return float(dp), float(da)


@pytest.mark.parametrize("noise", [0.0, 0.001])
def test_gap_is_bridged_close_to_the_motion(tmp_path: Path, noise: float) -> None:
    """Across a 0.9 s gap the path stays within 2 cm / 0.6 deg of the true motion, closer
    than the straight line between the gap's poses (5.9 cm / 2 deg here). A quintic through
    the noisy poses without the bridge swings 1.5 m off."""
    t, p = _gappy_file(tmp_path / "gappy.txt", noise)
    traj = FileTrajectory(TrajectoryConfig.model_validate({"file": str(tmp_path / "gappy.txt")}))
    assert traj.summary()["gaps"] == [pytest.approx([GAP[0], GAP[1]], abs=1e-6)]
    tg = np.linspace(GAP[0], GAP[1], 301)
    dp, da = _errors(traj, tg)
    assert dp < 0.02, dp
    assert da < np.radians(0.6), da
    # the straight line (and slerp) between the two poses of the gap
    i = int(np.flatnonzero(t <= GAP[0] + 1e-9)[-1])
    s = (tg - t[i]) / (t[i + 1] - t[i])
    line = p[i] + s[:, None] * (p[i + 1] - p[i])
    assert dp < np.linalg.norm(line - _truth(tg)[0], axis=1).max()
    q = np.loadtxt(tmp_path / "gappy.txt")[:, 4:]
    slerp = Slerp([t[i], t[i + 1]], Rotation.from_quat(q[i : i + 2]))(tg)
    assert da < (slerp.inv() * _truth(tg)[1]).magnitude().max()
    if noise:  # what the bridge prevents: the plain interpolating quintic's swing
        swing = make_interp_spline(t, p[:, 0], k=5)(tg) - _truth(tg)[0][:, 0]
        assert np.abs(swing).max() > 0.2


def test_bridge_keeps_the_imu_smooth(tmp_path: Path) -> None:
    """The accelerometer and gyro across the gap stay within the range of the motion
    (no step or spike at the gap's ends)."""
    _gappy_file(tmp_path / "gappy.txt", 0.0)
    traj = FileTrajectory(TrajectoryConfig.model_validate({"file": str(tmp_path / "gappy.txt")}))
    tg = np.linspace(GAP[0] - 0.2, GAP[1] + 0.2, 2001)
    st = traj.state(tg)
    h = 1e-4
    p_m, p_0, p_p = (_truth(tg + d)[0] for d in (-h, 0.0, h))
    a_true = (p_p - 2 * p_0 + p_m) / h**2
    assert np.abs(st.acceleration).max() < 1.5 * np.abs(a_true).max()
    assert np.abs(st.omega_body).max() < 1.5 * 0.5


def test_no_gap_no_bridge() -> None:
    t = np.arange(0.0, 1.0, 0.01) + np.random.default_rng(0).uniform(0, 0.002, 100)
    p, R = _truth(t)
    q = R.as_quat()
    t2, p2, q2, gaps = bridge_gaps(t, p, q)
    assert gaps == []
    assert t2 is t
    assert p2 is p
    assert q2 is q


def test_byte_order_mark_is_not_data(tmp_path: Path) -> None:
    t = np.arange(0.0, 0.1, 0.01)
    p, R = _truth(t)
    text = "".join(
        " ".join(f"{v:.9f}" for v in row) + "\n" for row in np.column_stack([t, p, R.as_quat()])
    )
    (tmp_path / "bom.txt").write_bytes(b"\xef\xbb\xbf" + text.encode())
    (tmp_path / "plain.txt").write_text(text)
    a = FileTrajectory(TrajectoryConfig.model_validate({"file": str(tmp_path / "bom.txt")}))
    b = FileTrajectory(TrajectoryConfig.model_validate({"file": str(tmp_path / "plain.txt")}))
    np.testing.assert_array_equal(a.samples_p, b.samples_p)
    np.testing.assert_array_equal(a.samples_t, b.samples_t)


def test_order_error_prints_the_times_as_written(tmp_path: Path) -> None:
    rows = [f"{1305031104.6658 + 0.01 * i:.4f} 0 0 1 0 0 0 1" for i in range(7)]
    rows[4] = "1305031104.6658 0 0 1 0 0 0 1"
    (tmp_path / "f.txt").write_text("\n".join(rows) + "\n")
    with pytest.raises(TrajectoryError) as err:
        FileTrajectory(TrajectoryConfig.model_validate({"file": str(tmp_path / "f.txt")}))
    msg = str(err.value)
    assert "f.txt:5: time 1305031104.6658 is not after the previous line's" in msg
    assert "(1305031104.6958)" in msg
    assert "np.float64" not in msg
