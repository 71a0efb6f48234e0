"""The IMU of a file trajectory: a tau landing flown back from its own groundtruth.txt
gives the closed form's noise-free gyroscope and specific force (through the IMU sensor's
own code path, with and without a lever arm and a rotated mount), and a strapdown
integration of a file trajectory's IMU follows the trajectory's poses."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, RotationSpline

from roslan.frames import rotation_log
from roslan.pipeline.context import Context
from roslan.sensors.imu import Imu, ImuConfig
from roslan.trajectory import TauTrajectory, Trajectory, TrajectoryConfig
from roslan.trajectory.export import write_trajectory_files
from roslan.trajectory.spline import FileTrajectory

QUIET = {
    "accelerometer_noise_density": 0.0,
    "accelerometer_random_walk": 0.0,
    "gyroscope_noise_density": 0.0,
    "gyroscope_random_walk": 0.0,
}
MOUNTS = {
    "base_link": {},
    "lever_and_tilt": {"position": [0.12, -0.05, 0.08], "rpy": [0.3, -0.2, 1.0]},
}


def _imu_txt(traj: Trajectory, folder: Path, pose: dict, rate: float = 500.0) -> np.ndarray:
    """Run the IMU sensor (noise off) and read back its imu.txt: t ax ay az gx gy gz."""
    cfg = ImuConfig.model_validate(
        {"type": "imu", "name": "imu", "rate": rate, "topic": "/imu", "pose": pose, **QUIET}
    )
    folder.mkdir()
    ctx = Context(traj, folder, seed=0, start_time_ns=10**18, sensors=[cfg])
    imu = Imu(cfg)
    for _ in imu.messages(ctx):
        pass
    imu.close(ctx)
    return np.loadtxt(folder / "imu.txt")


def test_body_rates_are_spline_derivatives_not_rotated() -> None:
    """SciPy's RotationSpline derivatives are body rates: R0 Rx(0.7 t) turns at
    [0.7, 0, 0] in the body, whatever R0; FileTrajectory passes them on unrotated."""
    t = np.linspace(0.0, 2.0, 41)
    R0 = Rotation.from_euler("ZYX", [1.2, 0.4, -0.3])
    spline = RotationSpline(t, R0 * Rotation.from_rotvec(np.outer(0.7 * t, [1.0, 0.0, 0.0])))
    np.testing.assert_allclose(spline(1.0, 1), [0.7, 0.0, 0.0], atol=1e-9)


@pytest.fixture(scope="module")
def landing(tmp_path_factory: pytest.TempPathFactory) -> tuple[TauTrajectory, FileTrajectory]:
    """A tau landing with goal yaw 1.2 rad and a tilted start, exported as roslan simulate
    writes it (groundtruth.txt at the default 200 Hz) and flown back from that file."""
    cfg = TrajectoryConfig.model_validate(
        {
            "initial": {
                "position": [-6.0, 2.5, 4.0],
                "rpy": [0.3, -0.25, -0.6],
                "descent_rate": 2.0,
            },
            "goal": {"position": [3.0, -2.0, 0.5], "rpy": [0.0, 0.0, 1.2]},
        }
    )
    tau = TauTrajectory(cfg, warn=False)
    out = tmp_path_factory.mktemp("landing")
    write_trajectory_files(tau, out)
    flown = FileTrajectory(TrajectoryConfig.model_validate({"file": str(out / "groundtruth.txt")}))
    return tau, flown


def test_flown_back_state_rates(landing: tuple[TauTrajectory, FileTrajectory]) -> None:
    """omega_body / alpha_body (the /ground_truth/odometry twist and /ground_truth/accel
    angular parts) of the file trajectory are the closed form's."""
    tau, flown = landing
    t = np.linspace(0.1, tau.T - 0.1, 2001)
    a, b = tau.state(t), flown.state(t)
    assert np.abs(a.omega_body).max() > 0.3  # a real rotation, not a near-identity
    np.testing.assert_allclose(b.omega_body, a.omega_body, atol=1e-4)
    np.testing.assert_allclose(b.alpha_body, a.alpha_body, atol=5e-3)


