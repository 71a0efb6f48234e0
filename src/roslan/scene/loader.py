"""Loading scenes: built-in names or scene YAML files -> one :class:`Scene`."""

from __future__ import annotations

import dataclasses
import re
import threading
import warnings
import weakref
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pydantic import ValidationError

from roslan.config.base import UnitWarning, did_you_mean, format_validation_error, load_yaml
from roslan.config.units import unit_slips
from roslan.errors import ConfigError, SceneError
from roslan.scene import mesh as m
from roslan.scene.classes import PartLabels
from roslan.scene.model import Lights, Material, Scene, SceneObject
from roslan.scene.perch import perch_object
from roslan.scene.spec import MaterialSpec, ObjectSpec, SceneFile

__all__ = ["BUILTIN_SCENES", "build_scene", "load_scene", "parse_scene_file"]

MESH_SUFFIXES = (".obj", ".gltf", ".glb", ".stl", ".ply")


def _builtins() -> dict[str, Callable[[int], Scene]]:
    from roslan.scene.builtin import empty
    from roslan.scene.refinery import refinery
    from roslan.scene.warehouse import warehouse

    return {"warehouse": warehouse, "refinery": refinery, "empty": empty}


BUILTIN_SCENES: tuple[str, ...] = ("warehouse", "refinery", "empty")


_BUILT: weakref.WeakValueDictionary[tuple[str, int], Scene] = weakref.WeakValueDictionary()
"""Built-in scenes alive in this process, by (name, seed): shared while someone holds one
(scenes are immutable: frozen dataclasses, read-only arrays), never kept alive by this
table (an environment that varies its scene does not grow)."""
_BUILT_LOCK = threading.Lock()


def _builtin(name: str, seed: int) -> Scene:
    with _BUILT_LOCK:
        scene = _BUILT.get((name, seed))
        if scene is None:
            scene = _BUILT[(name, seed)] = _builtins()[name](seed)
        return scene


def load_scene(
    spec: str | Path,
    *,
    base_dir: Path | None = None,
    seed: int = 0,
    allow_external_paths: bool = False,
) -> Scene:
    """Load a built-in scene (``warehouse``, ``refinery``, ``empty``) or a scene YAML file.

    Args:
        spec: built-in name or path to a scene YAML (relative paths resolve against
            ``base_dir``, e.g. the folder of the simulation config naming it).
        seed: seed of the procedural parts (built-ins, branch perches).
        allow_external_paths: let the file's mesh/texture paths be absolute or leave its folder.
    Raises:
        SceneError: unknown name, missing file or any invalid content (message names the
            file, the object and the key).
    """
    text = str(spec)
    if text in BUILTIN_SCENES:
        return _builtin(text, int(seed))
    path = Path(text).expanduser()
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    if not path.is_file():
        msg = (
            f"scene {text!r}: neither a built-in scene ({', '.join(BUILTIN_SCENES)}) "
            f"nor an existing scene file ({path}){did_you_mean(text, list(BUILTIN_SCENES))}"
        )
        raise SceneError(msg)
    spec_model = parse_scene_file(path)
    return build_scene(
        spec_model, path.parent, source=path, seed=seed, allow_external_paths=allow_external_paths
    )


_OBJ_RE = re.compile(r"objects\[(\d+)\]")


def parse_scene_file(path: Path) -> SceneFile:
    """Read and validate a scene YAML; errors name the file, the object (by name) and the key."""
    try:
        data = load_yaml(path)
    except ConfigError as err:
        raise SceneError(str(err)) from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        msg = (
            f"{path}: expected a mapping with 'name' and 'objects' at the top level, "
            f"got {type(data).__name__}"
        )
        raise SceneError(msg)
    try:
        spec = SceneFile.model_validate(data)
    except ValidationError as err:
        text = format_validation_error(err, path, model=SceneFile, data=data)
        objs = data.get("objects")

        def _named(mt: re.Match[str]) -> str:
            i = int(mt.group(1))
            if (
                isinstance(objs, list)
                and i < len(objs)
                and isinstance(objs[i], dict)
                and "name" in objs[i]
            ):
                return f"objects[{i}] (name {objs[i]['name']!r})"
            return mt.group(0)

        raise SceneError(_OBJ_RE.sub(_named, text)) from None
    for slip in unit_slips(spec):  # probable degrees in a pose's rpy
        warnings.warn(f"{path}: {slip}", UnitWarning, stacklevel=2)
    return spec


