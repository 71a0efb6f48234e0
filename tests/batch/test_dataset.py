"""The paper's dataset preset: the plan against Section 5, and a tiny end-to-end run."""

from __future__ import annotations

import csv
import itertools
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from roslan.batch import make_tasks
from roslan.batch.paper import dataset_plan, default_sensor_suite
from roslan.config.sim import SimConfig
from roslan.errors import ConfigError
from roslan.render.raycast import get_raycaster
from roslan.scene import check_clearance, load_scene
from roslan.trajectory.base import Trajectory
from roslan.trajectory.config import TrajectoryConfig
from roslan.trajectory.generator import TauTrajectory
from roslan.vehicle import base_link_trajectory


@pytest.fixture(scope="module")
def plan() -> list:  # type: ignore[type-arg]
    # scene loads per simulation seed are slow; clearance has its own test below
    return dataset_plan(["warehouse", "refinery"], seed=0, check_clearance=False)


def _traj(run) -> Trajectory:  # type: ignore[no-untyped-def]
    return TauTrajectory(TrajectoryConfig.model_validate(run.config["trajectory"]), warn=False)


def test_six_landings_per_scene_with_the_papers_parameters(plan) -> None:  # type: ignore[no-untyped-def]
    assert [r.scene for r in plan] == ["warehouse"] * 6 + ["refinery"] * 6
    for scene in ("warehouse", "refinery"):
        runs = [r for r in plan if r.scene == scene]
        pairs = {(r.kappa_x, r.kappa_y) for r in runs}
        assert len(pairs) == 6  # six different (kappa_x, kappa_y) pairs
        goal = load_scene(scene)
        for r in runs:
            traj = _traj(r)
            st = traj.state(np.array([0.0, traj.T]))
            x0, y0, z0 = st.gaps[0, :3]
            assert traj.k == 0.5
            # final approach angle pi/6: the start seen from the goal at 30 deg elevation
            assert math.atan2(z0, math.hypot(x0, y0)) == pytest.approx(math.pi / 6, abs=1e-12)
            speed = float(np.linalg.norm(st.rates[0, :3]))
            assert 3.0 <= speed <= 5.0
            assert speed == pytest.approx(r.speed, rel=1e-12)
            # k * kappa < 0.5: every gap closes with zero rate and bounded deceleration
            assert 0.5 * max(r.kappa_x, r.kappa_y) < 0.5
            assert traj.warnings() == []
            np.testing.assert_allclose(st.gaps[1, :3], 0.0, atol=1e-9)
            np.testing.assert_allclose(st.rates[1, :3], 0.0, atol=1e-9)
            acc = traj.state(np.linspace(0.0, traj.T, 2001)).accels[:, :3]
            assert np.all(np.isfinite(acc))
            assert np.abs(acc).max() < 20.0
            # lands on the scene's marker, table every 0.1 s
            assert tuple(r.config["trajectory"]["goal"]["position"]) == pytest.approx(
                goal.goal_position
            )
            assert tuple(r.config["trajectory"]["goal"]["rpy"]) == pytest.approx(goal.goal_rpy)
            assert r.config["trajectory"]["sample_dt"] == 0.1
            assert r.config["scene"] == scene
    speeds = sorted({r.speed for r in plan})
    assert speeds[0] == 3.0
    assert speeds[-1] == 5.0


@pytest.mark.parametrize(("scene", "number"), [("warehouse", 1), ("refinery", 4)])
def test_planned_paths_clear_the_scene_built_with_their_seed(plan, scene: str, number: int) -> None:  # type: ignore[no-untyped-def]
    # the simulation builds its scene with its own seed (clutter moves): the planned
    # landing must clear that scene (a full clearance-checked plan loads 6 scenes per
    # scene name, too slow here; the end-to-end test runs that code path)
    run = next(r for r in plan if r.scene == scene and r.number == number)
    # as roslan simulate checks it: the vehicle's body and every sensor of the run
    sc = load_scene(scene, seed=run.seed)
    cfg = SimConfig.model_validate(run.config)
    traj = TauTrajectory(base_link_trajectory(cfg.trajectory, cfg.vehicle, sc), warn=False)
    assert (
        check_clearance(
            sc, traj, caster=get_raycaster(sc), vehicle=cfg.vehicle, sensors=cfg.sensors
        )
        is None
    )


def test_paths_are_visibly_different(plan) -> None:  # type: ignore[no-untyped-def]
    # normalized horizontal path shape: (x/x0, y/y0) against normalized height z/z0
    zq = np.linspace(0.05, 0.95, 19)
    shapes = []
    for r in plan[:6]:
        traj = _traj(r)
        t = np.linspace(0.0, traj.T, 4001)
        g = traj.state(t).gaps
        z = g[:, 2] / g[0, 2]
        order = np.argsort(z)
        nx = np.interp(zq, z[order], (g[:, 0] / g[0, 0])[order])
        ny = np.interp(zq, z[order], (g[:, 1] / g[0, 1])[order])
        shapes.append((np.concatenate([nx, ny]), g[0, :2]))
    for (a, pa), (b, pb) in itertools.combinations(shapes, 2):
        # different closure profile, or a start at least 1 m apart
        assert np.abs(a - b).max() > 0.1 or np.linalg.norm(pa - pb) > 1.0


def test_paper_sensor_suite_validates() -> None:
    suite = default_sensor_suite()
    types = {s["type"] for s in suite}
    assert types == {"camera", "event_camera", "sonar", "imu", "lidar"}
    assert next(s for s in suite if s["type"] == "event_camera")["sensor"] == "davis346"
    assert next(s for s in suite if s["type"] == "lidar")["preset"] == "hdl32e"
    runs = dataset_plan(["empty"], seed=0)
    tasks = make_tasks([r.config for r in runs], Path.cwd(), names=[r.folder for r in runs])
    assert [t.error for t in tasks] == [None] * 6


