"""The scene at a time (roslan.scene.pose, Scene.at): objects keep their model-frame
geometry and a pose over time; renderer, caster and clearance read the scene at t, and a
static scene is the same (same bytes) at every time."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

from motion_helpers import Sliding
from roslan.errors import RenderError
from roslan.frames import rpy_to_matrix
from roslan.render.raycast import RayCaster
from roslan.scene import load_scene
from roslan.scene.clearance import segment_hits
from roslan.scene.loader import primitive_mesh
from roslan.scene.model import Scene, SceneObject
from roslan.scene.pose import ConstantPose
from roslan.scene.spec import ObjectSpec

POS = (1.5, -0.75, 0.6)
RPY = (0.3, -0.2, 1.1)
SCALE = (1.5, 0.5, 2.0)
BOX = {"type": "box", "size": [1.0, 2.0, 0.5]}


@pytest.fixture(scope="module")
def posed(tmp_path_factory: pytest.TempPathFactory) -> Scene:
    """A scene file: a floor and a box with a non-identity pose and scale."""
    doc = {
        "name": "posed",
        "objects": [
            {"name": "floor", "primitive": {"type": "plane", "size": [20.0, 20.0]}},
            {
                "name": "box",
                "primitive": BOX,
                "pose": {"position": list(POS), "rpy": list(RPY)},
                "scale": list(SCALE),
            },
        ],
    }
    path = tmp_path_factory.mktemp("posed") / "scene.yaml"
    path.write_text(yaml.safe_dump(doc), encoding="utf-8")
    return load_scene(str(path))


def _world_placed(scene: Scene) -> Scene:
    """The same scene built the old way: world-placed triangles only (identity pose, no
    model-frame arrays), placed here independently of the loader (float64, then float32)."""
    objs = []
    for o in scene.objects:
        T = o.pose
        local = o.model_geometry()[0].astype(np.float64) * np.asarray(o.scale)
        world = (T[:3, :3] @ local.T).T + T[:3, 3]
        objs.append(
            SceneObject(o.name, world.astype(np.float32), o.normals, o.uvs, o.faces, o.material)
        )
    return Scene("world_placed", tuple(objs), scene.lights)


def _rays(n: int = 400) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    o = np.tile(np.array([[-4.0, 3.0, 5.0]], np.float32), (n, 1))
    target = np.array(POS) + rng.uniform(-1.5, 1.5, (n, 3))
    d = target - o
    return o, (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)


def test_file_object_keeps_model_geometry_and_its_pose(posed: Scene) -> None:
    box = posed.object("box")
    spec = ObjectSpec.model_validate({"name": "box", "primitive": BOX})
    local, _ = box.model_geometry()
    np.testing.assert_array_equal(
        local, np.asarray(primitive_mesh(spec.primitive).vertices, np.float32)
    )
    T = box.pose_at(7.5)
    np.testing.assert_allclose(T[:3, :3], rpy_to_matrix(np.asarray(RPY)), atol=1e-12)
    np.testing.assert_allclose(T[:3, 3], POS, atol=0)
    assert box.is_static
    assert posed.is_static
    assert isinstance(box.track, ConstantPose)
    # the world triangles are the model geometry placed by the pose
    expect = (local.astype(np.float64) * SCALE) @ T[:3, :3].T + T[:3, 3]
    np.testing.assert_allclose(box.vertices, expect, atol=1e-5)
    assert not np.allclose(box.vertices, local, atol=0.1)


@pytest.mark.parametrize("t", [0.0, 0.37, 12.0])
def test_static_scene_at_any_time_is_its_own_arrays(posed: Scene, t: float) -> None:
    view = posed.at(t)
    assert view.is_static
    assert view.t == t
    assert view.triangles is posed.triangles  # the fast path: no copy, the same bytes
    assert view.bounds is posed.bounds
    for o in posed.objects:
        assert o.vertices_at(t) is o.vertices
    pts = np.random.default_rng(0).normal(size=(10, 3))
    own = np.array([0, 1, -1, 1, 0, 0, 1, 1, 0, -1])
    assert not view.point_velocity(pts, own).any()


def test_posed_file_object_casts_as_world_placed_triangles(posed: Scene) -> None:
    old = _world_placed(posed)
    np.testing.assert_allclose(old.triangles[0], posed.triangles[0], atol=2e-6)
    o, d = _rays()
    a, b = RayCaster(posed).cast(o, d), RayCaster(old).cast(o, d)
    hit = np.isfinite(a.distance)
    assert hit.mean() > 0.3  # most rays meet the box or the floor
    np.testing.assert_array_equal(np.isfinite(b.distance), hit)
    np.testing.assert_array_equal(a.triangle, b.triangle)
    np.testing.assert_allclose(a.distance[hit], b.distance[hit], atol=1e-5)
    assert set(np.asarray(a.object)[hit]) == {0, 1}


def test_renderer_caster_and_clearance_agree_at_every_time(posed: Scene) -> None:
    gl = pytest.importorskip("roslan.render.gl")
    caster = RayCaster(posed)
    o, d = _rays()
    base = caster.cast(o, d)
    hit = np.isfinite(base.distance)
    for t in (0.0, 2.5, np.linspace(0.0, 9.0, o.shape[0])):
        h = caster.cast(o, d, t=t)
        np.testing.assert_array_equal(h.distance, base.distance)
        np.testing.assert_array_equal(h.triangle, base.triangle)
        # clearance: the same rays as segments ending beyond the hits, at the same times
        ends = o.astype(np.float64) + 50.0 * d
        prim, frac = segment_hits(caster, o.astype(np.float64), ends, t)
        np.testing.assert_array_equal(prim, np.where(hit, base.triangle, -1))
        np.testing.assert_allclose(frac[hit] * 50.0, base.distance[hit], rtol=1e-5)
    # the rasterizer's depth at two times and the caster's range along the optical axis
    try:
        r = gl.Renderer(posed)
    except RenderError as err:  # pragma: no cover - no OpenGL on this machine
        pytest.skip(str(err))
    try:
        eye, target = np.array([-4.0, 3.0, 5.0]), np.array(POS)
        z = target - eye
        z /= np.linalg.norm(z)
        x = np.cross(z, [0.0, 0.0, 1.0])
        x /= np.linalg.norm(x)
        T = np.eye(4)
        T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, np.cross(z, x), z, eye
        K = np.array([[60.0, 0, 32.0], [0, 60.0, 32.0], [0, 0, 1.0]])
        d0 = r.render(T, K, 64, 64, color=False, t=0.0).depth
        d1 = r.render(T, K, 64, 64, color=False, t=4.0).depth
        assert d0 is not None
        assert d1 is not None
        np.testing.assert_array_equal(d0, d1)
        c = caster.cast(eye[None].astype(np.float32), z[None].astype(np.float32), t=4.0)
        # pixel (32, 32) is the principal point's: its ray is the optical axis
        assert abs(float(d1[32, 32]) - float(c.distance[0])) < 5e-3 * float(c.distance[0])
    finally:
        r.release()


def test_moving_object_is_placed_at_its_time(posed: Scene) -> None:
    box = posed.object("box")
    v = np.array([0.4, -0.2, 0.1])
    track = Sliding(box.pose.copy(), v, 0.5)
    moving = dataclasses.replace(box, motion=track)
    scene = Scene("moving", (posed.object("floor"), moving), posed.lights)
    assert not moving.is_static
    assert not scene.is_static
    # at t = 0 the track is the file's pose: the same bytes as the static object
    np.testing.assert_array_equal(moving.vertices_at(0.0), box.vertices)
    # at t = 2 the model geometry placed at the track's pose (independent calculation)
    t = 2.0
    c, s = np.cos(0.5 * t), np.sin(0.5 * t)
    Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    p0 = box.vertices.astype(np.float64) - box.pose[:3, 3]
    expect = p0 @ Rz.T + box.pose[:3, 3] + v * t
    view = scene.at(t)
    n_floor = posed.object("floor").vertices.shape[0]
    np.testing.assert_allclose(view.triangles[0][n_floor:], expect, atol=2e-5)
    np.testing.assert_array_equal(view.triangles[0][:n_floor], posed.object("floor").vertices)
    assert view.triangles[1] is scene.triangles[1]
    np.testing.assert_allclose(view.bounds[1], view.triangles[0].max(axis=0))
    # the motion field's object term: v + w x (p - origin) on the box, 0 on the floor
    pts = view.triangles[0][n_floor : n_floor + 4].astype(np.float64)
    own = np.array([1, 1, 0, -1])
    vel = view.point_velocity(pts, own)
    r = pts - (box.pose[:3, 3] + v * t)
    np.testing.assert_allclose(vel[:2], v + 0.5 * np.stack([-r[:2, 1], r[:2, 0], 0 * r[:2, 0]], 1))
    assert not vel[2:].any()
    # the caster casts the moving box where it is at the rays' time
    o = (box.pose[:3, 3] + v * t + [0.0, 0.0, 5.0]).astype(np.float32)[None]
    hit = RayCaster(scene).cast(o, np.array([[0.0, 0.0, -1.0]], np.float32), t=t)
    assert hit.object[0] == 1


def test_scene_file_round_trip_keeps_pose(posed: Scene, tmp_path: Path) -> None:
    from roslan.scene import export_scene

    export_scene(posed, tmp_path / "out")
    again = load_scene(str(tmp_path / "out" / "scene.yaml"))
    np.testing.assert_array_equal(again.object("box").vertices, posed.object("box").vertices)
    np.testing.assert_array_equal(
        again.object("box").model_geometry()[0], posed.object("box").model_geometry()[0]
    )
