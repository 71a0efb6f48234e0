"""Containment: a vehicle inside a closed object is a collision, in ``simulate`` (its
dry run names the object) and in the closed-loop environment (``reason: collision``)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from roslan.cli import main
from roslan.scene import load_scene
from roslan.scene.containment import CONTACT_DEPTH, closed_objects, inside

BOX = {"centre": (0.0, 0.0, 1.0), "size": 0.6}


def _scene_file(folder: Path) -> Path:
    """A 0.6 m closed box (``crate``), a closed sphere and an open floor quad."""
    path = folder / "room.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "name": "room",
                "objects": [
                    {
                        "name": "crate",
                        "primitive": {"type": "box", "size": [BOX["size"]] * 3},
                        "pose": {"position": list(BOX["centre"])},
                    },
                    {
                        "name": "ball",
                        "primitive": {"type": "sphere", "radius": 0.5},
                        "pose": {"position": [3.0, 0.0, 1.0]},
                    },
                    {"name": "floor", "primitive": {"type": "plane", "size": [20.0, 20.0]}},
                ],
            }
        )
    )
    return path


def _hold(folder: Path, name: str, position: tuple[float, float, float]) -> Path:
    """A pose file holding base_link still at ``position`` for 1 s (100 Hz)."""
    t = np.arange(0.0, 1.0 + 1e-9, 0.01)
    rows = np.column_stack(
        [t, np.tile(position, (t.size, 1)), np.tile([0, 0, 0, 1.0], (t.size, 1))]
    )
    path = folder / name
    np.savetxt(path, rows, "%.9f")
    return path


def _job(folder: Path, poses: str, **imu: Any) -> Path:
    _scene_file(folder)
    job = {
        "trajectory": {"file": poses},
        "scene": "room.yaml",
        "sensors": [{"type": "imu", "name": "imu", "rate": 200.0, **imu}],
    }
    path = folder / f"{Path(poses).stem}.yaml"
    path.write_text(yaml.safe_dump(job))
    return path


def test_inside_agrees_with_the_closed_form_and_skips_open_surfaces(tmp_path: Path) -> None:
    scene = load_scene(str(_scene_file(tmp_path)))
    names = [scene.objects[o.index].name for o in closed_objects(scene)]
    assert names == ["crate", "ball"]  # the floor quad is open: it has no inside
    rng = np.random.default_rng(4)
    p = rng.uniform([-1.0, -1.0, -0.5], [4.0, 1.0, 2.5], size=(20_000, 3))
    c, h = np.asarray(BOX["centre"]), BOX["size"] / 2
    box_d = np.abs(p - c).max(axis=1)  # < h inside the box
    ball_d = np.linalg.norm(p - [3.0, 0.0, 1.0], axis=1)  # < 0.5 inside the ball
    # away from the surfaces (the sphere is faceted: its facets lie within 1 cm of it)
    clear = (np.abs(box_d - h) > 1e-3) & (np.abs(ball_d - 0.5) > 0.01)
    got = inside(scene, p[clear])
    idx = {o.name: i for i, o in enumerate(scene.objects)}
    want = np.where(box_d[clear] < h, idx["crate"], np.where(ball_d[clear] < 0.5, idx["ball"], -1))
    assert np.array_equal(got, want)
    assert (want == idx["crate"]).sum() > 100
    assert (want == idx["ball"]).sum() > 100
    # below the floor is not inside anything: an open quad has no inside
    assert inside(scene, np.array([[5.0, 5.0, -1.0]]))[0] == -1


@pytest.mark.parametrize("depth", [0.0, 0.05])
def test_inside_tests_all_boxes_at_once_as_it_does_object_by_object(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, depth: float
) -> None:
    import roslan.scene.containment as containment

    scene = load_scene(str(_scene_file(tmp_path)))
    rng = np.random.default_rng(7)
    p = rng.uniform([-1.0, -1.0, -0.5], [4.0, 1.0, 2.5], size=(3_000, 3))
    batched = inside(scene, p, depth)  # 3000 points x 2 objects: one array test
    monkeypatch.setattr(containment, "_BOX_BATCH", 0)  # object by object
    assert np.array_equal(batched, inside(scene, p, depth))
    assert (batched >= 0).sum() > 30


def test_a_contact_point_on_a_surface_is_not_inside_but_one_below_it_is(tmp_path: Path) -> None:
    scene = load_scene(str(_scene_file(tmp_path)))
    top = BOX["centre"][2] + BOX["size"] / 2
    on = np.array([[0.1, 0.1, top], [0.1, 0.1, top - 0.5 * CONTACT_DEPTH]])
    deep = np.array([[0.1, 0.1, top - 5 * CONTACT_DEPTH]])
    assert (inside(scene, on, CONTACT_DEPTH) == -1).all()
    assert inside(scene, deep, CONTACT_DEPTH)[0] == 0
    assert inside(scene, on[1:])[0] == 0  # a body point has no tolerance


def test_simulate_dry_run_refuses_a_body_held_inside_a_box(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _hold(tmp_path, "inside.txt", BOX["centre"])
    job = _job(tmp_path, "inside.txt")
    out = tmp_path / "out"
    assert main(["simulate", str(job), "-o", str(out), "--dry-run"]) != 0
    err = capsys.readouterr().err
    assert "lies inside object 'crate'" in err
    assert "at t = 0.000 s" in err
    assert not out.exists()


def test_a_vehicle_beside_the_box_passes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _hold(tmp_path, "beside.txt", (1.0, 0.0, 1.0))  # 0.7 m from the box's centre
    job = _job(tmp_path, "beside.txt")
    assert main(["simulate", str(job), "-o", str(tmp_path / "out"), "--dry-run"]) == 0
    assert "1 valid, 0 invalid" in capsys.readouterr().out


def test_a_sensor_mounted_inside_the_box_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # base_link 0.5 m from the box's centre: the body (0.30 m long) is clear of the box's
    # +x face (x = 0.3); the IMU, mounted 0.3 m behind base_link, is at x = 0.2, inside
    _hold(tmp_path, "mounted.txt", (0.5, 0.0, 1.0))
    job = _job(tmp_path, "mounted.txt", pose={"position": [-0.3, 0.0, 0.0]})
    assert main(["simulate", str(job), "-o", str(tmp_path / "out"), "--dry-run"]) != 0
    err = capsys.readouterr().err
    assert "sensor 'imu' (origin) lies inside object 'crate'" in err
    # the same mount beside the box passes: the refusal is the mount's
    job = _job(tmp_path, "mounted.txt", pose={"position": [0.0, 0.0, 0.0]})
    assert main(["simulate", str(job), "-o", str(tmp_path / "out"), "--dry-run"]) == 0


def test_a_foot_deep_in_the_box_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # base_link 6 cm above the box's top face: the body (4 cm half-height) clears it, the
    # default feet 8 cm below base_link are 2 cm deep in the box
    _hold(tmp_path, "deep.txt", (0.0, 0.0, 1.3 + 0.06))
    job = _job(tmp_path, "deep.txt")
    assert main(["simulate", str(job), "-o", str(tmp_path / "out"), "--dry-run"]) != 0
    assert "foot 1 [0.05 0.05 -0.08] lies inside object 'crate'" in capsys.readouterr().err


def test_the_env_ends_an_episode_started_inside_a_box_with_a_collision(tmp_path: Path) -> None:
    pytest.importorskip("roslan.render.gl")
    from env_helpers import tiny_config
    from roslan.env import LandingEnv

    scene = _scene_file(tmp_path)
    cfg = tiny_config(scene=str(scene))
    cfg["trajectory"]["initial"]["position"] = list(BOX["centre"])  # the feet's centroid
    cfg["trajectory"]["goal"]["position"] = [0.0, 0.0, 0.0]
    env = LandingEnv(cfg)
    try:
        env.reset(seed=1)
        _, _, terminated, truncated, info = env.step(np.zeros(6, np.float32))
    finally:
        env.close()
    assert terminated
    assert not truncated
    ep = info["episode"]
    assert ep["reason"] == "collision"
    assert "inside object 'crate'" in ep["detail"]
    assert json.dumps(ep)  # episode.json-ready


def test_feet_may_sink_into_a_floor_markings_paint_on_landing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Only the start counts for the contact points: a landing whose feet end 3 mm deep
    in a 6 mm painted marking (a thin closed box, as the warehouse's landing lines) runs."""
    (tmp_path / "room.yaml").write_text(
        yaml.safe_dump(
            {
                "name": "painted",
                "objects": [
                    {
                        "name": "paint",
                        "primitive": {"type": "box", "size": [1.0, 1.0, 0.006]},
                        "pose": {"position": [0.0, 0.0, 0.003]},
                    }
                ],
            }
        )
    )
    t = np.arange(0.0, 1.0 + 1e-9, 0.01)
    z = 0.08 + 0.003 + 0.05 * (1.0 - t)  # the feet (8 cm below) from 5 cm above to 3 mm in
    rows = np.column_stack([t, 0 * t, 0 * t, z, np.tile([0, 0, 0, 1.0], (t.size, 1))])
    np.savetxt(tmp_path / "landing.txt", rows, "%.9f")
    job = tmp_path / "job.yaml"
    job.write_text(
        yaml.safe_dump(
            {
                "trajectory": {"file": "landing.txt"},
                "scene": "room.yaml",
                "sensors": [{"type": "imu", "name": "imu", "rate": 200.0}],
            }
        )
    )
    assert main(["simulate", str(job), "-o", str(tmp_path / "out"), "--dry-run"]) == 0
    assert "1 valid, 0 invalid" in capsys.readouterr().out


