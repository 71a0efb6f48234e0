"""Instances of a scene: which object part every triangle belongs to, and each part's box.

:func:`scene_labels` turns the objects' :class:`~roslan.scene.classes.PartLabels` into one
table for the whole scene:

- ``triangle_instance`` / ``triangle_class``: (F,) uint16 per triangle of
  :attr:`Scene.triangles <roslan.scene.model.Scene.triangles>` (0: unlabelled);
- ``instances``: every instance with its id, class, object and world-frame oriented box.

Instance ids are 1, 2, ... in order of first appearance: objects in scene order, parts in
face order within an object; parts with the same key (also of different objects) share
one id. The same scene (same file, or built-in name and seed) gives the same ids at every
load. At most 65 535 instances (uint16 ids; a SceneError beyond).

The box of an instance is aligned with its (first) object's axes (the object's pose
rotation): in that frame it is the axis-aligned bound of the instance's triangle vertices,
so every vertex lies inside and each face of the box touches a vertex.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from roslan.errors import SceneError
from roslan.frames import matrix_to_rpy
from roslan.scene.classes import UNLABELLED_ID, ClassInfo, scene_class_table
from roslan.scene.model import Scene

__all__ = ["MAX_INSTANCES", "Instance", "SceneLabels", "labels_document", "scene_labels"]

MAX_INSTANCES = 65_535
"""Most instances of one scene (ids are uint16; 0 is nothing)."""

U16 = NDArray[np.uint16]
F64 = NDArray[np.float64]


@dataclass(frozen=True)
class Instance:
    """One instance: ``center`` (m), ``size`` (m, along the box axes) and ``rpy`` (rad)
    of its world-frame oriented box; ``key`` its instance key."""

    id: int
    class_id: int
    class_name: str
    object: str
    key: str
    center: tuple[float, float, float]
    size: tuple[float, float, float]
    rpy: tuple[float, float, float]

    def box3d(self) -> dict[str, list[float]]:
        return {"center": list(self.center), "size": list(self.size), "rpy": list(self.rpy)}


@dataclass(frozen=True, eq=False)
class SceneLabels:
    """The class table, the instance table and the per-triangle ids of one scene."""

    classes: tuple[ClassInfo, ...]
    instances: tuple[Instance, ...]
    triangle_instance: U16
    triangle_class: U16

    def class_id(self, name: str) -> int:
        for c in self.classes:
            if c.name == name:
                return c.id
        raise KeyError(name)

    def instance_counts(self) -> dict[str, int]:
        """Class name -> number of instances, for the classes with at least one."""
        out: dict[str, int] = {}
        for inst in self.instances:
            out[inst.class_name] = out.get(inst.class_name, 0) + 1
        return out


def labels_document(scene: Scene) -> dict[str, Any]:
    """The scene's labels as plain data (``roslan scene info --json``): ``classes``
    ``[{id, name, color, instances}]`` (every class of the table) and ``instances``
    ``[{id, class_id, object, box3d: {center, size, rpy}}]``."""
    labels = scene_labels(scene)
    counts = labels.instance_counts()
    return {
        "scene": scene.name,
        "classes": [
            {"id": c.id, "name": c.name, "color": list(c.color), "instances": counts.get(c.name, 0)}
            for c in labels.classes
        ],
        "instances": [
            {"id": i.id, "class_id": i.class_id, "object": i.object, "box3d": i.box3d()}
            for i in labels.instances
        ],
    }


_CACHE: weakref.WeakKeyDictionary[Scene, SceneLabels] = weakref.WeakKeyDictionary()


def scene_labels(scene: Scene) -> SceneLabels:
    """The labels of ``scene`` (computed once per scene object; scenes are immutable).

    Raises:
        SceneError: an object's labels do not cover its triangles, or over
            :data:`MAX_INSTANCES` instances.
    """
    cached = _CACHE.get(scene)
    if cached is None:
        cached = _CACHE[scene] = _compute(scene)
    return cached


def _compute(scene: Scene) -> SceneLabels:
    names = [c for o in scene.objects if o.labels is not None for c in o.labels.classes]
    classes = scene_class_table(names)
    class_ids = {c.name: c.id for c in classes}
    ids: dict[str, int] = {}
    first: list[tuple[str, str, int]] = []  # (key, class, object index) per instance
    tri_inst, tri_cls = [], []
    for oi, obj in enumerate(scene.objects):
        lab = obj.labels
        if lab is None:
            tri_inst.append(np.zeros(obj.n_triangles, np.uint16))
            tri_cls.append(np.full(obj.n_triangles, UNLABELLED_ID, np.uint16))
            continue
        if lab.n_triangles != obj.n_triangles or any(n < 0 for n in lab.triangles):
            msg = (
                f"scene {scene.name!r}, object {obj.name!r}: its parts cover {lab.n_triangles} "
                f"triangles, the object has {obj.n_triangles}; the parts' triangles must add "
                "up to the object's"
            )
            raise SceneError(msg)
        part_ids = []
        for key, cname in zip(lab.keys(obj.name), lab.classes, strict=True):
            if key not in ids:
                ids[key] = len(first) + 1
                first.append((key, cname, oi))
            part_ids.append(ids[key])
        counts = np.asarray(lab.triangles, dtype=np.int64)
        if len(first) > MAX_INSTANCES:
            msg = (
                f"scene {scene.name!r}: {len(first)} instances; allowed: at most "
                f"{MAX_INSTANCES} (instance ids are uint16)"
            )
            raise SceneError(msg)
        tri_inst.append(np.repeat(np.asarray(part_ids, np.uint16), counts))
        tri_cls.append(
            np.repeat(np.asarray([class_ids[c] for c in lab.classes], np.uint16), counts)
        )
    t_inst = np.concatenate(tri_inst) if tri_inst else np.zeros(0, np.uint16)
    t_cls = np.concatenate(tri_cls) if tri_cls else np.zeros(0, np.uint16)
    # world-frame boxes at t = 0 (the scene at t = 0, each object's pose then)
    boxes = _boxes(scene, t_inst, [scene.objects[oi].pose_at(0.0)[:3, :3] for _, _, oi in first])
    instances = tuple(
        Instance(
            id=i + 1,
            class_id=class_ids[cname],
            class_name=cname,
            object=scene.objects[oi].name,
            key=key,
            center=boxes[i][0],
            size=boxes[i][1],
            rpy=boxes[i][2],
        )
        for i, (key, cname, oi) in enumerate(first)
    )
    for a in (t_inst, t_cls):
        a.flags.writeable = False
    return SceneLabels(classes, instances, t_inst, t_cls)


Box = tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]]


def _boxes(scene: Scene, tri_inst: U16, frames: list[F64]) -> list[Box]:
    """(center, size, rpy) of each instance's box in the axes ``frames[i]`` (world R)."""
    n = len(frames)
    if n == 0:
        return []
    verts, faces, _ = scene.at(0.0).triangles
    keep = tri_inst > 0
    inst = tri_inst[keep].astype(np.int64) - 1
    corners = verts[faces[keep]].astype(np.float64)  # (T, 3, 3)
    R = np.stack(frames)  # (n, 3, 3)
    local = np.einsum("tkj,tji->tki", corners, R[inst])  # p @ R: coordinates along R's axes
    lo = np.full((n, 3), np.inf)
    hi = np.full((n, 3), -np.inf)
    np.minimum.at(lo, inst, local.min(axis=1))
    np.maximum.at(hi, inst, local.max(axis=1))
    center = np.einsum("nij,nj->ni", R, (lo + hi) / 2.0)
    size = hi - lo
    out: list[Box] = []
    for i in range(n):
        rpy = matrix_to_rpy(R[i])
        out.append(
            (
                (float(center[i, 0]), float(center[i, 1]), float(center[i, 2])),
                (float(size[i, 0]), float(size[i, 1]), float(size[i, 2])),
                (float(rpy[0]), float(rpy[1]), float(rpy[2])),
            )
        )
    return out
