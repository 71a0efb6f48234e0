"""Touchdown: the vehicle lands on its contact point, nothing enters the scene, range
sensors read the mount height at rest, frames at rest are still, and every sensor instant
lies within the ground-truth record."""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from roslan.cli import main
from roslan.config.base import Pose
from roslan.config.sim import SimConfig
from roslan.frames import quat_xyzw_to_matrix
from roslan.render.raycast import get_raycaster
from roslan.scene import check_clearance, load_scene
from roslan.trajectory import TauTrajectory, TrajectoryConfig
from roslan.vehicle import VehicleConfig, base_link_trajectory

HOLD = 0.3537  # not a multiple of any sensor period: the end falls between samples
EXPOSURE = 0.02

JOB: dict[str, Any] = {
    # T = z0 / (k v0) = 1.0 / (0.5 * 2.0) = 1 s, then HOLD s at rest on the feet
    "trajectory": {
        "k": 0.5,
        "initial": {"position": [-1.5, 0.5, 1.0], "rpy": [0.0, 0.05, 0.2], "descent_rate": 2.0},
        "goal": {"position": [0.5, 0.3, 0.0], "rpy": [0.0, 0.0, 0.4]},
        "hold": HOLD,
    },
    "scene": "empty",
    "seed": 5,
    "output": {"formats": ["ros1"], "ground_truth_rate": 200.0},
    "sensors": [
        {"type": "imu", "name": "imu", "rate": 400.0},
        {
            "type": "sonar",
            "name": "sonar",
            "rate": 40.0,
            "axis": [0.0, 0.0, -1.0],
            "noise_sigma": 0.002,
            "pose": {"position": [0.02, 0.01, -0.03]},
        },
        # 5 cm above the ground at rest, below its 0.1 m minimum range: -inf (REP 117)
        {
            "type": "altimeter",
            "name": "alt_low",
            "topic": "/alt_low",
            "rate": 50.0,
            "pose": {"position": [0.03, 0.0, -0.03]},
        },
        {
            "type": "altimeter",
            "name": "alt_high",
            "topic": "/alt_high",
            "rate": 50.0,
            "min_range": 0.02,
            "noise_sigma": 0.001,
            "pose": {"position": [-0.02, 0.0, 0.04]},
        },
        {
            "type": "lidar",
            "name": "lidar",
            "preset": "vlp16",
            "rate": 10.0,
            "pose": {"position": [0.0, 0.0, 0.06]},
        },
        {
            "type": "camera",
            "name": "cam",
            "rate": 20.0,
            "resolution": [80, 60],
            "fx": 60.0,
            "exposure_time": EXPOSURE,
            "pose": {"position": [0.12, 0.0, 0.0], "rpy": [0.0, 0.35, 0.0]},
        },
        {
            "type": "event_camera",
            "name": "dvs",
            "rate": 25.0,
            "resolution": [64, 48],
            "max_rate": 200.0,
            "pose": {"position": [0.12, 0.03, 0.0], "rpy": [0.0, 0.35, 0.0]},
        },
    ],
}


@pytest.fixture(scope="module")
def landed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("touchdown")
    job = d / "job.yaml"
    job.write_text(yaml.safe_dump(JOB, sort_keys=False))
    out = d / "out"
    assert main(["simulate", str(job), "-o", str(out), "--quiet", "--no-overview"]) == 0
    return out


def _table(path: Path) -> np.ndarray:
    rows = [line.split() for line in path.read_text().splitlines() if line.strip()]
    return np.array([[float(v) for v in r[:2]] for r in rows])


def _final_pose(out: Path) -> tuple[np.ndarray, np.ndarray]:
    last = np.loadtxt(out / "groundtruth.txt")[-1]
    return last[1:4], quat_xyzw_to_matrix(last[4:8])


def test_contact_point_lands_on_the_goal(landed: Path) -> None:
    # independent: the default feet's lowest point, rotated by the final attitude, is at the goal
    p, R = _final_pose(landed)
    feet = np.asarray(VehicleConfig().feet)
    lowest = p + R @ np.array([feet[:, 0].mean(), feet[:, 1].mean(), feet[:, 2].min()])
    assert lowest == pytest.approx(JOB["trajectory"]["goal"]["position"], abs=1e-7)
    assert p[2] == pytest.approx(0.08, abs=1e-7)  # base_link 8 cm above the ground


