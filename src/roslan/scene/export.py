"""Export a scene as model files plus poses (what the paper's dataset ships).

Layout of ``outdir``::

    models/<object>.glb     one binary glTF per object, in the object's own frame
                            (before scale), with UVs (metres), normals and its texture
                            (a JPEG copy)
    textures/<material>.png each distinct texture once (exact pixels)
    poses.yaml              every object: name, model, position, rpy, quaternion_xyzw, scale
    scene.yaml              a scene file that loads back to the same triangles
"""

from __future__ import annotations

import os
import re
import weakref
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

from roslan.errors import OutputError
from roslan.frames import matrix_to_quat_xyzw, matrix_to_rpy
from roslan.scene.model import Scene, SceneObject

__all__ = ["export_scene", "local_geometry"]


def local_geometry(obj: SceneObject) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Object-frame (before scale) vertices and normals, (V, 3) float32 each."""
    return obj.model_geometry()


def _floats(a: Any) -> list[float]:
    return [float(x) for x in np.asarray(a, dtype=np.float64).ravel()]


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.\-]", "_", name) or "unnamed"


_GLB_CACHE: weakref.WeakKeyDictionary[SceneObject, bytes] = weakref.WeakKeyDictionary()
"""Encoded models of objects already exported in this process (scenes are immutable)."""


def _glb(obj: SceneObject, texture: NDArray[np.uint8] | None) -> bytes:
    cached = _GLB_CACHE.get(obj)
    if cached is None:
        cached = _GLB_CACHE[obj] = _encode_glb(obj, texture)
    return cached


def _encode_glb(obj: SceneObject, texture: NDArray[np.uint8] | None) -> bytes:
    import trimesh
    from PIL import Image

    v, n = local_geometry(obj)
    image = None
    if texture is not None:
        image = Image.fromarray(texture)
        # trimesh re-encodes every texture; as JPEG that is ~10x quicker than PNG for these
        # noisy images. The exact pixels are in textures/*.png, which scene.yaml uses.
        image.format = "JPEG"
    c = obj.material.color
    factor = [round(255 * min(max(x, 0.0), 1.0)) for x in c] + [255]
    mat = trimesh.visual.material.PBRMaterial(  # type: ignore[no-untyped-call]
        name=obj.material.name,
        baseColorFactor=factor,
        baseColorTexture=image,
        metallicFactor=0.0,
        roughnessFactor=1.0,
    )
    # UVs stay in metres (as in the Scene); scene.yaml carries texture_scale
    uv = obj.uvs.astype(np.float64)
    mesh = trimesh.Trimesh(
        vertices=v,
        faces=obj.faces,
        vertex_normals=n,
        visual=trimesh.visual.TextureVisuals(uv=uv, material=mat),  # type: ignore[no-untyped-call]
        process=False,
    )
    data = mesh.export(file_type="glb", include_normals=True)
    assert isinstance(data, bytes)
    return data


def _label_keys(obj: SceneObject) -> dict[str, Any]:
    """The scene-file keys of ``obj``'s labels: ``class`` (+ ``instance``) for one part,
    ``parts`` for several; none for an unlabelled object."""
    lab = obj.labels
    if lab is None:
        return {}
    keys = lab.keys(obj.name)
    if len(lab.classes) == 1:
        one: dict[str, Any] = {"class": lab.classes[0]}
        if keys[0] != obj.name:
            one["instance"] = keys[0]
        return one
    parts = []
    for k, (cname, n, key) in enumerate(zip(lab.classes, lab.triangles, keys, strict=True)):
        part: dict[str, Any] = {"class": cname, "triangles": int(n)}
        if key != f"{obj.name}#{k}":
            part["instance"] = key
        parts.append(part)
    return {"parts": parts}


def export_scene(scene: Scene, outdir: Path) -> None:
    """Write ``scene`` as GLB models, textures, ``poses.yaml`` and ``scene.yaml`` into ``outdir``.

    ``outdir`` must not exist or be empty. ``scene.yaml`` is written last, so its
    presence marks a complete export. Re-loading it with :func:`roslan.scene.load_scene`
    gives bit-identical world vertices and faces (UVs and normals to float32 rounding).

    Raises:
        OutputError: ``outdir`` is a non-empty folder or cannot be written.
    """
    out = Path(outdir)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        msg = f"{out}: exists and is not an empty folder; choose a new output folder"
        raise OutputError(msg)
    try:
        (out / "models").mkdir(parents=True, exist_ok=True)
        (out / "textures").mkdir(exist_ok=True)
        _write(scene, out)
    except OSError as err:
        msg = f"{out}: cannot write the scene export: {err}"
        raise OutputError(msg) from err


def _write(scene: Scene, out: Path) -> None:
    from PIL import Image

    tex_files: dict[int, str] = {}
    used: set[str] = set()
    poses: list[dict[str, Any]] = []
    objects: list[dict[str, Any]] = []
    for obj in scene.objects:
        mat = obj.material
        tex_rel = None
        if mat.texture is not None:
            key = id(mat.texture)
            if key not in tex_files:
                base = _safe(mat.name)
                stem, k = base, 1
                while stem in used:
                    k += 1
                    stem = f"{base}_{k}"
                used.add(stem)
                tex_files[key] = f"textures/{stem}.png"
                Image.fromarray(np.ascontiguousarray(mat.texture)).save(
                    out / tex_files[key], compress_level=1
                )
            tex_rel = tex_files[key]
        model = f"models/{_safe(obj.name)}.glb"
        (out / model).write_bytes(_glb(obj, mat.texture))
        rpy = _floats(matrix_to_rpy(obj.pose[:3, :3]))
        pos = _floats(obj.pose[:3, 3])
        scale = _floats(obj.scale)
        poses.append(
            {
                "name": obj.name,
                "model": model,
                "position": pos,
                "rpy": rpy,
                "quaternion_xyzw": _floats(matrix_to_quat_xyzw(obj.pose[:3, :3])),
                "scale": scale,
                "triangles": obj.n_triangles,
                "source": obj.source,
            }
        )
        material: dict[str, Any] = {
            "color": _floats(mat.color),
            "texture_scale": float(mat.texture_scale),
            "reflectivity": float(mat.reflectivity),
            "name": mat.name,
        }
        if tex_rel is not None:
            material["texture"] = tex_rel
        entry: dict[str, Any] = {
            "name": obj.name,
            "mesh": model,
            "pose": {"position": pos, "rpy": rpy},
            "scale": scale,
            "material": material,
        }
        objects.append(entry | _label_keys(obj))
    lights = scene.lights
    doc = {
        "name": scene.name,
        "lights": {
            "sun": {
                "direction": _floats(lights.sun_direction),
                "intensity": float(lights.sun_intensity),
            },
            "ambient": float(lights.ambient),
            "sky": _floats(lights.sky),
        },
        "goal": {"position": _floats(scene.goal_position), "rpy": _floats(scene.goal_rpy)},
        "objects": objects,
    }
    header = {
        "scene": scene.name,
        "frame": "world (ENU, m); p_world = R(rpy) (scale * p_model) + position",
        "goal": doc["goal"],
        "objects": poses,
    }
    (out / "poses.yaml").write_text(yaml.safe_dump(header, sort_keys=False), encoding="utf-8")
    tmp = out / "scene.yaml.tmp"
    tmp.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    os.replace(tmp, out / "scene.yaml")
