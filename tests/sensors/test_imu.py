"""IMU model: analytic (noise-free) readings checked against finite differences of the
trajectory, noise statistics against the Kalibr densities, +g at rest, dataset files."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from pipeline_helpers import SHORT_TRAJECTORY
from roslan.config.base import validate_model
from roslan.errors import ConfigError
from roslan.frames import rotation_log, rpy_to_matrix
from roslan.io.messages import Flavor, MessageStore
from roslan.pipeline.context import Context
from roslan.sensors.base import sample_times_ns
from roslan.sensors.imu import Imu, ImuConfig
from roslan.trajectory import TauTrajectory, Trajectory, TrajectoryConfig

QUIET = {
    "accelerometer_noise_density": 0.0,
    "accelerometer_random_walk": 0.0,
    "gyroscope_noise_density": 0.0,
    "gyroscope_random_walk": 0.0,
}


def _traj(**kw: object) -> Trajectory:
    return TauTrajectory(TrajectoryConfig.model_validate({**SHORT_TRAJECTORY, **kw}))


def _run(
    cfg: ImuConfig, traj: Trajectory, tmp_path: Path, seed: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list]:
    """Run the sensor: t_ns, acc (N,3), gyro (N,3) decoded from the ROS 2 bytes, messages."""
    ctx = Context(traj, tmp_path, seed=seed, start_time_ns=10**18, sensors=[cfg])
    imu = Imu(cfg)
    store = MessageStore(Flavor.ROS2)
    msgs = list(imu.messages(ctx))
    imu.close(ctx)
    decoded = [store.typestore.deserialize_cdr(m.build(store), m.msgtype) for m in msgs]
    t = np.array([m.t_ns for m in msgs])
    acc = np.array(
        [
            [d.linear_acceleration.x, d.linear_acceleration.y, d.linear_acceleration.z]
            for d in decoded
        ]
    )
    gyro = np.array(
        [[d.angular_velocity.x, d.angular_velocity.y, d.angular_velocity.z] for d in decoded]
    )
    return t, acc, gyro, decoded


def test_defaults_are_esim_and_minimal_config_validates() -> None:
    c = ImuConfig.model_validate({"type": "imu", "name": "imu", "rate": 500, "topic": "/imu"})
    assert (c.gyroscope_noise_density, c.accelerometer_noise_density) == (1.86e-4, 1.86e-3)
    assert (c.gyroscope_random_walk, c.accelerometer_random_walk) == (2.66e-5, 4.33e-4)
    assert ImuConfig.model_validate({"type": "imu", "name": "i", "topic": "/i"}).rate == 1000.0


@pytest.mark.parametrize(
    ("key", "value"), [("rate", 0), ("rate", -5), ("gyroscope_noise_density", -1.0)]
)
def test_bad_values_are_config_errors(key: str, value: float) -> None:
    data = {"type": "imu", "name": "imu", "topic": "/imu", key: value}
    with pytest.raises(ConfigError, match=key):
        validate_model(ImuConfig, data, "job.yaml")


def test_zero_noise_equals_finite_difference_kinematics(tmp_path: Path) -> None:
    """Independent check: position of the sensor point and its orientation sampled from the
    trajectory, differentiated numerically; specific force = R_ws^T (d2p/dt2 + g z)."""
    traj = _traj()
    pose = {"position": [0.3, -0.2, 0.1], "rpy": [0.2, -0.1, 0.4]}
    cfg = ImuConfig.model_validate(
        {"type": "imu", "name": "imu", "rate": 100, "topic": "/imu", "pose": pose, **QUIET}
    )
    t_ns, acc, gyro, _ = _run(cfg, traj, tmp_path)
    R_bs = rpy_to_matrix(np.array(pose["rpy"]))
    r = np.array(pose["position"])
    h = 1e-4
    inner = (t_ns > 0.05e9) & (t_ns < traj.T * 1e9 - 0.05e9)
    ts = t_ns[inner] * 1e-9

    def sensor_pose(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        st = traj.state(t)
        return st.position + st.R_world_body @ r, st.R_world_body @ R_bs

    p_m, R_m = sensor_pose(ts - h)
    p_0, R_0 = sensor_pose(ts)
    p_p, R_p = sensor_pose(ts + h)
    a_w = (p_p - 2 * p_0 + p_m) / h**2
    f_expected = np.einsum("nji,nj->ni", R_0, a_w + np.array([0.0, 0.0, 9.81]))
    w_expected = rotation_log(np.swapaxes(R_m, 1, 2) @ R_p) / (2 * h)
    np.testing.assert_allclose(acc[inner], f_expected, atol=2e-3 * (1 + np.abs(f_expected).max()))
    np.testing.assert_allclose(gyro[inner], w_expected, atol=1e-5 * (1 + np.abs(w_expected).max()))


def test_at_rest_reads_plus_g(tmp_path: Path) -> None:
    traj = _traj(hold=0.5)
    cfg = ImuConfig.model_validate(
        {"type": "imu", "name": "imu", "rate": 100, "topic": "/imu", **QUIET}
    )
    t_ns, acc, gyro, _ = _run(cfg, traj, tmp_path)
    rest = t_ns > traj.T * 1e9 + 1e6
    assert rest.sum() >= 40
    np.testing.assert_allclose(acc[rest], np.tile([0.0, 0.0, 9.81], (rest.sum(), 1)), atol=1e-9)
    np.testing.assert_allclose(gyro[rest], 0.0, atol=1e-12)
    # a sensor rolled by 90 deg about x sees gravity along its +y... (z_s = -y_b): f = R^T g_up
    cfg2 = ImuConfig.model_validate(
        {
            "type": "imu",
            "name": "imu",
            "rate": 100,
            "topic": "/imu",
            "pose": {"rpy": [math.pi / 2, 0, 0]},
            **QUIET,
        }
    )
    _, acc2, _, _ = _run(cfg2, traj, tmp_path / "b")
    np.testing.assert_allclose(acc2[rest], np.tile([0.0, 9.81, 0.0], (rest.sum(), 1)), atol=1e-9)


def test_white_noise_std_matches_density(tmp_path: Path) -> None:
    traj = _traj(hold=4.0)
    rate = 400.0
    cfg = ImuConfig.model_validate(
        {
            "type": "imu",
            "name": "imu",
            "rate": rate,
            "topic": "/imu",
            "accelerometer_noise_density": 0.02,
            "gyroscope_noise_density": 0.003,
            "accelerometer_random_walk": 0.0,
            "gyroscope_random_walk": 0.0,
        }
    )
    clean = ImuConfig.model_validate({**cfg.model_dump(), **QUIET})
    _, acc, gyro, _ = _run(cfg, traj, tmp_path / "n")
    _, acc0, gyro0, _ = _run(clean, traj, tmp_path / "c")
    n = acc.shape[0] * 3
    for noisy, truth, density in ((acc, acc0, 0.02), (gyro, gyro0, 0.003)):
        std = (noisy - truth).std()
        expected = density * math.sqrt(rate)
        # sample std of n normals: relative standard error ~ 1/sqrt(2n)
        assert abs(std / expected - 1) < 5 / math.sqrt(2 * n)


def test_bias_random_walk_statistics(tmp_path: Path) -> None:
    """Increments of the bias between consecutive samples have std rw * sqrt(dt); with white
    noise off the measurement minus truth *is* the bias."""
    traj = _traj(hold=4.0)
    rate = 200.0
    rw = 0.05
    cfg = ImuConfig.model_validate(
        {
            "type": "imu",
            "name": "imu",
            "rate": rate,
            "topic": "/imu",
            **QUIET,
            "gyroscope_random_walk": rw,
            "accelerometer_random_walk": 2 * rw,
            "gyroscope_bias": [0.1, 0.0, -0.1],
        }
    )
    clean = ImuConfig.model_validate(
        {**cfg.model_dump(), **QUIET, "gyroscope_bias": [0.0, 0.0, 0.0]}
    )
    _, acc, gyro, _ = _run(cfg, traj, tmp_path / "n")
    _, acc0, gyro0, _ = _run(clean, traj, tmp_path / "c")
    bias_g = gyro - gyro0
    inc = np.diff(bias_g, axis=0)
    n = inc.size
    assert abs(inc.std() / (rw * math.sqrt(1 / rate)) - 1) < 5 / math.sqrt(2 * n)
    assert abs(
        np.diff(acc - acc0, axis=0).std() / (2 * rw * math.sqrt(1 / rate)) - 1
    ) < 5 / math.sqrt(2 * n)
    # the walk starts at the configured bias (plus one step)
    np.testing.assert_allclose(bias_g[0], [0.1, 0.0, -0.1], atol=6 * rw / math.sqrt(rate))
    # and it is continuous across the 1 s vectorized chunks (no reset)
    assert np.abs(inc).max() < 6 * rw / math.sqrt(rate)


def test_turn_on_bias_and_seed_determinism(tmp_path: Path) -> None:
    traj = _traj()
    cfg = ImuConfig.model_validate(
        {
            "type": "imu",
            "name": "imu",
            "rate": 100,
            "topic": "/imu",
            **QUIET,
            "gyroscope_turn_on_bias_sigma": 0.5,
        }
    )
    clean = ImuConfig.model_validate({**cfg.model_dump(), "gyroscope_turn_on_bias_sigma": 0.0})
    _, _, g1, _ = _run(cfg, traj, tmp_path / "a", seed=1)
    _, _, g1b, _ = _run(cfg, traj, tmp_path / "b", seed=1)
    _, _, g2, _ = _run(cfg, traj, tmp_path / "c", seed=2)
    _, _, g0, _ = _run(clean, traj, tmp_path / "d", seed=1)
    np.testing.assert_array_equal(g1, g1b)
    b1 = g1 - g0
    assert np.ptp(b1, axis=0).max() < 1e-12  # a constant offset
    assert np.abs(b1[0]).max() > 1e-3
    assert not np.allclose(g1, g2)


def test_covariances_orientation_and_files(tmp_path: Path) -> None:
    traj = _traj()
    cfg = ImuConfig.model_validate({"type": "imu", "name": "imu", "rate": 50, "topic": "/imu"})
    t_ns, acc, gyro, decoded = _run(cfg, traj, tmp_path)
    m = decoded[0]
    assert m.orientation_covariance[0] == -1.0
    np.testing.assert_allclose(
        m.linear_acceleration_covariance.reshape(3, 3), np.eye(3) * (1.86e-3**2 * 50)
    )
    np.testing.assert_allclose(
        m.angular_velocity_covariance.reshape(3, 3), np.eye(3) * (1.86e-4**2 * 50)
    )
    assert m.header.frame_id == "imu"
    assert m.header.stamp.sec * 10**9 + m.header.stamp.nanosec == 10**18 + t_ns[0]
    np.testing.assert_array_equal(t_ns, sample_times_ns(50, traj.duration_ns))
    txt = np.loadtxt(tmp_path / "imu.txt")
    np.testing.assert_allclose(txt[:, 1:4], acc, rtol=1e-8, atol=1e-9)
    np.testing.assert_allclose(txt[:, 4:7], gyro, rtol=1e-8, atol=1e-9)
    calib = yaml.safe_load((tmp_path / "calib" / "imu.yaml").read_text())
    assert calib["rostopic"] == "/imu"
    assert calib["update_rate"] == 50.0
    assert calib["gyroscope_noise_density"] == 1.86e-4
    # orientation: true publishes the exact sensor orientation, covariance not -1
    cfg_o = ImuConfig.model_validate({**cfg.model_dump(), "orientation": True})
    _, _, _, dec_o = _run(cfg_o, traj, tmp_path / "o")
    st = traj.state_ns(np.array([0]))
    q = dec_o[0].orientation
    np.testing.assert_allclose([q.x, q.y, q.z, q.w], st.quat_xyzw[0], atol=1e-12)
    assert dec_o[0].orientation_covariance[0] == 0.0