@pytest.mark.parametrize("mount", sorted(MOUNTS))
def test_flown_back_imu_equals_closed_form(
    landing: tuple[TauTrajectory, FileTrajectory], tmp_path: Path, mount: str
) -> None:
    tau, flown = landing
    truth = _imu_txt(tau, tmp_path / "tau", MOUNTS[mount])
    file = _imu_txt(flown, tmp_path / "file", MOUNTS[mount])
    assert truth.shape == file.shape
    np.testing.assert_array_equal(truth[:, 0], file[:, 0])
    inner = (truth[:, 0] > 0.1) & (truth[:, 0] < tau.T - 0.1)
    gyro_err = np.abs(file[inner, 4:] - truth[inner, 4:]).max()
    force_err = np.abs(file[inner, 1:4] - truth[inner, 1:4]).max()
    assert np.abs(truth[inner, 4:]).max() > 0.3
    assert gyro_err < 2e-3, gyro_err
    assert force_err < 0.02, force_err


def _wavy_pose_file(path: Path, rate: float = 100.0, duration: float = 3.0) -> None:
    """Hand-held-like motion: positions and ZYX angles as sums of sines (TUM file)."""
    t = np.arange(0.0, duration + 1e-9, 1.0 / rate)
    p = np.column_stack([0.5 * np.sin(1.3 * t), 0.4 * np.cos(0.9 * t), 1.0 + 0.2 * np.sin(2.1 * t)])
    ypr = np.column_stack(
        [1.0 + 0.8 * np.sin(0.7 * t), 0.3 * np.sin(1.1 * t), 0.4 * np.cos(0.9 * t)]
    )
    q = Rotation.from_euler("ZYX", ypr).as_quat()
    np.savetxt(path, np.column_stack([t, p, q]), fmt="%.12f")


def test_strapdown_integration_follows_the_poses(tmp_path: Path) -> None:
    """Integrating the noise-free IMU of a file trajectory (gyro: quaternion exponential;
    specific force: rotated to the world, gravity added, twice integrated) from the true
    state at 0.5 s follows the trajectory's own poses for 2 s."""
    _wavy_pose_file(tmp_path / "wavy.txt")
    traj = FileTrajectory(TrajectoryConfig.model_validate({"file": str(tmp_path / "wavy.txt")}))
    rate = 1000.0
    imu = _imu_txt(traj, tmp_path / "imu", {}, rate)
    sel = (imu[:, 0] >= 0.5 - 1e-9) & (imu[:, 0] <= 2.5 + 1e-9)
    t, f, w = imu[sel, 0], imu[sel, 1:4], imu[sel, 4:]
    truth = traj.state(t)
    dt = 1.0 / rate
    g = np.array([0.0, 0.0, -9.81])
    R = truth.R_world_body[0].copy()
    v, p = truth.velocity[0].copy(), truth.position[0].copy()
    Rs, ps = [R], [p]
    for k in range(t.size - 1):
        R_next = R @ Rotation.from_rotvec(0.5 * (w[k] + w[k + 1]) * dt).as_matrix()
        a0, a1 = R @ f[k] + g, R_next @ f[k + 1] + g
        p = p + v * dt + (2.0 * a0 + a1) * dt * dt / 6.0
        v = v + 0.5 * (a0 + a1) * dt
        R = R_next
        Rs.append(R)
        ps.append(p)
    angle = np.linalg.norm(
        rotation_log(np.swapaxes(truth.R_world_body, 1, 2) @ np.array(Rs)), axis=1
    )
    drift = np.linalg.norm(np.array(ps) - truth.position, axis=1)
    assert np.all(np.abs(w).max(axis=0) > 0.2)  # the body turns about every axis
    print(f"strapdown over 2 s: {angle.max():.2e} rad, {drift.max():.2e} m")
    assert angle.max() < 1e-5, angle.max()
    assert drift.max() < 1e-4, drift.max()
