"""File trajectories: a tau landing exported as TUM poses and flown back."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from roslan.errors import TrajectoryError
from roslan.render.raycast import get_raycaster
from roslan.trajectory import TauTrajectory, Trajectory, TrajectoryConfig
from roslan.trajectory.spline import FileTrajectory

G = np.array([0.0, 0.0, -9.81])


def _write_tum(path: Path, t: np.ndarray, p: np.ndarray, q: np.ndarray) -> None:
    rows = np.column_stack([t, p, q])
    np.savetxt(path, rows, fmt="%.12f", header="t x y z qx qy qz qw")


@pytest.fixture
def tau_and_file(tmp_path: Path) -> tuple[Trajectory, FileTrajectory]:
    tau = TauTrajectory(TrajectoryConfig(), warn=False)
    t = np.arange(0.0, tau.T, 1.0 / 200.0)
    st = tau.state(t)
    path = tmp_path / "flight.txt"
    _write_tum(path, t, st.position, st.quat_xyzw)
    cfg = TrajectoryConfig.model_validate({"file": "flight.txt"})
    return tau, FileTrajectory(cfg, base_dir=tmp_path)


def test_round_trip_positions_and_specific_force(
    tau_and_file: tuple[Trajectory, FileTrajectory],
) -> None:
    tau, ft = tau_and_file
    # between the samples, away from the ends (the tau landing's last 10 % brakes hardest)
    t = np.linspace(0.1, 0.9 * ft.T, 3001)
    a, b = tau.state(t), ft.state(t)
    assert np.abs(a.position - b.position).max() < 1e-3
    # IMU specific force in the body frame, noise-free: R^T (a - g)
    fa = np.einsum("nji,nj->ni", a.R_world_body, a.acceleration - G)
    fb = np.einsum("nji,nj->ni", b.R_world_body, b.acceleration - G)
    rel = np.linalg.norm(fa - fb, axis=1) / np.linalg.norm(fa, axis=1)
    assert rel.max() < 0.01
    # body rates (RotationSpline's derivative, already in the body) against the closed form
    # (RotationSpline's free end conditions bend the rate near the first sample: 2 %)
    assert np.abs(a.omega_body - b.omega_body).max() < 0.02 * np.abs(a.omega_body).max()
    res = ft.residual()
    assert res["position_max_m"] < 1e-9
    assert ft.summary()["fit_residual"] == res


def test_smoothing_keeps_residual_reported(tmp_path: Path) -> None:
    tau = TauTrajectory(TrajectoryConfig(), warn=False)
    t = np.arange(0.0, tau.T, 0.01)
    st = tau.state(t)
    rng = np.random.default_rng(0)
    _write_tum(
        tmp_path / "f.txt", t, st.position + rng.normal(0, 0.002, st.position.shape), st.quat_xyzw
    )
    raw = FileTrajectory(TrajectoryConfig.model_validate({"file": "f.txt"}), base_dir=tmp_path)
    smooth = FileTrajectory(
        TrajectoryConfig.model_validate({"file": "f.txt", "smoothing": 1e-4}), base_dir=tmp_path
    )
    assert raw.residual()["position_max_m"] < 1e-9
    assert 1e-4 < smooth.residual()["position_rms_m"] < 0.01
    tm = np.linspace(0.2, 0.8 * tau.T, 500)
    err_raw = np.abs(raw.state(tm).acceleration - tau.state(tm).acceleration).max()
    err_smooth = np.abs(smooth.state(tm).acceleration - tau.state(tm).acceleration).max()
    assert err_smooth < err_raw / 5


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("0.7 0 0 1 0 0 0 1\n", "not after"),
        ("0.8 0 0 1 0 0 0 1 5\n", "9 columns"),
        ("0.8 0 0 1 0 0 0 2\n", "quaternion norm"),
        ("0.8 0 0 nan 0 0 0 1\n", "NaN"),
        ("5 0 0 1 0 0 0 1\n", "gap of"),
    ],
)
def test_bad_files_name_file_and_line(tmp_path: Path, text: str, needle: str) -> None:
    good = "".join(f"{0.1 * i:.1f} 0 0 1 0 0 0 1\n" for i in range(8))
    path = tmp_path / "bad.txt"
    path.write_text("# header\n" + good + text)
    cfg = TrajectoryConfig.model_validate({"file": str(path)})
    with pytest.raises(TrajectoryError, match=needle) as err:
        FileTrajectory(cfg)
    assert f"{path}:" in str(err.value)
    assert ":10:" in str(err.value) or ":11:" in str(err.value)


@pytest.mark.parametrize(
    ("row", "needle"),
    [
        (",".join(["0.9"] + ["0"] * 7), "8 columns; expected 19"),
        (",".join(["0.9", "0", "nan"] + ["0"] * 16), "all 19 columns must be finite"),
        (",".join(["0.7"] + ["0"] * 18), "not after"),
    ],
)
def test_bad_trajectory_csv_names_file_and_line(tmp_path: Path, row: str, needle: str) -> None:
    from roslan.trajectory.base import COMPONENTS

    good = "".join(
        ",".join([f"{0.1 * i:.1f}", "0", "0", "1"] + ["0"] * 15) + "\n" for i in range(9)
    )
    path = tmp_path / "trajectory.csv"
    path.write_text(",".join(["t", *COMPONENTS]) + "\n" + good + row + "\n")
    cfg = TrajectoryConfig.model_validate({"file": str(path)})
    with pytest.raises(TrajectoryError, match=needle) as err:
        FileTrajectory(cfg)
    assert f"{path}:11:" in str(err.value)


def test_too_few_samples_and_tau_keys(tmp_path: Path) -> None:
    path = tmp_path / "few.txt"
    path.write_text("0 0 0 1 0 0 0 1\n0.1 0 0 1 0 0 0 1\n")
    with pytest.raises(TrajectoryError, match="at least 6"):
        FileTrajectory(TrajectoryConfig.model_validate({"file": str(path)}))
    with pytest.raises(ValueError, match="belong to a tau"):
        TrajectoryConfig.model_validate({"file": "x.txt", "k": 0.3})


def _imu_acc(traj: Trajectory, tmp_path: Path) -> tuple[np.ndarray, np.ndarray]:
    """The real IMU sensor (noise off) along ``traj``: t_ns and specific force (N, 3)."""
    from roslan.io.messages import Flavor, MessageStore
    from roslan.pipeline.context import Context
    from roslan.sensors.imu import Imu, ImuConfig

    cfg = ImuConfig.model_validate(
        {
            "type": "imu",
            "name": "imu",
            "rate": 100,
            "topic": "/imu",
            "pose": {"position": [0.1, 0.0, 0.05], "rpy": [0.0, 0.1, 0.0]},
            "accelerometer_noise_density": 0.0,
            "accelerometer_random_walk": 0.0,
            "gyroscope_noise_density": 0.0,
            "gyroscope_random_walk": 0.0,
        }
    )
    ctx = Context(traj, tmp_path, seed=0, start_time_ns=10**18, sensors=[cfg])
    imu = Imu(cfg)
    store = MessageStore(Flavor.ROS2)
    msgs = list(imu.messages(ctx))
    imu.close(ctx)
    dec = [store.typestore.deserialize_cdr(m.build(store), m.msgtype) for m in msgs]
    acc = [[d.linear_acceleration.x, d.linear_acceleration.y, d.linear_acceleration.z] for d in dec]
    return np.array([m.t_ns for m in msgs]), np.array(acc)


def test_imu_sensor_on_file_trajectory(
    tau_and_file: tuple[Trajectory, FileTrajectory], tmp_path: Path
) -> None:
    tau, ft = tau_and_file
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    ta, fa = _imu_acc(tau, tmp_path / "a")
    tb, fb = _imu_acc(ft, tmp_path / "b")
    assert np.array_equal(ta, tb[: ta.shape[0]]) or np.array_equal(ta[: tb.shape[0]], tb)
    n = min(ta.shape[0], tb.shape[0])
    inner = (ta[:n] > 0.1e9) & (ta[:n] < 0.9 * ft.T * 1e9)
    rel = np.linalg.norm(fa[:n][inner] - fb[:n][inner], axis=1) / np.linalg.norm(
        fa[:n][inner], axis=1
    )
    assert rel.max() < 0.01


def test_clearance_check_on_file_trajectory(
    tau_and_file: tuple[Trajectory, FileTrajectory], tmp_path: Path
) -> None:
    import yaml

    from roslan.scene import check_clearance, load_scene

    _, ft = tau_and_file
    x_wall = float(ft.state([0.5 * ft.T]).position[0, 0])
    doc = {
        "name": "obstacle",
        "goal": {"position": [0.0, 0.0, 0.0]},
        "objects": [
            {"name": "ground", "primitive": {"type": "plane", "size": [100.0, 100.0]}},
            {
                "name": "wall_block",
                "primitive": {"type": "box", "size": [0.2, 20.0, 20.0]},
                "pose": {"position": [x_wall, 0.0, 0.0]},
            },
        ],
    }
    (tmp_path / "scene.yaml").write_text(yaml.safe_dump(doc))
    sc = load_scene(str(tmp_path / "scene.yaml"))
    msg = check_clearance(sc, ft, caster=get_raycaster(sc))
    assert msg is not None
    assert "'wall_block'" in msg
    reported = float(msg.split("t = ")[1].split(" s")[0])
    assert 0.3 * ft.T < reported < 0.5 * ft.T + 0.05


def test_cli_from_file_and_simulate_with_file(tmp_path: Path) -> None:
    """`roslan trajectory --from` writes the four files; a config with `file:` simulates."""
    import json
    import subprocess
    import sys

    tau = TauTrajectory(TrajectoryConfig(), warn=False)
    t = np.arange(0.0, tau.T, 0.02)
    st = tau.state(t)
    _write_tum(tmp_path / "flight.txt", t, st.position, st.quat_xyzw)
    env_py = [sys.executable, "-m", "roslan"]
    run = subprocess.run(
        [*env_py, "trajectory", "--from", "flight.txt", "-o", "out", "--no-plot"],
        cwd=tmp_path, capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["source"] == "file"
    assert summary["samples"] == t.shape[0]
    assert summary["fit_residual"]["position_max_m"] < 1e-6
    rows = np.loadtxt(tmp_path / "out" / "groundtruth.txt")
    # 200 Hz (the default ground_truth_rate): every 4th row is an input pose (50 Hz)
    np.testing.assert_allclose(rows[::4, 0], t, atol=1e-9)
    np.testing.assert_allclose(rows[::4, 1:4], st.position, atol=1e-6)
    (tmp_path / "sim.yaml").write_text(
        "trajectory: {file: flight.txt}\n"
        "sensors:\n  - {type: imu, name: imu, rate: 50}\noutput: {formats: [ros2]}\n"
    )
    sim = subprocess.run(
        [*env_py, "simulate", "sim.yaml", "-o", "sim", "--quiet"],
        cwd=tmp_path, capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert sim.returncode == 0, sim.stderr
    assert "fit_residual" in json.loads((tmp_path / "sim" / "summary.json").read_text())
    # a broken file stops the run with file and line, nothing written
    (tmp_path / "flight.txt").write_text("0 0 0 1 0 0 0 1\n0 0 0 1 0 0 0 1\n" * 4)
    bad = subprocess.run(
        [*env_py, "simulate", "sim.yaml", "-o", "sim2", "--quiet"],
        cwd=tmp_path, capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert bad.returncode != 0
    assert "flight.txt:2:" in bad.stderr
    assert "Traceback" not in bad.stderr
    assert not (tmp_path / "sim2").exists()


def test_trajectory_csv_flies_back_in_its_goal_frame(tmp_path: Path) -> None:
    """roslan's own trajectory.csv (gaps in F) is an input too: with the goal its
    summary.json records, the world path comes back within 1 mm and 1 mrad."""
    import json

    from roslan.frames import rotation_log
    from roslan.trajectory.export import write_trajectory_files

    goal = {"position": [1.5, -2.0, 0.4], "rpy": [0.0, 0.05, 0.7]}
    tau = TauTrajectory(
        TrajectoryConfig.model_validate({"goal": goal, "sample_dt": 0.005}), warn=False
    )
    write_trajectory_files(tau, tmp_path)
    recorded = json.loads((tmp_path / "summary.json").read_text())["goal"]
    assert recorded == goal
    cfg = TrajectoryConfig.model_validate({"file": "trajectory.csv", "goal": recorded})
    ft = FileTrajectory(cfg, base_dir=tmp_path)
    t = np.linspace(0.05, 0.95 * ft.T, 2001)
    a, b = tau.state(t), ft.state(t)
    assert np.abs(a.position - b.position).max() < 1e-3
    R_err = np.einsum("nji,njk->nik", a.R_world_body, b.R_world_body)
    assert np.linalg.norm(rotation_log(R_err), axis=-1).max() < 1e-3
    # without the goal the same file is a different path: the frame matters
    plain = FileTrajectory(
        TrajectoryConfig.model_validate({"file": "trajectory.csv"}), base_dir=tmp_path
    )
    assert np.abs(plain.state(t).position - a.position).max() > 1.0


def test_goal_places_a_tum_file_in_the_world(
    tau_and_file: tuple[Trajectory, FileTrajectory], tmp_path: Path
) -> None:
    from roslan.frames import rpy_to_matrix

    _, ft = tau_and_file
    goal = {"position": [3.0, 0.0, 1.0], "rpy": [0.0, 0.0, np.pi / 2]}
    cfg = TrajectoryConfig.model_validate({"file": "flight.txt", "goal": goal})
    moved = FileTrajectory(cfg, base_dir=tmp_path)
    t = np.linspace(0.0, ft.T, 101)
    R = rpy_to_matrix(np.array(goal["rpy"]))
    expected = ft.state(t).position @ R.T + np.array(goal["position"])
    np.testing.assert_allclose(moved.state(t).position, expected, atol=1e-9)
    np.testing.assert_allclose(
        moved.state(t).R_world_body, np.einsum("ij,njk->nik", R, ft.state(t).R_world_body),
        atol=1e-9,
    )  # fmt: skip


def _allan(x: np.ndarray, m: int) -> float:
    """Non-overlapping Allan deviation of samples ``x`` (N,) over clusters of ``m``."""
    n = x.shape[0] // m
    means = x[: n * m].reshape(n, m).mean(axis=1)
    return float(np.sqrt(0.5 * np.mean(np.diff(means) ** 2)))


def test_imu_noise_is_the_same_on_a_file_trajectory(tmp_path: Path) -> None:
    """Allan-style check: the IMU's noise (measurement minus the noise-free reading) on a
    file trajectory has the white-noise and random-walk Allan deviations of its densities,
    and is the very sequence the tau landing gets (same seed, same instants)."""
    import math

    from roslan.io.messages import Flavor, MessageStore
    from roslan.pipeline.context import Context
    from roslan.sensors.imu import Imu, ImuConfig

    tau = TauTrajectory(TrajectoryConfig.model_validate({"hold": 30.0}), warn=False)
    t = np.arange(0.0, tau.T, 1.0 / 200.0)
    st = tau.state(t)
    _write_tum(tmp_path / "flight.txt", t, st.position, st.quat_xyzw)
    ft = FileTrajectory(
        TrajectoryConfig.model_validate({"file": "flight.txt", "hold": 30.0}), base_dir=tmp_path
    )
    rate, white, walk = 400.0, 0.02, 0.1
    noisy = {
        "type": "imu", "name": "imu", "rate": rate, "topic": "/imu",
        "accelerometer_noise_density": white, "accelerometer_random_walk": walk,
        "gyroscope_noise_density": 0.0, "gyroscope_random_walk": 0.0,
    }  # fmt: skip
    clean = {**noisy, "accelerometer_noise_density": 0.0, "accelerometer_random_walk": 0.0}

    def acc(traj: Trajectory, cfg: dict, folder: str) -> np.ndarray:
        imu_cfg = ImuConfig.model_validate(cfg)
        (tmp_path / folder).mkdir()
        ctx = Context(traj, tmp_path / folder, seed=5, start_time_ns=10**18, sensors=[imu_cfg])
        imu, store = Imu(imu_cfg), MessageStore(Flavor.ROS2)
        msgs = list(imu.messages(ctx))
        imu.close(ctx)
        dec = [store.typestore.deserialize_cdr(m.build(store), m.msgtype) for m in msgs]
        return np.array([[d.linear_acceleration.x, d.linear_acceleration.y,
                          d.linear_acceleration.z] for d in dec])  # fmt: skip

    noise_file = acc(ft, noisy, "fn") - acc(ft, clean, "fc")
    noise_tau = acc(tau, noisy, "tn") - acc(tau, clean, "tc")
    n = min(noise_file.shape[0], noise_tau.shape[0])
    np.testing.assert_allclose(noise_file[:n], noise_tau[:n], atol=1e-9)
    x = noise_file[:, 0]
    # white noise dominates short clusters: sigma(tau) = N / sqrt(tau)
    for m in (1, 4):
        expected = white / math.sqrt(m / rate)
        assert abs(_allan(x, m) / expected - 1) < 0.1
    # the random walk dominates long ones: sigma(tau) = K sqrt(tau / 3)
    m = 400  # 1 s clusters, about 30 of them
    tau_s = m / rate
    expected = math.hypot(white / math.sqrt(tau_s), walk * math.sqrt(tau_s / 3))
    assert 0.6 < _allan(x, m) / expected < 1.5