def _resolve(raw: str, base: Path, allow: bool, where: str) -> Path:
    p = Path(raw).expanduser()
    if p.is_absolute():
        if not allow:
            msg = (
                f"{where} = {raw!r}: absolute paths are not allowed; give a path relative to the "
                "scene file's folder (or set allow_external_paths: true in the scene file)"
            )
            raise SceneError(msg)
        full = p
    else:
        full = (base / p).resolve()
        if not allow and not full.is_relative_to(base.resolve()):
            msg = (
                f"{where} = {raw!r}: path leaves the scene file's folder ({base}); "
                "keep models and textures inside it (or set allow_external_paths: true)"
            )
            raise SceneError(msg)
    if not full.is_file():
        msg = f"{where} = {raw!r}: file not found ({full})"
        raise SceneError(msg)
    return full


def load_texture(path: Path, where: str) -> NDArray[np.uint8]:
    """An image file as (H, W, 3) uint8 sRGB; SceneError if it is not a readable image."""
    from PIL import Image, UnidentifiedImageError

    from roslan.io.safe_read import check_image_header

    check_image_header(path, where, SceneError)
    try:
        with Image.open(path) as im:
            rgb = np.asarray(im.convert("RGB"), dtype=np.uint8)
    except (UnidentifiedImageError, OSError, ValueError) as err:
        msg = f"{where} = {str(path)!r}: not a readable image (PNG, JPEG, ...): {err}"
        raise SceneError(msg) from None
    rgb = np.ascontiguousarray(rgb)
    rgb.flags.writeable = False
    return rgb


def _planar_uvs(v: NDArray[np.float64], n: NDArray[np.float64]) -> NDArray[np.float64]:
    """Box projection in metres: each vertex takes the two coordinates across its dominant
    normal axis."""
    ax = np.argmax(np.abs(n), axis=1)
    u = np.where(ax == 0, v[:, 1], v[:, 0])
    w = np.where(ax == 2, v[:, 1], v[:, 2])
    return np.stack([u, w], axis=1)


