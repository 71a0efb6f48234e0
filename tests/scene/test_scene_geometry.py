"""Primitives against analytic facts; built-ins deterministic; textures tileable."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from roslan.scene import load_scene
from roslan.scene import mesh as m
from roslan.scene import textures as tx


def _tm(mesh: m.LocalMesh) -> trimesh.Trimesh:
    return trimesh.Trimesh(mesh.vertices, mesh.faces, process=True)


def _face_normals(mesh: m.LocalMesh) -> np.ndarray:
    t = mesh.vertices[mesh.faces]
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def test_box_volume_area_and_outward_normals() -> None:
    b = m.box((2.0, 3.0, 0.5))
    tm = _tm(b)
    assert tm.is_watertight
    assert tm.volume == pytest.approx(2.0 * 3.0 * 0.5)
    assert tm.area == pytest.approx(2 * (6.0 + 1.0 + 1.5))
    fn = _face_normals(b)
    centres = b.vertices[b.faces].mean(axis=1)
    assert (np.einsum("ij,ij->i", fn, centres) > 0).all()  # winding: outward
    # vertex normals agree with the faces they belong to
    assert np.allclose(b.normals[b.faces[:, 0]], fn)


@pytest.mark.parametrize("segments", [8, 24, 32])
def test_cylinder_radius_height_and_volume(segments: int) -> None:
    r, h = 0.7, 2.5
    c = m.cylinder(r, h, segments)
    assert np.allclose(np.hypot(c.vertices[:, 0], c.vertices[:, 1]).max(), r)
    side = np.abs(c.normals[:, 2]) < 0.5
    assert np.allclose(np.hypot(c.vertices[side, 0], c.vertices[side, 1]), r)
    assert c.vertices[:, 2].min() == pytest.approx(-h / 2)
    assert c.vertices[:, 2].max() == pytest.approx(h / 2)
    tm = _tm(c)
    assert tm.is_watertight
    polygon_area = 0.5 * segments * r * r * math.sin(2 * math.pi / segments)
    assert tm.volume == pytest.approx(polygon_area * h)
    fn = _face_normals(c)
    centres = c.vertices[c.faces].mean(axis=1)
    assert (np.einsum("ij,ij->i", fn, centres) > 0).all()
    assert np.allclose(np.linalg.norm(c.normals, axis=1), 1.0)


def test_cylinder_uvs_are_metres() -> None:
    r, h = 0.5, 2.0
    c = m.cylinder(r, h, 32, caps=False)
    assert c.uvs[:, 0].max() == pytest.approx(2 * math.pi * r)
    assert c.uvs[:, 1].max() == pytest.approx(h)


def test_sphere_and_capsule() -> None:
    s = m.sphere(1.3, 32)
    assert np.allclose(np.linalg.norm(s.vertices, axis=1), 1.3)
    assert np.allclose(s.normals * 1.3, s.vertices)
    tm = _tm(s)
    assert tm.is_watertight
    assert tm.volume == pytest.approx(4 / 3 * math.pi * 1.3**3, rel=0.03)
    assert (np.einsum("ij,ij->i", _face_normals(s), s.vertices[s.faces].mean(axis=1)) > 0).all()
    c = m.capsule(0.4, 3.0, 24)
    assert c.vertices[:, 2].max() == pytest.approx(1.5)
    assert np.hypot(c.vertices[:, 0], c.vertices[:, 1]).max() == pytest.approx(0.4)
    tmc = _tm(c)
    assert tmc.is_watertight
    exact = math.pi * 0.4**2 * (3.0 - 0.8) + 4 / 3 * math.pi * 0.4**3
    assert tmc.volume == pytest.approx(exact, rel=0.03)


def test_box_uvs_metres_and_texture_scale_semantics() -> None:
    b = m.box((4.0, 1.0, 1.0))
    top = b.normals[:, 2] > 0.5
    assert np.ptp(b.uvs[top, 0]) == pytest.approx(4.0)


def test_place_applies_scale_then_pose() -> None:
    b = m.box((1.0, 1.0, 1.0))
    T = m.pose_matrix((1.0, 2.0, 3.0), (0.0, 0.0, math.pi / 2))
    from roslan.scene.model import Material

    o = m.place("b", b, Material(), T, (2.0, 1.0, 1.0))
    # x extent 2 m becomes y extent after a 90 deg yaw
    ext = o.vertices.max(axis=0) - o.vertices.min(axis=0)
    assert np.allclose(ext, [1.0, 2.0, 1.0], atol=1e-6)
    assert np.allclose(o.vertices.mean(axis=0), [1.0, 2.0, 3.0], atol=1e-6)
    assert np.allclose(np.linalg.norm(o.normals, axis=1), 1.0, atol=1e-6)
    assert not o.vertices.flags.writeable


def test_textures_power_of_two_tileable_deterministic() -> None:
    a = tx.concrete(1, 64)
    assert a.shape == (64, 64, 3)
    assert a.dtype == np.uint8
    assert np.array_equal(a, tx.concrete(1, 64))
    assert not np.array_equal(a, tx.concrete(2, 64))
    # tileable: the jump across the wrap-around edge is like any interior jump
    n = tx.fbm(np.random.default_rng(0), 128)
    wrap = np.abs(n[:, 0] - n[:, -1]).mean()
    inner = np.abs(np.diff(n, axis=1)).mean()
    assert wrap < 2 * inner
    with pytest.raises(ValueError, match="power of two"):
        tx.fbm(np.random.default_rng(0), 100)


@pytest.mark.parametrize("name", ["warehouse", "refinery", "empty"])
def test_builtin_sane(name: str) -> None:
    s = load_scene(name)
    assert 1 <= s.n_triangles <= 150_000
    names = [o.name for o in s.objects]
    assert len(set(names)) == len(names)
    for o in s.objects:
        assert o.vertices.dtype == np.float32
        assert o.faces.dtype == np.int32
        assert o.normals.shape == o.vertices.shape
        assert o.uvs.shape == (o.vertices.shape[0], 2)
        assert np.isfinite(o.vertices).all()
        assert np.allclose(np.linalg.norm(o.normals, axis=1), 1.0, atol=1e-4)
        assert o.faces.max() < o.vertices.shape[0]
        tex = o.material.texture
        if tex is not None:
            h, w, _ = tex.shape
            assert h & (h - 1) == 0
            assert w & (w - 1) == 0
    if name != "empty":
        assert s.n_triangles >= 20_000


def test_empty_ground_is_plane_z0() -> None:
    s = load_scene("empty")
    v = s.triangles[0]
    assert np.all(v[:, 2] == 0.0)
    assert np.allclose(s.objects[0].normals, [0.0, 0.0, 1.0])
    assert s.goal_position == (0.0, 0.0, 0.0)


RANDOM_PREFIXES = ("pallet_stack_", "clutter_", "forklift")


def _is_random(name: str) -> bool:
    return name.startswith(RANDOM_PREFIXES) or name.endswith(("_boxes", "_pallets"))


@pytest.mark.parametrize("name", ["warehouse", "refinery"])
def test_builtins_deterministic_and_seed_varies_only_random_parts(name: str) -> None:
    from roslan.scene.refinery import refinery
    from roslan.scene.warehouse import warehouse

    gen = {"warehouse": warehouse, "refinery": refinery}[name]
    a, b, c = gen(0), gen(0), gen(1)
    assert [o.name for o in a.objects] == [o.name for o in b.objects]
    for oa, ob in zip(a.objects, b.objects, strict=True):
        assert np.array_equal(oa.vertices, ob.vertices)
        if oa.material.texture is not None:
            assert np.array_equal(oa.material.texture, ob.material.texture)
    fixed_a = {o.name: o for o in a.objects if not _is_random(o.name)}
    fixed_c = {o.name: o for o in c.objects if not _is_random(o.name)}
    assert fixed_a.keys() == fixed_c.keys()
    for k, o in fixed_a.items():
        assert np.array_equal(o.vertices, fixed_c[k].vertices), k
    rand_a = {o.name: o for o in a.objects if _is_random(o.name)}
    rand_c = {o.name: o for o in c.objects if _is_random(o.name)}
    assert rand_a
    differ = [
        k
        for k in rand_a
        if k not in rand_c
        or rand_a[k].vertices.shape != rand_c[k].vertices.shape
        or not np.array_equal(rand_a[k].vertices, rand_c[k].vertices)
    ]
    assert differ
    assert a.goal_position == c.goal_position


def _flipped(mesh: m.LocalMesh) -> m.LocalMesh:
    return m.LocalMesh(mesh.vertices, -mesh.normals, mesh.uvs, mesh.faces[:, ::-1].copy())


def test_closed_solid_primitives_and_their_failures() -> None:
    box = m.box((1.0, 2.0, 0.5), (3.0, -1.0, 2.0))
    assert m.closed_solid(box.vertices, box.faces)
    assert m.closed_solid(m.cylinder(0.3, 1.0, 12).vertices, m.cylinder(0.3, 1.0, 12).faces)
    for solid in (m.sphere(0.4), m.capsule(0.2, 1.0), m.ring(0.2, 0.5, 0.1)):
        assert m.closed_solid(solid.vertices, solid.faces)
    # open surfaces: a plane, an uncapped tube, a box missing one face
    pl = m.plane((2.0, 2.0))
    tube = m.cylinder(0.3, 1.0, 12, caps=False)
    assert not m.closed_solid(pl.vertices, pl.faces)
    assert not m.closed_solid(tube.vertices, tube.faces)
    assert not m.closed_solid(box.vertices, box.faces[2:])
    # inside out (clockwise from outside), and a two-sided sheet (closed, no volume)
    inv = _flipped(box)
    assert not m.closed_solid(inv.vertices, inv.faces)
    sheet = m.merge([pl, _flipped(pl)])
    assert not m.closed_solid(sheet.vertices, sheet.faces)
    # a corner copy moved by 1 mm leaves a crack; by a float32 ulp it still merges
    v = box.vertices.astype(np.float32).copy()
    v[0, 0] = np.nextafter(v[0, 0], np.float32(10.0))
    assert m.closed_solid(v, box.faces)
    v[0, 0] += 1e-3
    assert not m.closed_solid(v, box.faces)
    assert not m.closed_solid(np.zeros((0, 3)), np.zeros((0, 3), np.int64))


def test_closed_solid_compound_parts() -> None:
    a = m.box((1.0, 1.0, 1.0), (0.0, 0.0, 0.0))
    touching = m.box((1.0, 1.0, 1.0), (1.0, 1.0, 0.0))  # shares the edge x = y = 0.5
    overlapping = m.box((1.0, 1.0, 1.0), (0.3, 0.2, 0.1))
    far = m.cylinder(0.2, 0.5, 8)
    for parts in ([a, touching], [a, overlapping], [a, transformed_far(far)]):
        mesh = m.merge(parts)
        assert m.closed_solid(mesh.vertices, mesh.faces)
    # one part inside out: not a solid seen from outside, even though every edge matches
    mixed = m.merge([a, _flipped(m.box((0.5, 0.5, 0.5), (3.0, 0.0, 0.0)))])
    assert not m.closed_solid(mixed.vertices, mixed.faces)
    # conservative: a hollow box (cavity faces turned into the cavity) would be safe to
    # cull from outside, but its cavity is a part of negative volume like an inside-out one
    hollow = m.merge([m.box((2.0, 2.0, 2.0)), _flipped(m.box((1.0, 1.0, 1.0)))])
    assert not m.closed_solid(hollow.vertices, hollow.faces)


def transformed_far(mesh: m.LocalMesh) -> m.LocalMesh:
    return m.transformed(mesh, m.pose_matrix((5.0, 0.0, 0.0), (0.3, 0.2, 0.1)))


@pytest.mark.parametrize("name", ["warehouse", "refinery"])
def test_builtin_objects_are_closed_solids(name: str) -> None:
    # every built-in object is made of closed primitives: the renderer culls their back faces
    s = load_scene(name)
    assert all(m.closed_solid(o.vertices, o.faces) for o in s.objects)


def test_components_match_scipy() -> None:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    rng = np.random.default_rng(5)
    for n, e in ((50, 20), (400, 380), (2000, 1990), (30, 0)):
        a = rng.integers(0, n, size=e)
        b = rng.integers(0, n, size=e)
        label = m._components(n, a, b)
        k, ref = connected_components(
            coo_matrix((np.ones(e), (a, b)), shape=(n, n)), directed=False
        )
        # same partition: a bijection between the labellings
        pairs = np.unique(np.stack([label, ref], axis=1), axis=0)
        assert len(pairs) == k == np.unique(label).size
        assert np.all(label <= np.arange(n))  # the smallest vertex of each part


def test_closed_solid_keys_do_not_collide_at_the_extremes() -> None:
    # vertices at +-(largest coordinate) fill the key fields to their ends: an open
    # mesh whose corners would alias another's corners must stay open
    rng = np.random.default_rng(11)
    for _ in range(20):
        b = m.box(rng.uniform(0.1, 5.0, size=3), rng.uniform(-3, 3, size=3))
        v = b.vertices
        assert m.closed_solid(v, b.faces)
        assert not m.closed_solid(v, b.faces[1:])
        extreme = v / np.abs(v).max()  # every coordinate in [-1, 1], some at +-1
        assert m.closed_solid(extreme, b.faces)
        assert not m.closed_solid(extreme, b.faces[:-1])


def test_closed_solid_merges_relative_to_the_mesh_not_its_position() -> None:
    # a 1 mm plate 1 km from the origin: its faces are 1 mm apart, far more than float32
    # steps there (~0.06 mm), so its corners must not merge (2 x 4 distinct corners)
    plate = m.box((0.5, 0.5, 0.001), (1000.0, -800.0, 20.0))
    v = plate.vertices.astype(np.float32)
    assert m.closed_solid(v, plate.faces)
    assert m._merged_ids(v).max() + 1 == 8
    sheet = m.plane((0.5, 0.5))
    far = m.transformed(sheet, m.pose_matrix((1000.0, -800.0, 20.0)))
    assert not m.closed_solid(far.vertices.astype(np.float32), far.faces)
