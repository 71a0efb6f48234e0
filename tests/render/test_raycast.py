"""Embree ray caster: distances, triangle ids, normals, reflectivity, limits, threading."""

from __future__ import annotations

import numpy as np
import pytest

from range_helpers import box, plane, scene
from roslan.render.raycast import PARALLEL_MIN_RAYS, RayCaster, get_raycaster


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_plane_distances_match_geometry() -> None:
    sc = scene(plane(z=0.0, half=50.0))
    rc = get_raycaster(sc)
    rng = np.random.default_rng(1)
    n = 20000
    origins = np.column_stack(
        [rng.uniform(-5, 5, n), rng.uniform(-5, 5, n), rng.uniform(0.5, 3, n)]
    )
    d = _unit(rng.normal(size=(n, 3)))
    hits = rc.cast(origins, d)
    # independent: t = -z0 / dz for downward rays whose foot point lies on the square
    t = np.where(d[:, 2] < 0, -origins[:, 2] / np.minimum(d[:, 2], -1e-12), np.inf)
    foot = origins + d * np.where(np.isfinite(t), t, 0)[:, None]
    inside = np.isfinite(t) & (np.abs(foot[:, :2]) < 49.9).all(axis=1)
    outside = ~np.isfinite(t) | (np.abs(foot[:, :2]) > 50.1).any(axis=1)
    np.testing.assert_allclose(hits.distance[inside], t[inside], rtol=2e-5, atol=2e-5)
    assert np.isinf(hits.distance[outside]).all()
    assert (hits.triangle[inside] >= 0).all()
    assert (hits.triangle[outside] == -1).all()
    assert hits.distance.dtype == np.float32
    assert hits.triangle.dtype == np.int32


def test_normals_face_the_ray_and_are_unit() -> None:
    sc = scene(plane(z=1.0, half=10.0))
    rc = get_raycaster(sc)
    o = np.array([[0.0, 0.0, 3.0], [0.0, 0.0, -2.0]])
    d = np.array([[0.1, 0.0, -1.0], [0.0, 0.2, 1.0]])
    d = _unit(d)
    hits = rc.cast(o, d)
    np.testing.assert_allclose(hits.normal[0], [0, 0, 1], atol=1e-6)
    np.testing.assert_allclose(hits.normal[1], [0, 0, -1], atol=1e-6)  # from below: flipped
    np.testing.assert_allclose(hits.distance, [2.0 / d[0, 2] * -1, 3.0 / d[1, 2]], rtol=1e-5)
    np.testing.assert_allclose(hits.cos_incidence(d), np.abs(d[:, 2]), rtol=1e-5)


def test_triangle_ids_and_reflectivity_per_object() -> None:
    ground = plane(z=0.0, half=10.0, refl=0.2)
    b = box((-1, -1, 0), (1, 1, 2), refl=0.9)
    sc = scene(ground, b)
    rc = get_raycaster(sc)
    o = np.array([[0.0, 0.0, 5.0], [5.0, 5.0, 5.0]])
    d = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, -1.0]])
    hits = rc.cast(o, d)
    np.testing.assert_allclose(hits.distance, [3.0, 5.0], rtol=1e-6)
    owner = sc.triangles[2]
    assert owner[hits.triangle[0]] == 1  # the box
    assert owner[hits.triangle[1]] == 0  # the ground
    np.testing.assert_allclose(hits.reflectivity, [0.9, 0.2])


def test_max_range_scalar_and_per_ray() -> None:
    rc = get_raycaster(scene(plane()))
    o = np.tile([0.0, 0.0, 2.0], (3, 1))
    d = np.tile([0.0, 0.0, -1.0], (3, 1))
    assert np.isinf(rc.cast(o, d, 1.5).distance).all()
    hits = rc.cast(o, d, np.array([1.0, 2.5, 10.0]))
    assert np.isinf(hits.distance[0])
    np.testing.assert_allclose(hits.distance[1:], [2.0, 2.0])


def test_empty_scene_and_empty_batch() -> None:
    rc = get_raycaster(scene())
    hits = rc.cast(np.zeros((4, 3)), np.tile([1.0, 0, 0], (4, 1)))
    assert np.isinf(hits.distance).all()
    assert (hits.triangle == -1).all()
    rc2 = get_raycaster(scene(plane()))
    assert rc2.cast(np.zeros((0, 3)), np.zeros((0, 3))).distance.shape == (0,)


def test_cached_per_scene() -> None:
    a = scene(plane())
    b = scene(plane())
    assert get_raycaster(a) is get_raycaster(a)
    assert get_raycaster(a) is not get_raycaster(b)