def load_mesh_file(path: Path, where: str) -> tuple[m.LocalMesh, NDArray[np.uint8] | None]:
    """Triangles, normals and UVs of a model file (OBJ, glTF/GLB, STL, PLY) in its own frame.

    Multi-part files are concatenated with their node transforms. Vertex normals come from
    the file when present (else trimesh computes them); missing UVs get a box projection
    in metres. Returns the mesh and the first base-colour texture found (or None).
    """
    import trimesh

    if path.suffix.lower() not in MESH_SUFFIXES:
        allowed = ", ".join(MESH_SUFFIXES)
        msg = f"{where} = {path.name!r}: unsupported model format; allowed: {allowed}"
        raise SceneError(msg)
    from roslan.io.safe_read import MAX_MESH_BYTES, check_regular_file

    check_regular_file(path, MAX_MESH_BYTES, SceneError)
    try:
        loaded: Any = trimesh.load(str(path), process=False)
    except Exception as err:  # trimesh raises many kinds on corrupt input
        msg = f"{where} = {path.name!r}: cannot read model file: {type(err).__name__}: {err}"
        raise SceneError(msg) from None
    if isinstance(loaded, trimesh.Trimesh):
        items: list[tuple[NDArray[np.float64], Any]] = [(np.eye(4), loaded)]
    elif isinstance(loaded, trimesh.Scene):
        items = []
        for node in loaded.graph.nodes_geometry:
            T, gname = loaded.graph[node]
            g = loaded.geometry.get(gname)
            if isinstance(g, trimesh.Trimesh):
                items.append((np.asarray(T, dtype=np.float64), g))
    else:
        items = []
    items = [(T, g) for T, g in items if len(g.faces) > 0]
    if not items:
        msg = f"{where} = {path.name!r}: the file holds no triangles"
        raise SceneError(msg)
    parts = []
    texture = None
    for T, g in items:
        v = np.asarray(g.vertices, dtype=np.float64)
        n = np.asarray(g.vertex_normals, dtype=np.float64)
        uv = getattr(g.visual, "uv", None)
        if uv is None or len(uv) != len(v):
            uvs = _planar_uvs(v, n)
        else:
            uvs = np.asarray(uv, dtype=np.float64)
        if texture is None:
            mat = getattr(g.visual, "material", None)
            img = getattr(mat, "baseColorTexture", None) or getattr(mat, "image", None)
            if img is not None:
                texture = np.ascontiguousarray(np.asarray(img.convert("RGB"), dtype=np.uint8))
        part = m.LocalMesh(v, n, uvs, np.asarray(g.faces, dtype=np.int64))
        parts.append(part if np.array_equal(T, np.eye(4)) else m.transformed(part, T))
    if not all(np.isfinite(p.vertices).all() for p in parts):
        msg = f"{where} = {path.name!r}: vertices contain NaN or inf"
        raise SceneError(msg)
    from roslan.limits import MAX_COORD_M

    if any(np.abs(p.vertices).max(initial=0.0) > MAX_COORD_M for p in parts):
        msg = f"{where} = {path.name!r}: a vertex lies more than {MAX_COORD_M:g} m from the origin"
        raise SceneError(msg)
    return (parts[0] if len(parts) == 1 else m.merge(parts)), texture


def primitive_mesh(spec: Any) -> m.LocalMesh:
    """Local mesh of a validated primitive spec."""
    t = spec.type
    if t == "box":
        return m.box(spec.size)
    if t == "plane":
        return m.plane(spec.size)
    if t == "cylinder":
        return m.cylinder(spec.radius, spec.height, spec.segments)
    if t == "sphere":
        return m.sphere(spec.radius, spec.segments)
    if t == "capsule":
        return m.capsule(spec.radius, spec.height, spec.segments)
    msg = f"unknown primitive type {t!r}"  # unreachable after validation
    raise SceneError(msg)


def _material(
    ms: MaterialSpec,
    default_name: str,
    base: Path,
    allow: bool,
    where: str,
    mesh_texture: NDArray[np.uint8] | None,
) -> Material:
    tex = mesh_texture
    if ms.texture is not None:
        tex = load_texture(
            _resolve(ms.texture, base, allow, f"{where}.material.texture"),
            f"{where}.material.texture",
        )
    return Material(
        color=ms.color,
        texture=tex,
        texture_scale=ms.texture_scale,
        reflectivity=ms.reflectivity,
        name=ms.name or default_name,
    )


def _labelled(obj: SceneObject, spec: ObjectSpec, where: str) -> SceneObject:
    """``obj`` with the labels of ``spec``'s ``class``/``instance`` or ``parts``."""
    if spec.parts is not None:
        lab = PartLabels(
            tuple(p.class_ for p in spec.parts),
            tuple(p.triangles for p in spec.parts),
            tuple(p.instance for p in spec.parts),
        )
        if lab.n_triangles != obj.n_triangles:
            msg = (
                f"{where}.parts: the parts' triangles add up to {lab.n_triangles}, the object "
                f"has {obj.n_triangles}; allowed: counts adding up to exactly {obj.n_triangles}"
            )
            raise SceneError(msg)
    elif spec.class_ is not None:
        lab = PartLabels.whole(spec.class_, obj.n_triangles, spec.instance)
    else:
        return obj
    return dataclasses.replace(obj, labels=lab)