def test_winding_number_against_closed_forms() -> None:
    """Inside a box exactly; inside an icosphere wherever the sphere's inscribed and
    circumscribed radii decide; either winding order of the same closed surface."""
    import trimesh

    from roslan.scene.containment import winding_number

    rng = np.random.default_rng(3)
    p = rng.uniform(-2.0, 2.0, (3000, 3))
    tri = np.asarray(trimesh.creation.box((1.0, 2.0, 3.0)).triangles)
    truth = np.all(np.abs(p) < [0.5, 1.0, 1.5], axis=1)
    np.testing.assert_array_equal(winding_number(tri, p) > 0.5, truth)
    np.testing.assert_array_equal(winding_number(tri[:, ::-1], p) < -0.5, truth)
    sphere = trimesh.creation.icosphere(2, 1.0)
    tri = np.asarray(sphere.triangles)
    inner = float(np.abs((sphere.triangles_center * sphere.face_normals).sum(axis=1)).min())
    r = np.linalg.norm(p, axis=1)
    decided = (r < inner - 1e-9) | (r > 1.0 + 1e-9)
    w = winding_number(tri, p[decided])
    np.testing.assert_array_equal(w > 0.5, r[decided] < inner)
    np.testing.assert_allclose(np.abs(w - np.round(w)), 0.0, atol=1e-9)  # 0 or 1, no between


def test_inside_gives_the_same_answer_on_every_call() -> None:
    """Random points over the warehouse: the same owners on three calls (trimesh's
    Embree-backed contains gave 62, 60 and 56 inside of 20,000 points)."""
    scene = load_scene("warehouse")
    v = np.concatenate([np.asarray(o.vertices) for o in scene.objects])
    lo, hi = v.min(axis=0), v.max(axis=0)
    p = lo + np.random.default_rng(0).random((3000, 3)) * (hi - lo)
    first = inside(scene, p)
    assert (first >= 0).sum() > 50  # the racks, boxes and barrels hold many of them
    for _ in range(2):
        np.testing.assert_array_equal(inside(scene, p), first)
