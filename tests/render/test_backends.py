"""A scene's back ends are owned, not cached: a run's bundle renders and casts through
the same objects as its clearance check, and once the bundle is released and the scene
dropped, nothing in the process keeps the scene alive (renderer, caster and the built-in
scene table are weak)."""

from __future__ import annotations

import gc
import weakref

import numpy as np

from range_helpers import box, plane, scene
from roslan.render.backends import SceneBackends
from roslan.scene import load_scene


def _look_down(z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])  # optical z down, x along world x
    T[2, 3] = z
    return T


def test_a_released_bundle_lets_its_scene_go() -> None:
    sc = scene(plane(z=0.0, half=5.0), box((-0.5, -0.5, 0.0), (0.5, 0.5, 1.0)))
    alive = weakref.ref(sc)
    b = SceneBackends(sc)
    hits = b.caster().cast(np.array([[0.0, 0.0, 3.0]]), np.array([[0.0, 0.0, -1.0]]))
    np.testing.assert_allclose(hits.distance, [2.0], rtol=1e-6)
    K = np.array([[40.0, 0.0, 31.5], [0.0, 40.0, 23.5], [0.0, 0.0, 1.0]])
    depth = b.renderer().render(_look_down(3.0), K, 64, 48, color=False).depth
    assert depth is not None
    assert abs(float(depth[24, 32]) - 2.0) < 1e-3  # the box's top under the camera
    assert b.caster() is b.caster()  # one caster per bundle: beams, clearance, contact
    del sc, hits
    gc.collect()
    assert alive() is not None  # the bundle holds its scene while in use
    b.release()
    gc.collect()
    assert alive() is None  # no global cache kept it


def test_built_in_scenes_are_shared_while_held_and_freed_after() -> None:
    a = load_scene("empty", seed=11)
    assert load_scene("empty", seed=11) is a  # shared while someone holds it
    assert load_scene("empty", seed=12) is not a
    alive = weakref.ref(a)
    del a
    gc.collect()
    assert alive() is None