def _object(spec: ObjectSpec, i: int, base: Path, allow: bool, src: str) -> SceneObject:
    where = f"{src}objects[{i}] (name {spec.name!r})"
    return _labelled(_shaped(spec, where, base, allow), spec, where)


def _shaped(spec: ObjectSpec, where: str, base: Path, allow: bool) -> SceneObject:
    T = spec.pose.matrix()
    if spec.mesh is not None:
        path = _resolve(spec.mesh, base, allow, f"{where}.mesh")
        local, tex = load_mesh_file(path, f"{where}.mesh")
        mat = _material(spec.material, spec.name, base, allow, where, tex)
        return m.place(spec.name, local, mat, T, spec.scale, source=spec.mesh)
    assert spec.primitive is not None
    mat = _material(spec.material, spec.name, base, allow, where, None)
    obj = m.place(
        spec.name,
        primitive_mesh(spec.primitive),
        mat,
        T,
        spec.scale,
        source=f"primitive:{spec.primitive.type}",
    )
    _check_not_degenerate(obj, spec, where)
    return obj


def _check_not_degenerate(obj: SceneObject, spec: ObjectSpec, where: str) -> None:
    """Every primitive's triangles must keep a non-zero area once placed in the world in
    float32 (a dimension x scale too small for the object's distance from the origin
    collapses them; the dimensions alone are bounded by MIN_SIZE_M in the spec)."""
    v = obj.vertices.astype(np.float64)
    f = obj.faces
    area2 = np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    n_zero = int(np.count_nonzero(area2 == 0.0))
    if n_zero == 0:
        return
    assert spec.primitive is not None
    dims = spec.primitive.model_dump(exclude={"type", "segments"})
    shown = ", ".join(f"{k} {v!r}" for k, v in dims.items())
    reach = float(np.abs(obj.vertices).max(initial=0.0))
    least = float(np.spacing(np.float32(max(reach, 1.0)))) * 1e3
    msg = (
        f"{where}.primitive = {{type: {spec.primitive.type}, {shown}}} with scale "
        f"{list(spec.scale)}: {n_zero} of its {f.shape[0]} triangles have zero area in "
        f"float32 at {reach:.6g} m from the origin; allowed: every dimension x scale at "
        f"least {least:.3g} m there"
    )
    raise SceneError(msg)


def build_scene(
    spec: SceneFile,
    base_dir: Path,
    *,
    source: Path | None = None,
    seed: int = 0,
    allow_external_paths: bool = False,
) -> Scene:
    """Turn a validated :class:`SceneFile` into a :class:`Scene` (paths relative to
    ``base_dir``)."""
    allow = allow_external_paths or spec.allow_external_paths
    src = f"{source}: " if source is not None else ""
    objects = [_object(o, i, Path(base_dir), allow, src) for i, o in enumerate(spec.objects)]
    goal = spec.goal
    if goal is None and spec.perch is not None and spec.perch.pose is not None:
        goal = spec.perch.pose  # the perch's top is the scene's goal (roslan.scene.goal)
    goal_pos = goal.position if goal is not None else (0.0, 0.0, 0.0)
    goal_rpy = goal.rpy if goal is not None else (0.0, 0.0, 0.0)
    if spec.perch is not None:
        p = spec.perch
        T = p.pose.matrix() if p.pose is not None else m.pose_matrix(goal_pos, goal_rpy)
        objects.append(
            perch_object(
                p.type,
                T,
                length=p.length,
                radius=p.radius,
                supports=p.supports,
                name=p.name,
                seed=seed,
            )
        )
    lights = Lights(
        sun_direction=spec.lights.sun.direction,
        sun_intensity=spec.lights.sun.intensity,
        ambient=spec.lights.ambient,
        sky=spec.lights.sky,
    )
    return Scene(
        name=spec.name,
        objects=tuple(objects),
        lights=lights,
        goal_position=goal_pos,
        goal_rpy=goal_rpy,
    )
