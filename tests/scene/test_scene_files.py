"""Scene files: loading meshes and primitives, bad input, export -> load round trip, CLI."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import trimesh
import yaml
from PIL import Image

from roslan.cli import main
from roslan.errors import OutputError, SceneError
from roslan.frames import rpy_to_matrix
from roslan.scene import add_perch, export_scene, load_scene


def _write(path: Path, doc: dict) -> Path:
    path.write_text(yaml.safe_dump(doc), encoding="utf-8")
    return path


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    (tmp_path / "models").mkdir()
    (tmp_path / "textures").mkdir()
    trimesh.creation.box(extents=(1.0, 2.0, 3.0)).export(tmp_path / "models" / "box.stl")
    trimesh.creation.icosphere(subdivisions=1, radius=0.5).export(tmp_path / "models" / "ball.ply")
    trimesh.creation.cylinder(radius=0.3, height=1.0, sections=12).export(
        tmp_path / "models" / "cyl.obj"
    )
    img = (np.arange(16 * 16 * 3) % 251).astype(np.uint8).reshape(16, 16, 3)
    Image.fromarray(img).save(tmp_path / "textures" / "t.png")
    (tmp_path / "textures" / "bad.png").write_text("not an image")
    return tmp_path


def _doc(**extra: object) -> dict:
    doc: dict = {
        "name": "test_scene",
        "lights": {
            "sun": {"direction": [0.3, 0.2, -1.0], "intensity": 1.0},
            "ambient": 0.3,
            "sky": [0.2, 0.3, 0.45],
        },
        "goal": {"position": [1.0, 0.0, 0.0], "rpy": [0.0, 0.0, 0.5]},
        "objects": [
            {
                "name": "floor",
                "primitive": {"type": "box", "size": [20.0, 10.0, 0.1]},
                "pose": {"position": [0, 0, -0.05], "rpy": [0, 0, 0]},
                "material": {
                    "color": [0.5, 0.5, 0.5],
                    "texture": "textures/t.png",
                    "texture_scale": 2.0,
                    "reflectivity": 0.3,
                },
            },
            {
                "name": "crate",
                "mesh": "models/box.stl",
                "pose": {"position": [4.0, 2.0, 1.5], "rpy": [0.0, 0.0, 1.57]},
                "scale": [1.0, 1.0, 1.0],
            },
            {
                "name": "ball",
                "mesh": "models/ball.ply",
                "pose": {"position": [-3, 0, 1]},
                "scale": [2, 2, 2],
            },
            {"name": "drum", "mesh": "models/cyl.obj", "pose": {"position": [0, 3, 0.5]}},
            {"name": "pole", "primitive": {"type": "cylinder", "radius": 0.1, "height": 3.0}},
            {
                "name": "globe",
                "primitive": {"type": "sphere", "radius": 0.3},
                "pose": {"position": [0, -3, 2]},
            },
            {"name": "pill", "primitive": {"type": "capsule", "radius": 0.2, "height": 1.0}},
            {
                "name": "sheet",
                "primitive": {"type": "plane", "size": [1.0, 2.0]},
                "pose": {"position": [5, 5, 3]},
            },
        ],
    }
    doc.update(extra)
    return doc


def test_load_scene_file(folder: Path) -> None:
    s = load_scene(str(_write(folder / "scene.yaml", _doc())))
    assert s.name == "test_scene"
    assert s.goal_position == (1.0, 0.0, 0.0)
    assert s.goal_rpy == (0.0, 0.0, 0.5)
    floor = s.object("floor")
    assert floor.material.texture is not None
    assert floor.material.texture.shape == (16, 16, 3)
    assert floor.material.texture_scale == 2.0
    assert floor.material.reflectivity == pytest.approx(0.3)
    # STL box rotated 1.57 about z: its 1 x 2 footprint swaps axes
    crate = s.object("crate")
    ext = crate.vertices.max(axis=0) - crate.vertices.min(axis=0)
    assert np.allclose(ext, [2.0, 1.0, 3.0], atol=2e-3)
    # PLY sphere scaled by 2: radius 1 around its pose
    ball = s.object("ball")
    r = np.linalg.norm(ball.vertices - np.array([-3.0, 0.0, 1.0], np.float32), axis=1)
    assert np.allclose(r, 1.0, atol=1e-5)
    # meshes without UVs get a projection; normals always present
    for o in s.objects:
        assert o.uvs.shape == (o.vertices.shape[0], 2)
        assert np.allclose(np.linalg.norm(o.normals, axis=1), 1.0, atol=1e-4)
    # a relative scene path resolves against base_dir
    assert load_scene("scene.yaml", base_dir=folder).n_triangles == s.n_triangles


def _err(folder: Path, doc: dict, *, allow: bool = False) -> str:
    p = _write(folder / "bad.yaml", doc)
    with pytest.raises(SceneError) as ei:
        load_scene(str(p), allow_external_paths=allow)
    return str(ei.value)


def _with(obj_index: int, **fields: object) -> dict:
    d = _doc()
    d["objects"][obj_index].update(fields)
    return d


def test_missing_mesh(folder: Path) -> None:
    msg = _err(folder, _with(1, mesh="models/nope.glb"))
    assert "crate" in msg
    assert "mesh" in msg
    assert "not found" in msg


def test_unreadable_mesh(folder: Path) -> None:
    (folder / "models" / "junk.glb").write_bytes(b"\x00garbage" * 10)
    msg = _err(folder, _with(1, mesh="models/junk.glb"))
    assert "crate" in msg
    assert "mesh" in msg


def test_texture_not_an_image(folder: Path) -> None:
    d = _doc()
    d["objects"][0]["material"]["texture"] = "textures/bad.png"
    msg = _err(folder, d)
    assert "floor" in msg
    assert "material.texture" in msg
    assert "image" in msg


@pytest.mark.parametrize("path", ["../../etc/passwd", "models/../../outside.stl"])
def test_path_escaping_folder(folder: Path, path: str) -> None:
    msg = _err(folder, _with(1, mesh=path))
    assert "crate" in msg
    assert "leaves the scene file's folder" in msg


def test_absolute_path_needs_explicit_allow(folder: Path) -> None:
    absolute = str(folder / "models" / "box.stl")
    msg = _err(folder, _with(1, mesh=absolute))
    assert "absolute paths are not allowed" in msg
    p = _write(folder / "ok.yaml", _with(1, mesh=absolute))
    assert load_scene(str(p), allow_external_paths=True).object("crate").n_triangles == 12
    p2 = _write(folder / "ok2.yaml", {**_with(1, mesh=absolute), "allow_external_paths": True})
    assert load_scene(str(p2)).object("crate").n_triangles == 12


@pytest.mark.parametrize("bad", [".nan", ".inf", "-.inf"])
def test_nan_inf_in_pose(folder: Path, bad: str) -> None:
    d = _with(1, pose={"position": [0.0, 0.0, 0.0], "rpy": [0.0, 0.0, 0.0]})
    text = yaml.safe_dump(d).replace("- 0.0\n", f"- {bad}\n", 1)
    p = folder / "bad.yaml"
    p.write_text(text)
    with pytest.raises(SceneError, match="finite") as ei:
        load_scene(str(p))
    assert "pose" in str(ei.value)


@pytest.mark.parametrize("scale", [[0.0, 1.0, 1.0], [1.0, -2.0, 1.0]])
def test_scale_not_positive(folder: Path, scale: list[float]) -> None:
    msg = _err(folder, _with(1, scale=scale))
    assert "crate" in msg
    assert "scale" in msg
    assert "greater than 0" in msg


@pytest.mark.parametrize(
    ("index", "primitive", "key"),
    [
        (5, {"type": "sphere", "radius": 1e-300}, "sphere.radius = 1e-300"),  # 0 in float32
        (0, {"type": "box", "size": [1e-300, 1.0, 1.0]}, "box.size[0] = 1e-300"),
        (7, {"type": "plane", "size": [1.0, 0.0]}, "plane.size[1] = 0.0"),
        (4, {"type": "cylinder", "radius": 0.1, "height": 1e-5}, "cylinder.height = 1e-05"),
        (6, {"type": "capsule", "radius": 5e-5, "height": 1.0}, "capsule.radius = 5e-05"),
    ],
)
def test_degenerate_primitives_refused_by_one_rule(
    folder: Path, index: int, primitive: dict, key: str
) -> None:
    """Every primitive dimension obeys the same bounds [MIN_SIZE_M, MAX_SIZE_M]: the
    message names the file, the object, the key, the value and what is allowed."""
    from roslan.limits import MIN_SIZE_M

    d = _doc()
    d["objects"][index]["primitive"] = primitive
    name = d["objects"][index]["name"]
    msg = _err(folder, d)
    assert "bad.yaml" in msg
    assert name in msg
    assert f"(name {name!r}).primitive.{key}: " in msg, msg
    assert f"greater than or equal to {MIN_SIZE_M}" in msg, msg


def test_primitive_too_small_for_its_place_refused(folder: Path) -> None:
    """A valid radius shrunk by a tiny scale collapses the sphere in float32: refused by
    name (each of its 528 triangles would have zero area), not rendered silently."""
    d = _doc()
    d["objects"][5]["scale"] = [1e-30, 1e-30, 1e-30]
    msg = _err(folder, d)
    assert "globe" in msg
    assert "primitive" in msg
    assert "radius 0.3" in msg
    assert "scale [1e-30, 1e-30, 1e-30]" in msg
    assert "528 of its 528 triangles have zero area" in msg
    d["objects"][5]["scale"] = [1e-3, 1e-3, 1e-3]  # 0.3 mm: small but a real sphere
    s = load_scene(str(_write(folder / "ok.yaml", d)))
    assert s.object("globe").n_triangles == 528


@pytest.mark.parametrize("sky", [[0.5, 2.0, 0.1], [0.5, 0.5], [-0.1, 0.2, 0.3]])
def test_bad_sky(folder: Path, sky: list[float]) -> None:
    d = _doc()
    d["lights"]["sky"] = sky
    msg = _err(folder, d)
    assert "bad.yaml" in msg
    assert "lights.sky" in msg


def test_duplicate_names(folder: Path) -> None:
    d = _doc()
    d["objects"][2]["name"] = "crate"
    msg = _err(folder, d)
    assert "duplicate" in msg
    assert "crate" in msg


def test_unknown_primitive(folder: Path) -> None:
    msg = _err(folder, _with(4, primitive={"type": "cone", "radius": 1.0}))
    assert "pole" in msg
    assert "primitive" in msg
    assert "cone" in msg
    assert "box" in msg


def test_mesh_and_primitive_both_or_neither(folder: Path) -> None:
    d = _doc()
    d["objects"][4]["mesh"] = "models/box.stl"
    assert "exactly one" in _err(folder, d)
    d = _doc()
    del d["objects"][4]["primitive"]
    assert "exactly one" in _err(folder, d)


def test_unknown_key_and_missing_file(folder: Path) -> None:
    assert "unknown key" in _err(folder, _with(1, colour=[1, 0, 0]))
    with pytest.raises(SceneError, match="neither a built-in"):
        load_scene(str(folder / "missing.yaml"))


def _assert_same(a, b) -> None:  # type: ignore[no-untyped-def]
    assert [o.name for o in a.objects] == [o.name for o in b.objects]
    for oa, ob in zip(a.objects, b.objects, strict=True):
        assert np.array_equal(oa.vertices, ob.vertices), oa.name
        assert np.array_equal(oa.faces, ob.faces), oa.name
        assert np.allclose(oa.pose, ob.pose, atol=1e-12), oa.name
        assert oa.scale == ob.scale
        assert np.allclose(oa.uvs, ob.uvs, atol=1e-4), oa.name
        assert np.allclose(oa.normals, ob.normals, atol=1e-5), oa.name
        assert oa.material.color == pytest.approx(ob.material.color)
        assert oa.material.texture_scale == ob.material.texture_scale
        assert oa.material.reflectivity == pytest.approx(ob.material.reflectivity)
        if oa.material.texture is None:
            assert ob.material.texture is None
        else:
            assert np.array_equal(oa.material.texture, ob.material.texture)
    assert a.lights == b.lights
    assert a.goal_position == b.goal_position
    assert a.goal_rpy == b.goal_rpy
    assert np.array_equal(a.triangles[0], b.triangles[0])


@pytest.mark.parametrize("name", ["refinery", "file"])
def test_export_load_round_trip(tmp_path: Path, folder: Path, name: str) -> None:
    if name == "file":
        scene = load_scene(str(_write(folder / "scene.yaml", _doc())))
    else:
        scene = load_scene(name, seed=5)
    out = tmp_path / "export"
    export_scene(scene, out)
    again = load_scene(str(out / "scene.yaml"))
    _assert_same(scene, again)
    poses = yaml.safe_load((out / "poses.yaml").read_text())
    assert [p["name"] for p in poses["objects"]] == [o.name for o in scene.objects]
    for p, o in zip(poses["objects"], scene.objects, strict=True):
        assert (out / p["model"]).is_file()
        R = rpy_to_matrix(np.array(p["rpy"]))
        assert np.allclose(R, o.pose[:3, :3], atol=1e-12)
        assert np.allclose(p["position"], o.pose[:3, 3])
        q = np.array(p["quaternion_xyzw"])
        # quaternion and rpy describe the same rotation
        x, y, z, w = q
        Rq = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )
        assert np.allclose(Rq, R, atol=1e-9)
    # models are ordinary glTF files other tools read, in the object frame
    first = scene.objects[0]
    tm = trimesh.load(out / poses["objects"][0]["model"], force="mesh", process=False)
    assert len(tm.faces) == first.n_triangles
    with pytest.raises(OutputError, match="not an empty folder"):
        export_scene(scene, out)


def test_perch_in_file_and_add_perch(folder: Path) -> None:
    d = _doc(perch={"type": "pipe", "length": 2.0, "radius": 0.05})
    d["goal"] = {"position": [1.0, 0.0, 2.0], "rpy": [0.0, 0.0, 0.5]}
    s = load_scene(str(_write(folder / "perch.yaml", d)))
    perch = s.object("perch")
    top = perch.vertices[:, 2].max()
    assert top == pytest.approx(2.0, abs=1e-5)
    # axis along the goal frame's y: the perch is long in that direction
    yaxis = np.array([-math.sin(0.5), math.cos(0.5), 0.0])
    upper = perch.vertices[perch.vertices[:, 2] > 1.85].astype(np.float64) - [1.0, 0.0, 2.0]
    assert np.ptp(upper @ yaxis) == pytest.approx(2.0, abs=1e-4)
    assert np.ptp(upper @ np.array([math.cos(0.5), math.sin(0.5), 0.0])) == pytest.approx(
        0.1, abs=1e-3
    )
    base = load_scene("empty")
    for kind in ("bar", "branch", "pipe"):
        with_perch = add_perch(base, kind, None, name=f"{kind}_perch", seed=3)
        obj = with_perch.object(f"{kind}_perch")
        tm = trimesh.Trimesh(obj.vertices, obj.faces, process=False)
        # a ray straight down onto the goal meets the perch's top at the goal
        loc, _, _ = tm.ray.intersects_location([[0.0, 0.0, 1.0]], [[0.0, 0.0, -1.0]])
        assert loc[:, 2].max() == pytest.approx(0.0, abs=2e-3)
    with pytest.raises(ValueError, match="unknown"):
        add_perch(base, "rope")


def test_cli_info_preview_export(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["scene", "info", "empty"]) == 0
    out = capsys.readouterr().out
    assert "'empty'" in out
    assert "2 triangles" in out
    png = tmp_path / "top.png"
    assert main(["scene", "preview", "empty", "-o", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["scene", "export", "empty", "-o", str(tmp_path / "e")]) == 0
    assert (tmp_path / "e" / "scene.yaml").is_file()
    assert main(["scene", "info", str(tmp_path / "nope.yaml")]) == 2
    assert "neither a built-in" in capsys.readouterr().err


# ---------------------------------------------------------------- rendered preview
def test_look_at_points_the_optical_axis_at_the_target() -> None:
    from roslan.plots.scene import look_at

    rng = np.random.default_rng(4)
    for _ in range(20):
        eye, target = rng.normal(size=3) * 10, rng.normal(size=3) * 10
        T = look_at(eye, target)
        R = T[:3, :3]
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
        p = R.T @ (target - eye)  # the target in the camera frame: straight ahead
        np.testing.assert_allclose(p[:2], 0.0, atol=1e-9)
        assert p[2] > 0
        # world up (+z) is image up (-y), unless looking straight up or down
        assert (R.T @ np.array([0.0, 0.0, 1.0]))[1] <= 1e-12
    T = look_at(np.zeros(3), np.array([0.0, 0.0, -5.0]))  # straight down: still a rotation
    assert np.linalg.det(T[:3, :3]) == pytest.approx(1.0)


def test_preview_renders_the_goal_at_the_centre_of_the_approach_view(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from roslan.errors import RenderError
    from roslan.plots import scene as pv

    (tmp_path / "red.yaml").write_text(
        yaml.safe_dump(
            {
                "name": "red",
                "goal": {"position": [3.0, 2.0, 1.0], "rpy": [0.0, 0.0, 0.5]},
                "objects": [
                    {
                        "name": "floor",
                        "primitive": {"type": "plane", "size": [80.0, 80.0]},
                        "material": {"color": [0.5, 0.5, 0.5]},
                    },
                    {
                        "name": "red_box_under_the_goal",
                        "primitive": {"type": "box", "size": [1.0, 1.0, 1.0]},
                        "pose": {"position": [3.0, 2.0, 0.5]},
                        "material": {"color": [0.9, 0.05, 0.05]},
                    },
                ],
            }
        )
    )
    scene = load_scene(str(tmp_path / "red.yaml"))
    views = pv.render_views(scene, width=96, height=72)
    assert [t for t, _ in views] == ["approach to the goal", "overview"]
    img = views[0][1].astype(int)
    assert img.shape == (72, 96, 3)
    r, g, b = img[35:37, 47:49].reshape(-1, 3).mean(axis=0)
    assert r > 3 * g + 20  # the red box is where the camera looks
    assert abs(g - b) < 10
    assert views[1][1].std() > 5  # the overview sees the floor, not the void
    png = tmp_path / "prev.png"
    pv.write_preview(scene, png, dpi=40)
    with Image.open(png) as im:
        rgb = np.asarray(im.convert("RGB"))
    assert rgb.shape[0] == 7 * 40  # top view + rendered views, side by side
    inked = np.flatnonzero((rgb < 245).any(axis=2).any(axis=0))
    # the layout fits the columns to the figure: no blank strip at either side
    assert inked.min() <= 0.02 * rgb.shape[1]
    assert rgb.shape[1] - 1 - inked.max() <= 0.02 * rgb.shape[1]

    # without OpenGL: a warning and the top view alone
    def no_gl(*_a: object, **_k: object) -> None:
        msg = "no EGL"
        raise RenderError(msg)

    monkeypatch.setattr(pv, "render_views", no_gl)
    with pytest.warns(UserWarning, match="without rendered views: no EGL"):
        pv.write_preview(scene, png, dpi=40)
    with Image.open(png) as im:
        assert im.size == (9 * 40, 7 * 40)


def test_object_rpy_in_degrees_warned_by_key(folder: Path) -> None:
    """A pose's rpy beyond +-2 pi (45 meant as degrees) loads but warns, naming the file
    and the key; a radian rpy does not warn."""
    from roslan.config.base import UnitWarning

    d = _with(5, pose={"position": [0, -3, 2], "rpy": [0.0, 0.0, 45.0]})
    path = _write(folder / "deg.yaml", d)
    with pytest.warns(UnitWarning) as rec:
        load_scene(str(path))
    assert [str(w.message) for w in rec] == [
        f"{path}: objects[5].pose.rpy = [0, 0, 45]: beyond +-2 pi; angles are in radians "
        "(if 45 means degrees, write 0.7854)"
    ]
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", UnitWarning)
        load_scene(str(_write(folder / "rad.yaml", _doc())))