def test_threaded_equals_single_thread() -> None:
    sc = scene(plane(), box((2, -1, 0), (3, 1, 1)), box((-4, -4, 0), (-3, -2, 3)))
    n = 4 * PARALLEL_MIN_RAYS + 17
    rng = np.random.default_rng(3)
    o = np.tile([0.0, 0.0, 1.0], (n, 1))
    d = _unit(rng.normal(size=(n, 3)))
    one = RayCaster(sc, threads=1).cast(o, d)
    two = RayCaster(sc, threads=2).cast(o, d)
    for a, b in zip(one, two, strict=True):
        np.testing.assert_array_equal(a, b)


def test_shape_mismatch_is_an_error() -> None:
    from roslan.errors import RenderError

    rc = get_raycaster(scene(plane()))
    with pytest.raises(RenderError, match="origins"):
        rc.cast(np.zeros((3, 3)), np.zeros((2, 3)))


def test_cast_incidence_matches_cast() -> None:
    sc = scene(plane(refl=0.3), box((1, -1, 0), (2, 1, 1), refl=0.8))
    rng = np.random.default_rng(5)
    o = np.tile([0.0, 0.0, 0.5], (5000, 1))
    d = _unit(rng.normal(size=(5000, 3)))
    rc = get_raycaster(sc)
    hits = rc.cast(o, d, 30.0)
    dist, echo = rc.cast_incidence(o, d, 30.0)
    np.testing.assert_array_equal(dist, hits.distance)
    np.testing.assert_allclose(echo, hits.reflectivity * hits.cos_incidence(d), rtol=1e-6)
    np.testing.assert_allclose(np.unique(hits.reflectivity[hits.hit]), [0.3, 0.8], rtol=1e-6)
    empty = get_raycaster(scene()).cast_incidence(o, d)
    assert np.isinf(empty[0]).all()
    assert (empty[1] == 0).all()


def test_parallel_cast_works_in_a_forked_child() -> None:
    import multiprocessing as mp

    sc = scene(plane())
    n = 2 * PARALLEL_MIN_RAYS
    o = np.tile([0.0, 0.0, 2.0], (n, 1))
    d = np.tile([0.0, 0.0, -1.0], (n, 1))
    RayCaster(sc, threads=2).cast(o, d)  # the parent's pool exists before the fork
    ctx = mp.get_context("fork")
    with ctx.Pool(1) as pool:
        res = pool.apply_async(_child_cast, (sc, o, d))
        dist = res.get(timeout=60)
    np.testing.assert_allclose(dist, 2.0)


def _child_cast(sc: object, o: np.ndarray, d: np.ndarray) -> np.ndarray:
    return RayCaster(sc, threads=2).cast(o, d).distance  # type: ignore[arg-type]


def test_the_hit_record_has_range_point_triangle_and_object() -> None:
    """One record per ray: the point lies ``range`` along the ray on the hit triangle's
    plane, and the object is the scene's owner of that triangle (-1 and NaN: no hit)."""
    ground = plane(z=0.0, half=10.0, refl=0.2)
    b = box((-1, -1, 0), (1, 1, 2), refl=0.9)
    sc = scene(ground, b)
    rc = get_raycaster(sc)
    rng = np.random.default_rng(7)
    n = 500
    o = np.column_stack([rng.uniform(-3, 3, n), rng.uniform(-3, 3, n), np.full(n, 4.0)])
    d = _unit(np.column_stack([rng.normal(0, 0.3, n), rng.normal(0, 0.3, n), -np.ones(n)]))
    d[:20] = _unit(np.array([0.3, 0.1, 1.0]))  # upward: nothing above
    hits = rc.cast(o, d)
    assert (hits.range == hits.distance).all()
    hit = hits.hit
    assert hit[20:].all()
    assert not hit[:20].any()
    np.testing.assert_allclose(hits.point[hit], (o + d * hits.distance[:, None])[hit], atol=1e-5)
    assert np.isnan(hits.point[~hit]).all()
    verts, faces, owner = sc.triangles
    v0 = verts[faces[hits.triangle[hit], 0]].astype(np.float64)
    # the point is on its triangle's plane (independent: the plane through its vertex)
    off = np.einsum("ij,ij->i", hits.point[hit] - v0, hits.normal[hit])
    np.testing.assert_allclose(off, 0.0, atol=1e-4)
    np.testing.assert_array_equal(hits.object[hit], owner[hits.triangle[hit]])
    assert (hits.object[~hit] == -1).all()
    # the box (object 1) where the foot point falls on its top, the ground elsewhere
    foot = o + d * ((4.0 - 2.0) / -d[:, 2])[:, None]
    on_top = hit & (np.abs(foot[:, :2]) < 0.99).all(axis=1)
    assert on_top.sum() > 20
    assert (hits.object[on_top] == 1).all()
    np.testing.assert_allclose(hits.point[on_top][:, 2], 2.0, atol=1e-5)
