"""Issue 48, the sensors' side: a box sliding across the view, seen by each back end at
its own instants. Rasterizer depth and ids, ray-cast hits, LiDAR points with their labels,
the event camera's motion field and the DSEC flow, each checked against an independent
calculation (the box's analytic position at that time, a pinhole projection) -- and a
static scene keeps the static fast path."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from motion_helpers import Sliding
from range_helpers import FakeContext, LinearTrajectory
from roslan.config.base import validate_model
from roslan.errors import RenderError
from roslan.render.raycast import RayCaster
from roslan.scene import load_scene
from roslan.scene.instances import scene_labels
from roslan.scene.model import Scene
from roslan.sensors.beams import Lidar, LidarConfig
from roslan.sensors.beams.labels import decode, triangle_labels

SCENE = """\
name: slide
objects:
  - {name: floor, primitive: {type: plane, size: [40, 40]}}
  - {name: box, primitive: {type: box, size: [1.0, 0.8, 0.6]}, pose: {position: [-2.0, 1.5, 0.3]},
     class: crate}
"""
HALF = np.array([0.5, 0.4, 0.3])
C0 = np.array([-2.0, 1.5, 0.3])
V = np.array([4.0, 0.0, 0.0])  # m/s: fast enough that a scan's start is centimetres off


@pytest.fixture(scope="module")
def scenes(tmp_path_factory: pytest.TempPathFactory) -> tuple[Scene, Scene]:
    """The static scene and the same scene with the box sliding at ``V``."""
    path = tmp_path_factory.mktemp("slide") / "slide.yaml"
    path.write_text(SCENE, encoding="utf-8")
    static = load_scene(path)
    box = static.object("box")
    moving = dataclasses.replace(box, motion=Sliding(box.pose.copy(), V, 0.0))
    return static, Scene("slide-moving", (static.object("floor"), moving), static.lights)


def _centre(t: np.ndarray | float) -> np.ndarray:
    return C0 + np.multiply.outer(np.asarray(t, float), V)


def _box_distance(p: np.ndarray, t: np.ndarray | float) -> np.ndarray:
    """Unsigned distance of points (N, 3) to the box's surface at times ``t`` (analytic)."""
    q = np.abs(p - _centre(t)) - HALF
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
    return np.abs(outside + np.minimum(q.max(axis=-1), 0.0))


def _look_down(height: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])  # optical z down, x = world x
    T[:3, 3] = (0.0, 1.5, height)
    return T


def test_caster_meets_the_box_where_it_is_at_each_rays_time(scenes: tuple[Scene, Scene]) -> None:
    static, moving = scenes
    rng = np.random.default_rng(4)
    n = 3000
    t = rng.uniform(0.0, 1.0, n)
    # vertical rays over the box's sweep: the top face (z = 0.6) where the box is then
    xy = np.stack([rng.uniform(-3.0, 3.0, n), rng.uniform(1.0, 2.0, n)], 1)
    o = np.column_stack([xy, np.full(n, 5.0)]).astype(np.float32)
    d = np.tile(np.array([[0.0, 0.0, -1.0]], np.float32), (n, 1))
    hits = RayCaster(moving, threads=1).cast(o, d, t=t)
    c = _centre(t)
    on_top = np.all(np.abs(xy - c[:, :2]) < HALF[:2] - 1e-3, axis=1)
    off = np.any(np.abs(xy - c[:, :2]) > HALF[:2] + 1e-3, axis=1)
    assert on_top.sum() > 200
    assert off.sum() > 200
    np.testing.assert_allclose(hits.distance[on_top], 5.0 - 0.6, atol=1e-5)
    assert (hits.object[on_top] == 1).all()
    np.testing.assert_allclose(hits.normal[on_top], [[0, 0, 1]] * int(on_top.sum()), atol=1e-6)
    np.testing.assert_allclose(hits.distance[off], 5.0, atol=1e-5)
    assert (hits.object[off] == 0).all()
    # the static scene: the box at its file pose at every time, caster unchanged
    base = RayCaster(static, threads=1).cast(o, d)
    again = RayCaster(static, threads=1).cast(o, d, t=t)
    assert base.distance.tobytes() == again.distance.tobytes()