def test_seeds_are_deterministic_and_distinct() -> None:
    a = [r.seed for r in dataset_plan(["empty", "warehouse"], seed=7, check_clearance=False)]
    b = [r.seed for r in dataset_plan(["empty", "warehouse"], seed=7, check_clearance=False)]
    c = [r.seed for r in dataset_plan(["empty", "warehouse"], seed=8, check_clearance=False)]
    assert a == b
    assert len(set(a)) == 12
    assert not set(a) & set(c)


def test_duration_override_sets_touchdown_time() -> None:
    runs = dataset_plan(["empty"], duration=0.25, sensors=[])
    for r in runs:
        assert pytest.approx(0.25, rel=1e-9) == _traj(r).T
        assert r.config["sensors"] == []


@pytest.mark.parametrize(
    ("kwargs", "expect"),
    [
        ({"scenes": []}, "at least one scene"),
        ({"scenes": ["empty", "empty"]}, "must not repeat"),
        ({"scenes": ["empty"], "duration": -1.0}, r"--duration = -1.0"),
        ({"scenes": ["empty"], "seed": -2}, r"--seed = -2"),
    ],
)
def test_bad_options(kwargs: dict, expect: str) -> None:  # type: ignore[type-arg]
    with pytest.raises(ConfigError, match=expect):
        dataset_plan(**kwargs)


def test_tiny_dataset_end_to_end(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from roslan.cli import main

    sensors = tmp_path / "sensors.yaml"
    sensors.write_text(
        yaml.safe_dump(
            [
                {"type": "imu", "name": "imu", "rate": 200.0, "topic": "/imu"},
                {
                    "type": "sonar",
                    "name": "sonar",
                    "rate": 20.0,
                    "topic": "/sonar",
                    "axis": [0.0, 0.0, -1.0],
                },
            ]
        )
    )
    out = tmp_path / "ds"
    args = ["dataset", "-o", str(out), "--scenes", "empty", "--sensors", str(sensors),
            "--duration", "0.2", "--format", "ros1", "--workers", "0", "--quiet"]  # fmt: skip
    assert main(args) == 0
    with (out / "index.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    plan = dataset_plan(["empty"], duration=0.2)
    assert [r["folder"] for r in rows] == [p.folder for p in plan]
    for row, p in zip(rows, plan, strict=True):
        run = json.loads((out / p.folder / "run.json").read_text())
        assert run["complete"] is True
        assert (out / p.folder / "landing.bag").is_file()
        assert (out / p.folder / "trajectory.csv").is_file()
        assert float(row["kappa_x"]) == p.kappa_x
        assert float(row["kappa_y"]) == p.kappa_y
        assert float(row["speed_mps"]) == p.speed
        assert float(row["k"]) == 0.5
        assert float(row["approach_angle_rad"]) == pytest.approx(math.pi / 6, abs=1e-9)
        assert float(row["duration_s"]) == pytest.approx(run["trajectory_duration_s"], abs=1e-9)
        assert int(row["messages"]) == run["messages_total"]
        assert int(row["messages"]) == sum(t["messages"] for t in run["topics"].values())
        assert int(row["events"]) == 0  # no event camera in this suite
        assert int(row["seed"]) == run["seed"] == p.seed
        assert row["status"] == "complete"
        topics = set(run["topics"])
        assert {"/imu", "/sonar", "/tf"} <= topics
    png = (out / "trajectories_empty.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(png) > 20_000
    readme = (out / "README.md").read_text()
    assert "index.csv" in readme
    assert "empty_06" in readme
    # rerun: all six skipped, nothing rewritten
    mtimes = [(out / p.folder / "run.json").stat().st_mtime_ns for p in plan]
    assert main(args) == 0
    assert [(out / p.folder / "run.json").stat().st_mtime_ns for p in plan] == mtimes
    batch = json.loads((out / "batch.json").read_text())
    assert batch["counts"] == {"skipped": 6}
    capsys.readouterr()
    assert main([*args, "--dry-run"]) == 0  # the same dataset: done, nothing refused
    assert "empty_06" in capsys.readouterr().out
    # the default sensor suite into the same folder: the run would refuse every task
    assert main(["dataset", "-o", str(out), "--scenes", "empty", "--dry-run"]) == 1
    assert "0 valid, 6 invalid" in capsys.readouterr().out


def test_the_dry_run_builds_each_landings_scene_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The plan's clearance check and the run's checks share the scene each landing is
    built with (its own seed): one build per landing, whatever the weak scene table
    keeps; main built each twice."""
    import roslan.scene.builtin as builtin
    import roslan.scene.loader as loader
    from roslan.cli import main

    built: list[int] = []
    real = builtin.empty

    def counted(seed: int = 0) -> Any:
        built.append(seed)
        return real(seed)

    monkeypatch.setattr(builtin, "empty", counted)
    loader._BUILT.clear()
    try:
        out = tmp_path / "ds"
        args = ["dataset", "-o", str(out), "--scenes", "empty", "refinery", "--dry-run"]
        assert main(args) == 0
    finally:
        loader._BUILT.clear()
    plan = dataset_plan(["empty", "refinery"], check_clearance=False)
    seeds = [r.seed for r in plan if r.scene == "empty"]
    assert len(seeds) == 6
    assert [built.count(s) for s in seeds] == [1] * 6  # each landing's scene built once
    assert set(built) == {0, *seeds}  # and the goal's (seed 0)
    assert "12 valid, 0 invalid" in capsys.readouterr().out
    assert not out.exists()