def test_range_sensors_at_rest_read_the_mount_height(landed: Path) -> None:
    run = json.loads((landed / "run.json").read_text())
    T = run["touchdown_time_s"]
    p, R = _final_pose(landed)
    by_name = {s["name"]: s for s in JOB["sensors"]}

    def height(name: str) -> float:  # mount above the ground plane z = 0, beam straight down
        return float((p + R @ np.asarray(by_name[name]["pose"]["position"]))[2])

    sonar = _table(landed / "range_sonar.txt")
    rest = sonar[sonar[:, 0] > T + 1e-9, 1]
    assert rest.size >= 10
    assert np.all(np.abs(rest - height("sonar")) < 5 * 0.002)
    assert height("sonar") == pytest.approx(0.05, abs=1e-6)
    high = _table(landed / "range_alt_high.txt")
    rest = high[high[:, 0] > T + 1e-9, 1]
    assert np.all(np.abs(rest - height("alt_high")) < 5 * 0.001)
    low = _table(landed / "range_alt_low.txt")
    rest = low[low[:, 0] > T + 1e-9, 1]
    assert height("alt_low") < 0.1  # below its minimum range
    assert rest.size >= 10
    assert np.all(rest == -np.inf)


def test_every_sensor_instant_lies_within_the_ground_truth(landed: Path) -> None:
    from rosbags.highlevel import AnyReader

    run = json.loads((landed / "run.json").read_text())
    end = run["trajectory_duration_s"]
    assert end == pytest.approx(1.0 + HOLD)
    gt = np.loadtxt(landed / "groundtruth.txt")[:, 0]
    start_ns = run["start_time_ns"]
    with AnyReader([landed / "landing.bag"]) as reader:
        conns = [c for c in reader.connections if c.topic == "/ground_truth/pose"]
        stamps = np.array([t for _, t, _ in reader.messages(connections=conns)])
    bag_gt = (stamps - start_ns) * 1e-9
    for record in (gt, bag_gt):
        assert record[0] == 0.0
        assert record[-1] == pytest.approx(end, abs=1e-9)
    lo, hi = 0.0, end + 1e-9
    instants: dict[str, np.ndarray] = {
        "imu": np.loadtxt(landed / "imu.txt")[:, 0],
        "sonar": _table(landed / "range_sonar.txt")[:, 0],
        "alt_high": _table(landed / "range_alt_high.txt")[:, 0],
        "events": np.loadtxt(landed / "events.txt", usecols=0),
        "aps": np.loadtxt(landed / "images.txt", usecols=0),
    }
    cam = np.loadtxt(landed / "cam" / "images.txt", usecols=0)
    instants["cam exposure start"] = cam - EXPOSURE / 2
    instants["cam exposure end"] = cam + EXPOSURE / 2
    firing = []
    for line in (landed / "lidar" / "lidar" / "timestamps.txt").read_text().splitlines():
        scan = np.load(landed / "lidar" / line.split()[1])
        firing.append(scan["stamp"] * 1e-9 + scan["time"].astype(np.float64))
    instants["lidar firings"] = np.concatenate(firing)
    for name, t in instants.items():
        assert t.size > 0, name
        assert t.min() >= lo - 1e-9, name
        assert t.max() <= hi, name
    # the last LiDAR turn is the last one that fits: the next would fire past the end
    span = float(firing[-1].max() - firing[-1].min())
    assert firing[-1].min() + 0.1 + span > end