def test_lidar_points_on_the_box_lie_on_it_at_their_own_time(
    scenes: tuple[Scene, Scene], tmp_path: Path
) -> None:
    _, moving = scenes
    H = 1.0
    ctx = FakeContext(moving, LinearTrajectory((0.0, 0.0, H)), tmp_path)
    cfg = {"type": "lidar", "name": "velodyne", "preset": "custom", "azimuth_steps": 900,
           "elevations_deg": [-30.0, -20.0, -14.0, -10.0, -6.0, -3.0, 0.0], "noise_sigma": 0.0,
           "rate": 10.0}  # fmt: skip
    lid = Lidar(validate_model(LidarConfig, cfg, "sim.yaml"))
    t0 = 0.2
    pts = lid.scan(
        ctx.trajectory, ctx.raycaster(), int(t0 * 1e9), ctx.rng("l"), labels=triangle_labels(moving)
    )
    _, inst = decode(pts["label"])
    box_id = next(i.id for i in scene_labels(moving).instances if i.object == "box")
    sel = inst == box_id
    assert sel.sum() > 50
    world = np.stack([pts["x"], pts["y"], pts["z"] + H], axis=1).astype(np.float64)[sel]
    t = t0 + pts["time"][sel].astype(np.float64)
    assert np.ptp(t) > 0.002  # the box's points span part of the turn
    d_own = _box_distance(world, t)
    assert d_own.max() < 0.01, d_own.max()
    # at the scan's start the box was elsewhere: its points on the faces across the motion
    # (the +-x faces; the others slide along themselves) miss it by the distance moved
    d_start = _box_distance(world, np.full(t.shape, t0))
    across = np.abs(np.abs(world[:, 0] - _centre(t)[:, 0]) - HALF[0]) < 2e-3
    far = across & (np.linalg.norm(V) * (t - t0) > 0.02)
    assert far.sum() > 10
    assert (d_start[far] > 0.01).all()
    np.testing.assert_allclose(d_start[far], np.linalg.norm(V) * (t - t0)[far], atol=0.01)


def _renderer(scene: Scene):  # type: ignore[no-untyped-def]
    gl = pytest.importorskip("roslan.render.gl")
    try:
        return gl.Renderer(scene)
    except RenderError as err:  # pragma: no cover - no OpenGL on this machine
        pytest.skip(str(err))


def test_rasterizer_draws_the_box_at_each_render_time(scenes: tuple[Scene, Scene]) -> None:
    static, moving = scenes
    r = _renderer(moving)
    W, Hh, f, height = 96, 64, 40.0, 4.0
    K = np.array([[f, 0, (W - 1) / 2], [0, f, (Hh - 1) / 2], [0, 0, 1.0]])
    T = _look_down(height)
    u = np.arange(W)
    for t in (0.0, 0.45, 0.9, 0.2):  # (out of order: each render places the box anew)
        res = r.render(T, K, W, Hh, color=False, luminance=True, t=t, ids=True)
        # independent: the box top (z = 0.6) spans these columns at the centre row
        x = (u - K[0, 2]) / f * (height - 0.6)
        cx = _centre(t)[0]
        inside = np.abs(x - cx) < HALF[0] - 0.06
        x_floor = (u - K[0, 2]) / f * height  # a ray misses the box if it passes it on
        a, b = x - cx, x_floor - cx  # one side at both the top's and the floor's height
        m = HALF[0] + 0.06
        outside = ((a > m) & (b > m)) | ((a < -m) & (b < -m))
        row = Hh // 2
        np.testing.assert_allclose(res.depth[row, inside], height - 0.6, rtol=1e-4)
        np.testing.assert_allclose(res.depth[row, outside], height, rtol=1e-4)
        owner = moving.triangles[2]
        obj = owner[res.ids[row].astype(np.int64) - 1]
        assert (obj[inside] == 1).all()
        assert (obj[outside] == 0).all()
        assert res.luminance is not None
    r.release()
    # a static scene's render ignores t: the same bytes at any time
    rs = _renderer(static)
    a = rs.render(T, K, W, Hh, color=True, t=0.0)
    b = rs.render(T, K, W, Hh, color=True, t=0.7)
    assert a.color.tobytes() == b.color.tobytes()
    assert rs.buffers.movers == []
    rs.release()
