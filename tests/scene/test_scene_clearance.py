"""Built-in goals are reachable without collision; collisions are reported with time and object."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from roslan.batch.paper import default_sensor_suite
from roslan.config.base import Pose
from roslan.render.raycast import get_raycaster
from roslan.scene import Scene, check_clearance, load_scene
from roslan.sensors.registry import config_class
from roslan.trajectory import TauTrajectory, Trajectory, TrajectoryConfig
from roslan.vehicle import VehicleConfig, base_link_trajectory

VEHICLE = VehicleConfig()
SUITE = [config_class(s["type"]).model_validate(s) for s in default_sensor_suite()]


def _clear(scene: Scene, traj: Trajectory, **kw: Any) -> str | None:
    """check_clearance through the scene's ray caster (the beam sensors' own)."""
    return check_clearance(scene, traj, caster=get_raycaster(scene), **kw)


def _landing(cfg: TrajectoryConfig, scene) -> Trajectory:  # type: ignore[no-untyped-def]
    """base_link's trajectory: the default vehicle's contact point on the goal."""
    return TauTrajectory(base_link_trajectory(cfg, VEHICLE, scene))


def _goal(name: str) -> dict:
    s = load_scene(name)
    return Pose(position=s.goal_position, rpy=s.goal_rpy).model_dump()


@pytest.mark.parametrize("name", ["warehouse", "refinery", "empty"])
def test_default_trajectory_is_clear(name: str) -> None:
    cfg = TrajectoryConfig.model_validate({"goal": _goal(name), "hold": 0.5})
    assert cfg.initial.position == (-8.0, 2.0, 4.6)
    scene = load_scene(name)
    traj = _landing(cfg, scene)
    assert _clear(scene, traj, vehicle=VEHICLE, sensors=SUITE) is None


@pytest.mark.parametrize("name", ["warehouse", "refinery"])
@pytest.mark.parametrize("seed", [0, 1])
def test_paper_dataset_approaches_are_clear(name: str, seed: int) -> None:
    scene = load_scene(name, seed=seed)
    failures = []
    for distance in (8.0, 10.0, 12.0):
        for heading in np.linspace(-math.pi / 4, math.pi / 4, 5):
            for kx, ky in ((0.4, 0.6), (0.9, 0.9), (0.3, 0.3)):
                cfg = TrajectoryConfig.model_validate(
                    {
                        "goal": _goal(name),
                        "kappa": {"x": kx, "y": ky},
                        "approach": {
                            "distance": distance,
                            "angle": math.pi / 6,
                            "heading": float(heading),
                            "speed": 4.0,
                        },
                    }
                )
                traj = _landing(cfg, scene)
                msg = _clear(scene, traj, vehicle=VEHICLE, sensors=SUITE)
                if msg is not None:
                    failures.append((distance, heading, kx, ky, msg))
    assert failures == []


@pytest.mark.parametrize("name", ["warehouse", "refinery"])
def test_ceiling_above_starting_heights(name: str) -> None:
    scene = load_scene(name)
    gz = scene.goal_position[2]
    start_max = gz + 12.0 * math.sin(math.pi / 6)
    # nothing above the goal's approach column below the highest start, at the goal's x-y
    v = scene.triangles[0]
    near = np.linalg.norm(v[:, :2] - np.asarray(scene.goal_position[:2], np.float32), axis=1) < 3.0
    above = v[near, 2] > gz + 0.5
    assert not above.any() or v[near][above, 2].min() > start_max


def _box_scene(tmp_path: Path, centre: list[float]) -> Path:
    doc = {
        "name": "obstacle",
        "goal": {"position": [0.0, 0.0, 0.0]},
        "objects": [
            {"name": "ground", "primitive": {"type": "plane", "size": [100.0, 100.0]}},
            {
                "name": "wall_block",
                "primitive": {"type": "box", "size": [0.4, 8.0, 8.0]},
                "pose": {"position": centre},
            },
        ],
    }
    p = tmp_path / "scene.yaml"
    p.write_text(yaml.safe_dump(doc))
    return p


def test_collision_reported_with_time_and_object(tmp_path: Path) -> None:
    cfg = TrajectoryConfig.model_validate(
        {
            "initial": {"position": [-8.0, 0.0, 4.0], "descent_rate": 1.0},
            "kappa": {"x": 1.0, "y": 1.0},
        }
    )
    traj = TauTrajectory(cfg)
    # the wall stands at x = -4 (face at -4.2): find when the path crosses it, independently
    t = np.linspace(0.0, traj.T, 200001)
    x = traj.state(t).position[:, 0]
    # the body's nose (0.15 m ahead of base_link; no rotation on this path) meets it first
    t_cross = t[np.argmax(x >= -4.2 - 0.15)]
    scene = load_scene(str(_box_scene(tmp_path, [-4.0, 0.0, 4.0])))
    msg = _clear(scene, traj)
    assert msg is not None
    assert "'wall_block'" in msg
    reported = float(msg.split("t = ")[1].split(" s")[0])
    assert reported == pytest.approx(t_cross, abs=0.01)
    assert msg.startswith("the body enters")
    # landing on the feet at the goal is not a collision; a wall off the path is none either
    far = load_scene(str(_box_scene(tmp_path, [30.0, 0.0, 4.0])))
    assert _clear(far, _landing(cfg, far)) is None
    # but base_link itself on the ground puts the body into it
    low = _clear(far, traj)
    assert low is not None
    assert low.startswith("the body enters object 'ground'")


def test_goal_below_ground_is_a_collision(tmp_path: Path) -> None:
    cfg = TrajectoryConfig.model_validate(
        {
            "initial": {"position": [-8.0, 0.0, 4.0], "descent_rate": 1.0},
            "goal": {"position": [0.0, 0.0, -1.0]},
        }
    )
    msg = _clear(load_scene("empty"), TauTrajectory(cfg))
    assert msg is not None
    assert "'ground'" in msg


def test_clearance_and_the_sensors_cast_the_same_hits() -> None:
    """The clearance check and the beam sensors cast through one robust caster: the same
    rays (aimed at the scene's own vertices and edge midpoints, where a non-robust BVH
    lets rays slip between triangles) give the same triangles and ranges both ways."""
    from roslan.pipeline import make_plan
    from roslan.pipeline.plan import load_checked_scene
    from roslan.scene.clearance import path_hit, segment_hits

    cfg = SimConfig_for("warehouse")
    plan = make_plan(cfg, None)
    checked = load_checked_scene(plan)
    assert checked.backends is not None
    assert checked.scene is not None
    ctx = plan.context(checked.traj, None, checked.scene, backends=checked.backends)
    caster = ctx.raycaster()  # what every beam sensor of the run casts with
    assert caster is checked.backends.caster()  # ... and the clearance check
    verts, faces, _ = checked.scene.triangles
    v = verts.astype(np.float64)
    targets = np.concatenate([v[faces[:, 0]], (v[faces[:, 0]] + v[faces[:, 1]]) / 2])
    rng = np.random.default_rng(3)
    targets = targets[rng.choice(targets.shape[0], size=min(20_000, targets.shape[0]))]
    origins = np.array([0.5, -0.3, 2.5]) + rng.normal(0, 0.2, targets.shape)
    seg = targets - origins
    length = np.linalg.norm(seg, axis=1)
    d = seg / length[:, None]
    ends = origins + d * (length + 0.05)[:, None]  # a little past the target
    beams = caster.cast(origins, d, length + 0.05)
    tri, frac = segment_hits(caster, origins, ends)
    np.testing.assert_array_equal(tri, beams.triangle)
    hit = beams.hit
    assert hit.mean() > 0.9  # (a target may hide behind another surface: still a hit)
    np.testing.assert_allclose(
        frac[hit] * (length[hit] + 0.05), beams.distance[hit], rtol=1e-5, atol=1e-4
    )
    # the same segments as a standstill path (two instants, identity attitude)
    k = 64
    pts = np.zeros((k, 3))
    one = path_hit(
        checked.scene,
        caster,
        pts,
        np.array([0.0, 1.0]),
        np.stack([origins[0], ends[0]]),
        np.stack([np.eye(3)] * 2),
    )
    assert (one is not None) == bool(hit[0])
    if one is not None:
        assert one.triangle == int(beams.triangle[0])


def SimConfig_for(scene_name: str) -> Any:
    from roslan.config.sim import SimConfig

    return SimConfig.model_validate(
        {
            "scene": scene_name,
            "trajectory": {"goal": {"position": [2.0, -1.0, 0.01], "rpy": [0.0, 0.0, 0.3]}},
            "sensors": [{"type": "imu", "name": "imu", "rate": 100.0}],
        }
    )