def test_frames_at_rest_differ_only_by_noise(landed: Path) -> None:
    import cv2

    run = json.loads((landed / "run.json").read_text())
    T = run["touchdown_time_s"]

    def rest_frames(index: Path, margin: float) -> list[np.ndarray]:
        rows = [line.split() for line in index.read_text().splitlines()]
        return [
            cv2.imread(str(index.parent / r[1]), cv2.IMREAD_UNCHANGED)
            for r in rows
            if float(r[0]) - margin > T + 1e-9
        ]

    # no noise configured: the frames of the resting vehicle are identical, byte for byte
    for frames in (
        rest_frames(landed / "cam" / "images.txt", EXPOSURE / 2),
        rest_frames(landed / "images.txt", 0.0),
    ):
        assert len(frames) >= 3
        for a, b in itertools.pairwise(frames):
            assert np.array_equal(a, b)
    # and the event camera sees only its noise at rest: far below its rate in flight
    t = np.loadtxt(landed / "events.txt", usecols=0)
    flying = np.count_nonzero(t < T) / T
    resting = np.count_nonzero(t > T + 0.05) / (HOLD - 0.05)
    assert resting < 0.05 * flying


def test_sensor_below_the_contact_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    job = {
        "trajectory": JOB["trajectory"],
        "scene": "empty",
        "sensors": [
            {
                "type": "altimeter",
                "name": "alt",
                "rate": 50.0,
                "pose": {"position": [0.0, 0.0, -0.12]},
            }
        ],
    }
    path = tmp_path / "job.yaml"
    path.write_text(yaml.safe_dump(job))
    out = tmp_path / "out"
    assert main(["simulate", str(path), "-o", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "sensor 'alt' (origin) enters object 'ground' at t = " in err[0]
    assert "--allow-collision" in err[0]
    # the instant is when the mount crosses z = 0, computed independently
    cfg = SimConfig.model_validate(job)
    traj = TauTrajectory(base_link_trajectory(cfg.trajectory, cfg.vehicle))
    t = np.linspace(0.0, traj.T, 100001)
    st = traj.state(t)
    z = st.position[:, 2] + st.R_world_body[:, 2, :] @ np.array([0.0, 0.0, -0.12])
    reported = float(err[0].split("at t = ")[1].split(" s")[0])
    assert reported == pytest.approx(t[np.argmax(z <= 0.0)], abs=2e-3)
    assert not out.exists()
    # --allow-collision overrides
    assert (
        main(
            ["simulate", str(path), "-o", str(out), "--quiet", "--no-overview", "--allow-collision"]
        )
        == 0
    )


@pytest.mark.parametrize("near_clip", [0.05, 0.2])
def test_camera_near_plane_is_checked(near_clip: float) -> None:
    # a camera looking straight down, 8 cm above the ground at rest: its near plane at
    # 5 cm is clear, at 20 cm it lies under the ground
    cfg = SimConfig.model_validate(
        {
            "trajectory": JOB["trajectory"],
            "sensors": [
                {
                    "type": "camera",
                    "name": "down",
                    "rate": 10.0,
                    "resolution": [40, 30],
                    "near_clip": near_clip,
                    "pose": {"rpy": [0.0, math.pi / 2, 0.0]},
                }
            ],
        }
    )
    scene = load_scene("empty")
    traj = TauTrajectory(base_link_trajectory(cfg.trajectory, cfg.vehicle, scene))
    msg = check_clearance(
        scene, traj, caster=get_raycaster(scene), vehicle=cfg.vehicle, sensors=cfg.sensors
    )
    if near_clip < 0.08:
        assert msg is None
    else:
        assert msg is not None
        assert msg.startswith(
            f"sensor 'down' (near plane, near_clip {near_clip:g} m) enters object 'ground'"
        )


def test_goal_moves_by_the_contact_point() -> None:
    goal = {"position": [1.0, 2.0, 0.5], "rpy": [0.1, -0.05, 0.7]}
    cfg = TrajectoryConfig.model_validate({"goal": goal})
    for vehicle, contact in (
        (VehicleConfig(contact="feet"), (0.0, 0.0, -0.08)),
        (VehicleConfig(contact="grasp", grasp=(0.01, 0.0, -0.07)), (0.01, 0.0, -0.07)),
        (VehicleConfig(feet=[[0.1, 0.0, -0.2], [-0.1, 0.0, -0.1]]), (0.0, 0.0, -0.2)),
    ):
        moved = base_link_trajectory(cfg, vehicle)
        traj = TauTrajectory(moved)
        st = traj.state([traj.T])
        assert st.position[0] + st.R_world_body[0] @ np.array(contact) == pytest.approx(
            goal["position"], abs=1e-9
        )
        assert moved.goal.rpy == cfg.goal.rpy
        assert traj.T == TauTrajectory(cfg).T  # only the goal moves, not the timing


def test_perching_uses_the_grasp_point(tmp_path: Path) -> None:
    scene = load_scene("refinery")
    goal = Pose(position=scene.goal_position, rpy=scene.goal_rpy)
    cfg = TrajectoryConfig.model_validate({"goal": goal.model_dump(), "hold": 0.3})
    v = VehicleConfig(grasp=(0.0, 0.0, -0.06))  # claws 2 cm higher than the feet
    traj = TauTrajectory(base_link_trajectory(cfg, v, scene))
    top = np.asarray(scene.goal_position)
    p = traj.state([traj.duration]).position[0]
    assert p == pytest.approx(top + np.array([0.0, 0.0, 0.06]), abs=1e-9)
    assert check_clearance(scene, traj, caster=get_raycaster(scene), vehicle=v) is None
    default = TauTrajectory(base_link_trajectory(cfg, VehicleConfig(), scene))
    assert check_clearance(scene, default, caster=get_raycaster(scene)) is None
    # `roslan trajectory` flies the same goal (it reads the scene only for this choice)
    job = tmp_path / "perch.yaml"
    job.write_text(
        yaml.safe_dump(
            {
                "trajectory": cfg.model_dump(mode="json"),
                "scene": "refinery",
                "vehicle": {"grasp": [0.0, 0.0, -0.06]},
            }
        )
    )
    assert main(["trajectory", str(job), "-o", str(tmp_path / "t"), "--no-plot"]) == 0
    last = np.loadtxt(tmp_path / "t" / "groundtruth.txt")[-1]
    assert last[1:4] == pytest.approx(top + np.array([0.0, 0.0, 0.06]), abs=1e-8)
    # on the warehouse marker (no perch) the feet are the contact
    wh = load_scene("warehouse")
    goal = Pose(position=wh.goal_position, rpy=wh.goal_rpy)
    cfg = TrajectoryConfig.model_validate({"goal": goal.model_dump()})
    traj = TauTrajectory(base_link_trajectory(cfg, v, wh))
    assert traj.state([traj.T]).position[0][2] == pytest.approx(wh.goal_position[2] + 0.08)


def test_vehicle_block_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "job.yaml"
    path.write_text(yaml.safe_dump({"vehicle": {"grasp": [0.0, 0.0, 0.0]}}))
    assert main(["simulate", str(path), "-o", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "vehicle" in err
    assert "grasp" in err
    assert "below the body" in err
    assert "Traceback" not in err


@pytest.mark.slow
def test_default_job_event_rate_falls_at_touchdown(tmp_path: Path) -> None:
    # the packaged default job with its event camera only (same trajectory, vehicle,
    # scene and mount): near the ground the rate must fall with the speed, not burst
    from importlib.resources import files

    from roslan.pipeline import run_simulation

    data = yaml.safe_load((files("roslan") / "data" / "default.yaml").read_text())
    data["sensors"] = [s for s in data["sensors"] if s["type"] == "event_camera"]
    data["output"]["formats"] = ["ros1"]
    run = run_simulation(
        SimConfig.model_validate(data), tmp_path / "out", quiet=True, overview=False
    )
    T, end = run["touchdown_time_s"], run["trajectory_duration_s"]
    t = np.loadtxt(tmp_path / "out" / "events.txt", usecols=0)
    counts, edges = np.histogram(t, np.arange(0.0, end + 0.01, 0.01))
    flight = counts[edges[1:] <= T - 0.3]
    late = counts[edges[:-1] >= T - 0.3]
    assert late.max() <= 2 * flight.max()
    per_ms, _ = np.histogram(t, np.arange(0.0, end + 0.001, 0.001))
    assert per_ms.max() <= 346 * 260 / 4
