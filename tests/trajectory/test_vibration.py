"""``trajectory.vibration``: the vibrated motion is one consistent motion (the IMU's
specific force and rates equal finite differences of the pose the cameras see), its
levels are the configured ones, it is deterministic per seed, absent means untouched,
and bad blocks are clear config errors."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pipeline_helpers import SHORT_TRAJECTORY
from roslan.config.base import validate_model
from roslan.errors import ConfigError
from roslan.frames import rotation_log, rpy_to_matrix
from roslan.pipeline.context import Context
from roslan.sensors.imu import Imu, ImuConfig, imu_measurements
from roslan.trajectory import (
    TauTrajectory,
    TrajectoryConfig,
    VibratingTrajectory,
    make_trajectory,
)

VIBRATION: dict[str, Any] = {
    "harmonics": [{"frequency": 12.0, "accel": [0.5, 1.0, 2.0], "gyro": [0.3, 0.2, 0.1]}],
    "broadband": [
        {"band": [20.0, 80.0], "accel_rms": [1.5, 1.0, 2.5], "gyro_rms": [0.05, 0.1, 0.02]}
    ],
}


def _cfg(vibration: dict[str, Any] | None = VIBRATION, **kw: Any) -> TrajectoryConfig:
    data = {**SHORT_TRAJECTORY, "flapping": {"frequency": 5, "heave": 0.05, "pitch": 0.1}, **kw}
    if vibration is not None:
        data["vibration"] = vibration
    return TrajectoryConfig.model_validate(data)


def test_imu_with_vibration_equals_finite_difference_of_pose(tmp_path: Path) -> None:
    """Independent check of the analytic derivatives: the sensor point's position and
    orientation (what a camera at the IMU's pose sees), differentiated numerically."""
    traj = make_trajectory(_cfg())
    assert isinstance(traj, VibratingTrajectory)
    pose = {"position": [0.1, -0.05, 0.03], "rpy": [0.2, -0.1, 0.4]}
    cfg = ImuConfig.model_validate(
        {"type": "imu", "name": "imu", "rate": 400, "topic": "/imu", "pose": pose,
         "accelerometer_noise_density": 0.0, "accelerometer_random_walk": 0.0,
         "gyroscope_noise_density": 0.0, "gyroscope_random_walk": 0.0}
    )  # fmt: skip
    ctx = Context(traj, tmp_path, seed=0, sensors=[cfg])
    imu = Imu(cfg)
    for _ in imu.messages(ctx):
        pass
    imu.close(ctx)
    rows = np.loadtxt(tmp_path / "imu.txt")
    t, acc, gyro = rows[:, 0], rows[:, 1:4], rows[:, 4:7]
    R_bs, r = rpy_to_matrix(np.array(pose["rpy"])), np.array(pose["position"])
    inner = (t > 0.02) & (t < traj.T - 0.02)
    ts, h = t[inner], 2e-5

    def sensor_pose(tt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        st = traj.state(tt)
        return st.position + st.R_world_body @ r, st.R_world_body @ R_bs

    (p_m, R_m), (p_0, R_0), (p_p, R_p) = (sensor_pose(ts + d) for d in (-h, 0.0, h))
    a_w = (p_p - 2 * p_0 + p_m) / h**2
    f_fd = np.einsum("nji,nj->ni", R_0, a_w + np.array([0.0, 0.0, 9.81]))
    w_fd = rotation_log(np.swapaxes(R_m, 1, 2) @ R_p) / (2 * h)
    # the vibration dominates: its accelerations reach several m/s^2
    base = imu_measurements(
        make_trajectory(_cfg(None)), np.rint(ts * 1e9).astype(np.int64), cfg.pose.matrix()
    )
    assert np.abs(acc[inner] - base[0]).max() > 3.0
    np.testing.assert_allclose(acc[inner], f_fd, atol=2e-3 * (1 + np.abs(f_fd).max()))
    np.testing.assert_allclose(gyro[inner], w_fd, atol=1e-5 * (1 + np.abs(w_fd).max()))


def test_gap_components_follow_the_vibrated_pose() -> None:
    """trajectory.csv's 18 components: gaps of the vibrated pose, rates and accelerations
    their derivatives (central differences)."""
    traj = make_trajectory(_cfg())
    t = np.linspace(0.05, traj.T - 0.05, 40)
    h = 1e-5
    sm, s0, sp = (traj.state(t + d) for d in (-h, 0.0, h))
    np.testing.assert_allclose(
        s0.gaps[:, :3], (s0.position - traj.p_world_goal) @ traj.R_world_goal
    )
    np.testing.assert_allclose(
        (sp.gaps - sm.gaps) / (2 * h), s0.rates, atol=1e-6 * (1 + np.abs(s0.rates).max())
    )
    np.testing.assert_allclose(
        (sp.rates - sm.rates) / (2 * h), s0.accels, atol=1e-5 * (1 + np.abs(s0.accels).max())
    )


def test_vibration_levels_are_the_configured_ones() -> None:
    """The body acceleration and rate added have the configured RMS per axis (harmonic:
    amplitude / sqrt 2; band: its RMS), before the fade."""
    vib = {"broadband": [{"band": [20.0, 80.0], "accel_rms": [1.5, 1.0, 2.5],
                          "gyro_rms": [0.05, 0.1, 0.02], "components": 200}],
           "harmonics": [{"frequency": 9.0, "accel": [0.0, 0.0, 2.0]}]}  # fmt: skip
    plain = make_trajectory(_cfg(None))
    traj = make_trajectory(_cfg(vib))
    t = np.arange(0.0, 0.75, 1e-4)
    a, b = traj.state(t), plain.state(t)
    # body-frame difference of acceleration (the vibration's rotation adds << 1 %)
    d_acc = np.einsum("nji,nj->ni", b.R_world_body, a.acceleration - b.acceleration)
    d_w = a.omega_body - b.omega_body
    rms = lambda x: np.sqrt(np.mean(x * x, axis=0))  # noqa: E731
    want_acc = np.sqrt(np.array([1.5, 1.0, 2.5]) ** 2 + np.array([0.0, 0.0, 2.0]) ** 2 / 2)
    np.testing.assert_allclose(rms(d_acc), want_acc, rtol=0.15)
    np.testing.assert_allclose(rms(d_w), [0.05, 0.1, 0.02], rtol=0.15)
    # faded out: nothing added at and after touchdown
    end = np.array([traj.T, traj.T + 0.1])
    np.testing.assert_array_equal(traj.state(end).position, plain.state(end).position)


def test_deterministic_per_seed() -> None:
    t = np.linspace(0.0, 1.0, 300)
    a = make_trajectory(_cfg()).state(t)
    b = make_trajectory(_cfg()).state(t)
    c = make_trajectory(_cfg({**VIBRATION, "seed": 7})).state(t)
    np.testing.assert_array_equal(a.position, b.position)
    np.testing.assert_array_equal(a.omega_body, b.omega_body)
    assert np.abs(a.acceleration - c.acceleration).max() > 0.1


def test_absent_block_leaves_the_trajectory_untouched() -> None:
    cfg = _cfg(None)
    traj = make_trajectory(cfg)
    assert type(traj) is TauTrajectory
    assert "vibration" not in cfg.model_dump(mode="json")
    assert "vibration" in _cfg().model_dump(mode="json")


@pytest.mark.parametrize(
    ("block", "expect"),
    [
        ({}, "give harmonics and/or broadband"),
        ({"broadband": [{"band": [80, 10], "accel_rms": [1, 1, 1]}]}, "band = [80.0, 10.0] Hz"),
        ({"harmonics": [{"frequency": 0, "accel": [1, 1, 1]}]}, "frequency"),
        ({"harmonics": [{"frequency": 10, "accel": [-1, 0, 0]}]}, "accel"),
        ({"harmonics": [{"frequency": 10, "acel": [1, 0, 0]}]}, "acel"),
        ({"harmonics": [{"frequency": 10}], "fade": 0}, "fade"),
    ],
)
def test_bad_blocks_are_config_errors(block: dict[str, Any], expect: str) -> None:
    with pytest.raises(ConfigError, match=r"sim\.yaml") as err:
        validate_model(TrajectoryConfig, {**SHORT_TRAJECTORY, "vibration": block}, "sim.yaml")
    assert "vibration" in str(err.value)
    assert expect in str(err.value)


def test_shipped_euroc_example_validates_and_runs() -> None:
    """docs/examples/vibration_euroc_v1_02.yaml (fitted by benchmarks/sim_to_real.py) is
    a valid block whose 10-80 Hz acceleration level is the sum of its bands."""
    import yaml

    path = Path(__file__).resolve().parents[2] / "docs" / "examples" / "vibration_euroc_v1_02.yaml"
    block = yaml.safe_load(path.read_text())["trajectory"]["vibration"]
    traj = make_trajectory(_cfg(block))
    assert isinstance(traj, VibratingTrajectory)
    acc = np.array([b["accel_rms"] for b in block["broadband"]])
    assert 1.0 < float(np.sqrt((acc**2).sum(0)).min()) < 4.0  # ~2 m/s^2 RMS per axis


def test_simulate_run_applies_vibration_to_the_imu(tmp_path: Path) -> None:
    """Through ``roslan simulate`` (plan, vehicle goal, workers): the IMU of a run with the
    block differs from the same run without it by the configured levels; trajectory.csv
    carries the vibrated motion too."""
    import yaml

    from roslan.cli import main

    vib = {"harmonics": [{"frequency": 10.0, "accel": [0.0, 0.0, 3.0], "gyro": [0.0, 0.4, 0.0]}]}
    rows = {}
    for name, block in (("plain", None), ("shaken", vib)):
        traj = dict(SHORT_TRAJECTORY) | ({"vibration": block} if block else {})
        job = tmp_path / f"{name}.yaml"
        data = {"trajectory": traj, "sensors": [{"type": "imu", "name": "imu", "rate": 400}]}
        job.write_text(yaml.safe_dump(data), encoding="utf-8")
        out = tmp_path / name
        assert main(["simulate", str(job), "-o", str(out), "--quiet", "--no-overview"]) == 0
        rows[name] = np.loadtxt(out / "imu.txt")
    a, b = rows["shaken"], rows["plain"]
    early = a[:, 0] < 0.75  # before the fade
    d = a[early, 1:] - b[early, 1:]
    rms = np.sqrt(np.mean(d * d, axis=0))
    np.testing.assert_allclose(rms[[2, 4]], [3.0 / np.sqrt(2), 0.4 / np.sqrt(2)], rtol=0.05)
    np.testing.assert_array_equal(a[a[:, 0] > 1.0], b[b[:, 0] > 1.0])  # off in the hold
