"""Classes and instances of scenes: every built-in triangle labelled, boxes that hold their
triangles tightly, instance counts the builders' own numbers give, scene-file labels and
their errors, export round trips, the documented class table."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

from roslan.errors import SceneError
from roslan.frames import rpy_to_matrix
from roslan.scene import export_scene, load_scene
from roslan.scene.classes import (
    BUILTIN_CLASSES,
    NOISE_CLASS_ID,
    UNLABELLED_ID,
    PartLabels,
    scene_class_table,
)
from roslan.scene.instances import MAX_INSTANCES, SceneLabels, labels_document, scene_labels
from roslan.scene.mesh import box, place
from roslan.scene.model import Material, Scene
from roslan.scene.refinery import refinery
from roslan.scene.warehouse import HALL_SIZE, warehouse

ROOT = Path(__file__).resolve().parents[2]


def _instance_vertices(scene: Scene, labels: SceneLabels, iid: int) -> NDArray[np.float64]:
    verts, faces, _ = scene.triangles
    out: NDArray[np.float64] = verts[faces[labels.triangle_instance == iid]].astype(np.float64)
    return out.reshape(-1, 3)


@pytest.mark.parametrize(("name", "seed"), [("warehouse", 0), ("warehouse", 7), ("refinery", 0)])
def test_every_builtin_triangle_has_an_instance_and_its_box_is_tight(name: str, seed: int) -> None:
    scene = load_scene(name, seed=seed)
    labels = scene_labels(scene)
    assert labels.triangle_instance.shape == (scene.n_triangles,)
    assert labels.triangle_instance.dtype == np.uint16
    assert (labels.triangle_instance > 0).all()
    assert (labels.triangle_class > NOISE_CLASS_ID).all()  # neither nothing nor noise
    assert [i.id for i in labels.instances] == list(range(1, len(labels.instances) + 1))
    # the triangle's class is its instance's class
    cls_of = np.array([0] + [i.class_id for i in labels.instances])
    np.testing.assert_array_equal(cls_of[labels.triangle_instance], labels.triangle_class)
    for inst in labels.instances:
        v = _instance_vertices(scene, labels, inst.id)
        R = rpy_to_matrix(np.asarray(inst.rpy))
        local = (v - np.asarray(inst.center)) @ R  # coordinates along the box axes
        half = np.asarray(inst.size) / 2.0
        assert (np.abs(local) <= half + 1e-6).all(), inst
        # tight: each of the six faces touches a vertex
        assert np.allclose(local.max(axis=0), half, atol=1e-6), inst
        assert np.allclose(local.min(axis=0), -half, atol=1e-6), inst


def test_warehouse_instance_counts_are_the_builders() -> None:
    scene = warehouse(3)
    labels = scene_labels(scene)
    counts = labels.instance_counts()
    objs = {o.name: o for o in scene.objects}
    # each rack box is a 12-triangle box; each pallet 5 deck boards and 3 x (2 boards +
    # 3 blocks) = 20 boxes of 12 triangles
    n_boxes = sum(o.n_triangles for n, o in objs.items() if n.endswith("_boxes")) // 12
    assert counts["box"] == n_boxes > 100
    rack_pallets = sum(
        o.n_triangles for n, o in objs.items() if re.fullmatch(r"rack_\d+_pallets", n)
    )
    stack_layers = sum(
        round(float(np.ptp(o.vertices[:, 2])) / 0.144)
        for n, o in objs.items()
        if n.startswith("pallet_stack_")
    )
    assert counts["pallet"] == rack_pallets // (20 * 12) + stack_layers
    n_barrel_groups = sum(n.startswith("clutter_barrels_") for n in objs)
    n_crate_groups = sum(n.startswith("clutter_crates_") for n in objs)
    assert counts.get("barrel", 0) == 4 * n_barrel_groups
    assert counts.get("crate", 0) == 2 * n_crate_groups
    assert counts["rack"] == 7  # 7 racks, frame and beams one instance each
    assert counts["column"] == 4 * 2  # x in (-24, -12, 12, 24), y = +-14.5
    assert counts["lamp"] == 5 * 3  # x every 12 m over [-24, 24], y in (-10, 0, 10)
    assert counts["wall"] == 4
    assert counts["landing_marker"] == 1
    assert counts.get("forklift", 0) == ("forklift_body" in objs)
    # a box instance is one whole box: its 12 triangles span exactly its 8 corners
    box_id = labels.class_id("box")
    for inst in [i for i in labels.instances if i.class_id == box_id][:50]:
        v = _instance_vertices(scene, labels, inst.id)
        assert v.shape[0] == 36
        assert np.unique(np.round(v, 5), axis=0).shape[0] == 8
    # parts of two objects as one instance: a column and its foot, the forklift
    col = [i for i in labels.instances if i.class_name == "column"]
    owner = scene.triangles[2]
    for inst in col:
        objects = {
            scene.objects[k].name for k in np.unique(owner[labels.triangle_instance == inst.id])
        }
        assert objects == {"columns", "column_guards"}
        assert np.isclose(inst.size[2], HALL_SIZE[2])  # foot (0-1.2 m) + column (to the roof)


def test_refinery_instance_counts_are_the_builders() -> None:
    counts = scene_labels(refinery(0)).instance_counts()
    heights = (32.0, 26.0, 22.0)  # the three columns; platforms every 6 m from 6 m to h - 2
    platforms = sum(len(np.arange(6.0, h - 2.0, 6.0)) for h in heights)
    assert counts["platform"] == platforms + 4  # + each tank's roof walkway
    assert counts["ladder"] == 3
    assert counts["distillation_column"] == 3
    assert counts["tank"] == 4 + 2  # storage tanks + bullet tanks
    assert counts["stairs"] == counts["bund"] == 4
    assert counts["pipe"] == 2 * 5 + 5  # rack pipes at two levels + pipe runs
    assert counts["guy_wire"] == 3 * 2
    assert counts["perch"] == 1


def test_labels_are_the_same_at_every_build() -> None:
    a, b = scene_labels(warehouse(5)), scene_labels(warehouse(5))
    assert a.instances == b.instances
    assert a.classes == b.classes
    np.testing.assert_array_equal(a.triangle_instance, b.triangle_instance)
    other = scene_labels(warehouse(6))
    assert [i.key for i in other.instances] != [i.key for i in a.instances]  # the seed moves boxes


def test_class_table_invariants() -> None:
    ids = [cid for cid, _, _ in BUILTIN_CLASSES]
    names = [n for _, n, _ in BUILTIN_CLASSES]
    assert ids == list(range(len(ids)))
    assert len(set(names)) == len(names)
    assert names[UNLABELLED_ID] == "unlabelled"
    assert names[NOISE_CLASS_ID] == "noise"
    assert all(re.fullmatch(r"[a-z_]+", n) for n in names)
    # user classes come after the built-ins, in order of first appearance, each once
    table = scene_class_table(["truck", "box", "cone", "truck"])
    assert [c.name for c in table[len(ids) :]] == ["truck", "cone"]
    assert [c.id for c in table] == list(range(len(ids) + 2))
    assert next(c.id for c in table if c.name == "box") == names.index("box")
    colors = [c.color for c in table]
    assert len(set(colors)) == len(colors)


def test_scenes_guide_lists_the_class_table() -> None:
    text = (ROOT / "docs" / "guide" / "scenes.md").read_text(encoding="utf-8")
    section = text.split("## Classes and instances", 1)[1]
    rows = re.findall(r"^\| (\d+) \| `([a-z_]+)` \| ", section, flags=re.MULTILINE)
    assert [(int(i), n) for i, n in rows] == [(cid, n) for cid, n, _ in BUILTIN_CLASSES]


def _write_scene(tmp_path: Path, objects: str) -> Path:
    path = tmp_path / "s.yaml"
    path.write_text(f"name: s\nobjects:\n{objects}", encoding="utf-8")
    return path


_BOX = "primitive: {type: box, size: [1, 1, 1]}"


def test_scene_file_classes_instances_and_parts(tmp_path: Path) -> None:
    path = _write_scene(
        tmp_path,
        f"  - {{name: a, {_BOX}, class: truck, instance: t1}}\n"
        f"  - {{name: b, {_BOX}, pose: {{position: [3, 0, 0]}}, class: truck, instance: t1}}\n"
        f"  - {{name: c, {_BOX}, pose: {{position: [0, 5, 0]}}, class: box}}\n"
        f"  - {{name: d, {_BOX}, pose: {{position: [9, 0, 0]}},\n"
        "      parts: [{class: cone, triangles: 4}, {class: box, triangles: 8}]}\n"
        f"  - {{name: e, {_BOX}, pose: {{position: [0, 9, 0]}}}}\n",
    )
    scene = load_scene(path)
    labels = scene_labels(scene)
    n_builtin = len(BUILTIN_CLASSES)
    assert [c.name for c in labels.classes[n_builtin:]] == ["truck", "cone"]
    assert [(i.id, i.class_name, i.key) for i in labels.instances] == [
        (1, "truck", "t1"),
        (2, "box", "c"),
        (3, "cone", "d#0"),
        (4, "box", "d#1"),
    ]
    truck = labels.instances[0]
    assert np.allclose(truck.center, (1.5, 0.0, 0.0))
    assert np.allclose(truck.size, (4.0, 1.0, 1.0))
    assert (labels.triangle_instance[-12:] == 0).all()  # e: no class
    assert (labels.triangle_class[-12:] == UNLABELLED_ID).all()
    doc = labels_document(scene)
    assert doc["instances"][0] == {
        "id": 1,
        "class_id": n_builtin,
        "object": "a",
        "box3d": {"center": list(truck.center), "size": list(truck.size), "rpy": [0.0, 0.0, 0.0]},
    }
    assert {c["name"]: c["instances"] for c in doc["classes"]}["box"] == 2


@pytest.mark.parametrize(
    ("obj", "expected"),
    [
        (f"{{name: a, {_BOX}, class: ''}}", r"objects\[0\] \(name 'a'\)\.class.*at least 1"),
        (f"{{name: a, {_BOX}, class: 'a b'}}", r"objects\[0\] \(name 'a'\)\.class"),
        (
            f"{{name: a, {_BOX}, class: x, parts: [{{class: y, triangles: 12}}]}}",
            r"objects\[0\] \(name 'a'\).*either 'class'.*or 'parts'",
        ),
        (
            f"{{name: a, {_BOX}, parts: [{{class: y, triangles: 10}}]}}",
            r"objects\[0\] \(name 'a'\)\.parts: the parts' triangles add up to 10, "
            r"the object has 12",
        ),
        (
            f"{{name: a, {_BOX}, parts: [{{class: y, triangles: 0}}]}}",
            r"objects\[0\] \(name 'a'\)\.parts\[0\]\.triangles",
        ),
        (f"{{name: a, {_BOX}, instance: x}}", r"instance 'x' without a 'class'"),
        (f"{{name: a, {_BOX}, clas: x}}", r"objects\[0\] \(name 'a'\)\.clas"),
    ],
)
def test_bad_labels_name_the_file_object_and_key(tmp_path: Path, obj: str, expected: str) -> None:
    path = _write_scene(tmp_path, f"  - {obj}\n")
    with pytest.raises(SceneError, match=expected) as err:
        load_scene(path)
    assert str(path) in str(err.value)


def test_more_instances_than_uint16_ids_is_an_error() -> None:
    n = MAX_INSTANCES + 1
    mesh = box((1.0, 1.0, 1.0))
    obj = place("many", mesh, Material())
    # one object of n triangles (the box's, repeated), each its own instance
    faces = np.tile(obj.faces, (n // 12 + 1, 1))[:n]
    obj = replace(obj, faces=faces, labels=PartLabels.each("box", [1] * n))
    with pytest.raises(SceneError, match="65536 instances; allowed: at most 65535"):
        scene_labels(Scene(name="big", objects=(obj,)))


@pytest.mark.parametrize("name", ["warehouse", "refinery"])
def test_export_keeps_classes_and_instances(tmp_path: Path, name: str) -> None:
    scene = load_scene(name, seed=2)
    export_scene(scene, tmp_path / "out")
    back = load_scene(tmp_path / "out" / "scene.yaml")
    a, b = scene_labels(scene), scene_labels(back)
    assert a.classes == b.classes
    assert a.instances == b.instances
    np.testing.assert_array_equal(a.triangle_instance, b.triangle_instance)
    np.testing.assert_array_equal(a.triangle_class, b.triangle_class)


def test_export_of_a_user_scene_keeps_its_classes(tmp_path: Path) -> None:
    path = _write_scene(
        tmp_path,
        f"  - {{name: a, {_BOX}, class: truck, instance: t1}}\n"
        f"  - {{name: d, {_BOX}, parts: [{{class: cone, triangles: 4}},\n"
        "      {class: box, triangles: 8, instance: q}]}\n"
        f"  - {{name: e, {_BOX}}}\n",
    )
    scene = load_scene(path)
    export_scene(scene, tmp_path / "out")
    back = load_scene(tmp_path / "out" / "scene.yaml")
    assert scene_labels(back).instances == scene_labels(scene).instances
    assert scene_labels(back).classes == scene_labels(scene).classes
    assert back.object("e").labels is None


def test_scene_info_lists_classes_and_instance_counts(capsys: pytest.CaptureFixture[str]) -> None:
    import json

    from roslan.cli.app import main

    labels = scene_labels(load_scene("refinery"))
    assert main(["scene", "info", "refinery"]) == 0
    text = capsys.readouterr().out
    in_use = len(labels.instance_counts())
    assert f"classes: {in_use} in use, {len(labels.instances)} instances" in text
    rows = dict(re.findall(r"^\s*\d+\s+([a-z_]+)\s+(\d+)\s+\d+$", text, flags=re.MULTILINE))
    assert {k: int(v) for k, v in rows.items()} == labels.instance_counts()
    assert main(["scene", "info", "refinery", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc == json.loads(json.dumps(labels_document(load_scene("refinery"))))
    assert len(doc["instances"]) == len(labels.instances)
