"""Labels of the beam sensors (output.labels): each return carries the instance and class of
the triangle its ray hit, checked against the geometry with trimesh (an independent
closest-point query), and a labelled scan keeps the unlabelled scan's points bit for bit."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from label_helpers import mesh_distance
from range_helpers import FakeContext, LinearTrajectory
from roslan.config.base import validate_model
from roslan.scene import load_scene
from roslan.scene.instances import scene_labels
from roslan.scene.model import Scene
from roslan.sensors.beams import (
    XYZIRT,
    XYZIRTL,
    Altimeter,
    AltimeterConfig,
    Laser,
    LaserConfig,
    Lidar,
    LidarConfig,
    SolidStateLidar,
    SolidStateLidarConfig,
)
from roslan.sensors.beams.labels import decode, encode, triangle_labels

SCENE = """\
name: labelled
objects:
  - {name: floor, primitive: {type: box, size: [40, 40, 0.2]}, pose: {position: [0, 0, -0.1]},
     class: ground}
  - {name: crate_a, primitive: {type: box, size: [1, 1, 1]}, pose: {position: [3, 0, 0.5]},
     class: crate}
  - {name: crate_b, primitive: {type: box, size: [1, 2, 1.5]},
     pose: {position: [-2.5, 2, 0.75], rpy: [0, 0, 0.4]}, class: crate}
  - {name: drum, primitive: {type: cylinder, radius: 0.4, height: 1.2},
     pose: {position: [0, -3, 0.6]}, class: barrel, instance: d1}
  - {name: wall, primitive: {type: box, size: [0.2, 40, 4]}, pose: {position: [8, 0, 2]}}
"""
H = 1.2


@pytest.fixture(scope="module")
def labelled_scene(tmp_path_factory: pytest.TempPathFactory) -> Scene:
    path = tmp_path_factory.mktemp("scene") / "labelled.yaml"
    path.write_text(SCENE, encoding="utf-8")
    return load_scene(path)


def _world_meshes(scene: Scene) -> dict[str, np.ndarray]:
    """Each object's world-frame triangles (T, 3, 3), from the scene's own (by owner)."""
    verts, faces, owner = scene.at(0.0).triangles
    return {obj.name: verts[faces[owner == i]] for i, obj in enumerate(scene.objects)}


def _check_against_geometry(scene: Scene, world: np.ndarray, label: np.ndarray) -> None:
    """Every labelled point within 1 cm of its instance's object mesh, its class the
    instance's; unlabelled points lie on an object without a class."""
    labels = scene_labels(scene)
    meshes = _world_meshes(scene)
    cls, inst = decode(label)
    by_id = {i.id: i for i in labels.instances}
    names = {o.name for o in scene.objects if o.labels is None}
    for iid in np.unique(inst).tolist():
        sel = inst == iid
        if iid == 0:
            assert (cls[sel] == 0).all()
            d = np.min([mesh_distance(meshes[n], world[sel]) for n in names], axis=0)
        else:
            assert (cls[sel] == by_id[iid].class_id).all()
            mesh = meshes[by_id[iid].object]
            d = mesh_distance(mesh, world[sel])
        assert d.max() < 0.01, (iid, d.max())


def _lidar(**kw: object) -> Lidar:
    cfg = {"type": "lidar", "name": "velodyne", "preset": "custom", "azimuth_steps": 400,
           "elevations_deg": [-40.0, -25.0, -12.0, -6.0, -2.0, 0.0, 3.0], "noise_sigma": 0.0,
           **kw}  # fmt: skip
    return Lidar(validate_model(LidarConfig, cfg, "sim.yaml"))


def test_lidar_labels_are_the_hit_instances_and_points_are_unchanged(
    labelled_scene: Scene, tmp_path: Path
) -> None:
    ctx = FakeContext(labelled_scene, LinearTrajectory((0.0, 0.0, H)), tmp_path)
    caster = ctx.raycaster()
    lid = _lidar(dropout=0.1)
    plain = lid.scan(ctx.trajectory, caster, 0, np.random.default_rng(5))
    table = triangle_labels(labelled_scene)
    got = lid.scan(ctx.trajectory, caster, 0, np.random.default_rng(5), labels=table)
    assert plain.dtype == XYZIRT
    assert got.dtype == XYZIRTL
    for name in XYZIRT.names or ():
        assert got[name].tobytes() == plain[name].tobytes(), name
    world = np.stack([got["x"], got["y"], got["z"] + H], axis=1).astype(np.float64)
    _check_against_geometry(labelled_scene, world, got["label"])
    _cls, inst = decode(got["label"])
    ids = scene_labels(labelled_scene)
    # the floor, both crates, the drum and the unlabelled wall are all seen
    assert set(np.unique(inst).tolist()) == {0, *(i.id for i in ids.instances)}


def test_organized_cloud_labels_no_return_with_zero(labelled_scene: Scene, tmp_path: Path) -> None:
    ctx = FakeContext(labelled_scene, LinearTrajectory((0.0, 0.0, H)), tmp_path)
    lid = _lidar(organized=True, max_range=6.0)
    table = triangle_labels(labelled_scene)
    pts = lid.scan(ctx.trajectory, ctx.raycaster(), 0, ctx.rng("o"), labels=table)
    miss = np.isnan(pts["x"])
    assert miss.any()
    assert (~miss).any()
    assert (pts["label"][miss] == 0).all()
    assert (pts["label"][~miss & (pts["z"] < -H + 0.05)] != 0).all()  # the floor has a class


def test_solid_state_labels(labelled_scene: Scene, tmp_path: Path) -> None:
    cfg = {"type": "solid_state_lidar", "name": "livox", "point_rate": 20000.0,
           "pose": {"rpy": [0.0, 0.5, 0.0]}, "noise_sigma": 0.0, "min_range": 0.1}  # fmt: skip
    sensor = SolidStateLidar(validate_model(SolidStateLidarConfig, cfg, "sim.yaml"))
    ctx = FakeContext(labelled_scene, LinearTrajectory((0.0, 0.0, H)), tmp_path)
    table = triangle_labels(labelled_scene)
    plain = sensor.scan(ctx.trajectory, ctx.raycaster(), 0, np.random.default_rng(1))
    got = sensor.scan(ctx.trajectory, ctx.raycaster(), 0, np.random.default_rng(1), labels=table)
    assert got.shape[0] > 100
    for name in XYZIRT.names or ():
        assert got[name].tobytes() == plain[name].tobytes(), name
    R = np.array(
        [[np.cos(0.5), 0.0, np.sin(0.5)], [0.0, 1.0, 0.0], [-np.sin(0.5), 0.0, np.cos(0.5)]]
    )
    xyz = np.stack([got["x"], got["y"], got["z"]], axis=1).astype(np.float64)
    _check_against_geometry(labelled_scene, xyz @ R.T + [0.0, 0.0, H], got["label"])


def test_laser_labels_follow_its_ranges(labelled_scene: Scene, tmp_path: Path) -> None:
    cfg = {"type": "laser", "name": "laser", "pose": {"position": [0, 0, 0], "rpy": [0, 0.15, 0]},
           "range_max": 10.0, "dropout": 0.05, "noise_sigma": 0.0}  # fmt: skip
    laser = Laser(validate_model(LaserConfig, cfg, "sim.yaml"))
    ctx = FakeContext(labelled_scene, LinearTrajectory((0.0, 0.0, 0.6)), tmp_path)
    table = triangle_labels(labelled_scene)
    ranges, inten = laser.scan(ctx.trajectory, ctx.raycaster(), 0, np.random.default_rng(2))
    m = laser.measure_scan(ctx.trajectory, ctx.raycaster(), 0, np.random.default_rng(2), table)
    assert m.label is not None
    assert m.range.astype(np.float32).tobytes() == ranges.tobytes()
    assert m.intensity.tobytes() == inten.tobytes()
    finite = np.isfinite(m.range)
    assert (m.label[~finite] == 0).all()
    assert (~finite).any()
    assert finite.sum() > 100
    R = np.array([[np.cos(0.15), 0.0, np.sin(0.15)], [0.0, 1.0, 0.0],
                  [-np.sin(0.15), 0.0, np.cos(0.15)]])  # fmt: skip
    a = laser.angles[finite]
    d = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1) @ R.T
    world = d * m.range[finite, None] + [0.0, 0.0, 0.6]
    _check_against_geometry(labelled_scene, world, m.label[finite])


def test_altimeter_label_is_the_surface_below(labelled_scene: Scene, tmp_path: Path) -> None:
    alt = Altimeter(validate_model(AltimeterConfig, {"type": "altimeter", "name": "alt"}, "s"))
    ids = scene_labels(labelled_scene)
    crate = next(i for i in ids.instances if i.object == "crate_a")
    floor = next(i for i in ids.instances if i.object == "floor")
    table = triangle_labels(labelled_scene)
    t = np.array([0, 10_000_000], np.int64)
    for x, inst in ((3.0, crate), (0.5, floor)):
        traj = LinearTrajectory((x, 0.0, 2.0))
        ctx = FakeContext(labelled_scene, traj, tmp_path)
        r, lab = alt.labelled_readings(
            traj, ctx.raycaster(), t, np.zeros(2), np.ones(2, bool), table
        )
        assert lab is not None
        assert lab.tolist() == encode([inst.class_id] * 2, [inst.id] * 2).tolist()
        assert np.array_equal(
            r, alt.readings(traj, ctx.raycaster(), t, np.zeros(2), np.ones(2, bool))
        )
    # nothing within range: no label
    traj = LinearTrajectory((0.0, 0.0, 30.0))
    ctx = FakeContext(labelled_scene, traj, tmp_path)
    r, lab = alt.labelled_readings(traj, ctx.raycaster(), t, np.zeros(2), np.ones(2, bool), table)
    assert np.isinf(r).all()
    assert lab is not None
    assert (lab == 0).all()


def test_encoding_is_semantickitti() -> None:
    label = encode([9, 65535, 0], [1, 2, 65535])
    assert label.dtype == np.uint32
    assert label.tolist() == [9 | 1 << 16, 65535 | 2 << 16, 65535 << 16]
    cls, inst = decode(label)
    assert cls.tolist() == [9, 65535, 0]
    assert inst.tolist() == [1, 2, 65535]
