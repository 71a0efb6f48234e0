"""Label outputs of the frame, stereo and depth cameras (``output.labels``).

Per frame and eye, from the renderer's id pass (:mod:`roslan.render.gl.ids`: the scene
triangle at every pixel centre of the same virtual pinhole view the image is rendered
from) mapped to instance ids and through the same lens maps, nearest (never a blend of
two ids, :mod:`.remap`):

- ``<camera folder>/instance/<frame>.png``: uint16 instance id (0: nothing);
- ``<camera folder>/semantic/<frame>.png``: uint16 class id;
- ``<camera folder>/annotations.json``: COCO (images, categories, one annotation per
  visible instance: ``bbox`` the tight box of its pixels, ``area`` their count, RLE
  ``segmentation`` (``pycocotools.mask.encode``), ``iscrowd`` 0, ``instance_id``,
  ``visible_fraction``, ``truncated``);
- the bag topics ``<topic>/semantic``, ``<topic>/instance`` (mono16) and
  ``<topic>/detections`` (vision_msgs/Detection2DArray).

Rolling shutter: the ids of an output row come from the id render at the render instant
of the frame's shutter plan (:func:`~.shutter.shutter_plan`) with the largest weight in
that row, i.e. the one nearest the middle of the row's exposure window (the configured
``exposure_time``); a global shutter's ids from its middle instant.

``visible_fraction`` and ``truncated`` are measured on fixed surface samples of each
instance (:func:`surface_samples`, area-weighted, the same in every frame): of the
samples in front of the camera, ``truncated`` is the fraction that projects outside the
image; of those inside, ``visible_fraction`` is the fraction whose pixel shows the
instance itself (a part hidden by the instance's own front counts as visible).
"""

from __future__ import annotations

import functools
import json
import weakref
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from roslan.io.files import atomic_write_text
from roslan.io.images import write_png
from roslan.scene.instances import SceneLabels, scene_labels
from roslan.sensors.cameras.model import pose_matrices
from roslan.sensors.cameras.remap import remap_view

if TYPE_CHECKING:
    from roslan.render.base import FrameRenderer
    from roslan.scene.model import Scene
    from roslan.sensors.base import Message, SimContext
    from roslan.sensors.cameras.model import CameraModel, RenderPlan

__all__ = [
    "SAMPLES_PER_INSTANCE",
    "CameraLabels",
    "EyeLabels",
    "coco_annotations",
    "instance_boxes",
    "instance_classes",
    "label_messages",
    "label_topics",
    "surface_samples",
]

U16 = NDArray[np.uint16]
F64 = NDArray[np.float64]


def instance_classes(labels: SceneLabels) -> U16:
    """(n + 1,) class id of each instance id (0: nothing), a lookup table for id images."""
    out = np.zeros(len(labels.instances) + 1, dtype=np.uint16)
    ids = np.array([i.id for i in labels.instances], dtype=np.int64)
    out[ids] = [i.class_id for i in labels.instances]
    return out


SAMPLES_PER_INSTANCE = 64
"""Surface samples per instance for ``visible_fraction`` and ``truncated``."""

MONO16 = "mono16"
IMAGE = "sensor_msgs/msg/Image"


def label_topics(topic: str) -> list[tuple[str, str]]:
    """The label topics of a camera (eye) publishing under ``topic``."""
    from roslan.io.vision import DETECTION2D_ARRAY

    return [
        (f"{topic}/semantic", IMAGE),
        (f"{topic}/instance", IMAGE),
        (f"{topic}/detections", DETECTION2D_ARRAY),
    ]


def label_messages(
    t_ns: int,
    stamp: int,
    seq: int,
    topic: str,
    frame: str,
    sem: U16,
    inst: U16,
    dets: tuple[Any, Any, Any],
) -> Iterator[Message]:
    """The bag messages of one labelled frame of a camera (eye) publishing under
    ``topic`` (:func:`label_topics`): its semantic and instance images (mono16) and its
    Detection2DArray of ``dets`` = (boxes (N, 4) x, y, w, h; class ids; instance ids).
    Used by the frame, stereo and depth cameras and by the event camera's APS frames."""
    from roslan.io.vision import DETECTION2D_ARRAY, detection2d_array
    from roslan.sensors.base import Message

    boxes, classes, insts = dets

    def image(data: U16, store: Any) -> Any:
        return store.image(frame, stamp, data, MONO16, seq)

    def detections(store: Any) -> Any:
        return detection2d_array(store, stamp, frame, boxes, classes, insts)

    yield Message(t_ns, f"{topic}/semantic", IMAGE, functools.partial(image, sem))
    yield Message(t_ns, f"{topic}/instance", IMAGE, functools.partial(image, inst))
    yield Message(t_ns, f"{topic}/detections", DETECTION2D_ARRAY, detections)


_SAMPLES: weakref.WeakKeyDictionary[Scene, tuple[F64, NDArray[np.int64]]] = (
    weakref.WeakKeyDictionary()
)


def surface_samples(scene: Scene) -> tuple[F64, NDArray[np.int64]]:
    """(N, 3) world points on the instances' triangles (area-weighted, a fixed seed) and
    (N,) the instance id of each: :data:`SAMPLES_PER_INSTANCE` per instance."""
    got = _SAMPLES.get(scene)
    if got is not None:
        return got
    labels = scene_labels(scene)
    verts, faces, _ = scene.at(0.0).triangles
    tri_inst = labels.triangle_instance.astype(np.int64)
    keep = np.flatnonzero(tri_inst > 0)
    corners = verts[faces[keep]].astype(np.float64)
    area = 0.5 * np.linalg.norm(
        np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
    )
    inst = tri_inst[keep]
    order = np.argsort(inst, kind="stable")
    inst, area, corners = inst[order], area[order], corners[order]
    n_inst = len(labels.instances)
    cum = np.cumsum(area)
    total = np.zeros(n_inst + 1)
    np.add.at(total, inst, area)
    before = np.concatenate([[0.0], np.cumsum(total)])[:-1]  # area of smaller ids
    rng = np.random.default_rng(47)
    ids = np.repeat(np.arange(1, n_inst + 1), SAMPLES_PER_INSTANCE)
    u = (np.arange(ids.size) % SAMPLES_PER_INSTANCE + rng.random(ids.size)) / SAMPLES_PER_INSTANCE
    target = before[ids] + u * total[ids]
    tri = np.clip(np.searchsorted(cum, target), 0, max(cum.size - 1, 0))
    has = total[ids] > 0
    ids, tri = ids[has], tri[has]
    a, b = rng.random(ids.size), rng.random(ids.size)
    flip = a + b > 1.0
    a[flip], b[flip] = 1.0 - a[flip], 1.0 - b[flip]
    c = corners[tri]
    pts = c[:, 0] + a[:, None] * (c[:, 1] - c[:, 0]) + b[:, None] * (c[:, 2] - c[:, 0])
    _SAMPLES[scene] = (pts, ids)
    return pts, ids


def instance_boxes(inst: U16) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """The instances in ``inst`` (ids > 0, ascending), their pixel counts and tight boxes
    ``(x0, y0, x1, y1)`` (inclusive pixel indices), vectorised: one stable sort of the
    pixels by id (row-major order kept within an id: its first pixel has the smallest row,
    its last the largest), the columns' extremes reduced per id."""
    w = inst.shape[1]
    flat = inst.reshape(-1)
    order = np.argsort(flat, kind="stable")  # (a radix sort for uint16)
    ids_sorted = flat[order]
    starts = np.flatnonzero(np.concatenate([[True], ids_sorted[1:] != ids_sorted[:-1]]))
    ends = np.concatenate([starts[1:], [flat.size]])
    ids = ids_sorted[starts].astype(np.int64)
    keep = ids > 0
    if not keep.any():
        e = np.zeros(0, dtype=np.int64)
        return e, e.copy(), np.zeros((0, 4), dtype=np.int64)
    cols = (order % w).astype(np.int64)
    x0 = np.minimum.reduceat(cols, starts)
    x1 = np.maximum.reduceat(cols, starts)
    y0 = order[starts] // w
    y1 = order[ends - 1] // w
    boxes = np.stack([x0, y0, x1, y1], axis=1).astype(np.int64)[keep]
    return ids[keep], (ends - starts).astype(np.int64)[keep], boxes


def _runs(inst: U16) -> dict[int, list[int]]:
    """Every instance's uncompressed COCO RLE counts (column-major runs of 0 and 1,
    starting with 0s) from one pass over ``inst``."""
    f = np.ascontiguousarray(inst.T).reshape(-1)
    n = f.size
    cut = np.flatnonzero(f[1:] != f[:-1]) + 1
    starts = np.concatenate([[0], cut])
    ends = np.concatenate([cut, [n]])
    vals = f[starts]
    order = np.argsort(vals, kind="stable")
    vals, starts, ends = vals[order], starts[order], ends[order]
    first = np.concatenate([[0], np.flatnonzero(np.diff(vals)) + 1])
    last = np.concatenate([first[1:], [vals.size]])
    out: dict[int, list[int]] = {}
    for a, b in zip(first.tolist(), last.tolist(), strict=True):
        k = int(vals[a])
        if k == 0:
            continue
        edges = np.empty(2 * (b - a) + 2, dtype=np.int64)
        edges[0], edges[-1] = 0, n
        edges[1:-1:2], edges[2:-1:2] = starts[a:b], ends[a:b]
        c = np.diff(edges)
        out[k] = (c[:-1] if c[-1] == 0 else c).tolist()
    return out


def coco_annotations(
    inst: U16, image_id: int, first_id: int, inst_class: U16, extra: dict[int, dict[str, float]]
) -> list[dict[str, Any]]:
    """COCO annotations of every instance visible in ``inst`` (ids from ``first_id``)."""
    from pycocotools import mask as mask_utils

    ids, counts, boxes = instance_boxes(inst)
    runs = _runs(inst)
    h, w = inst.shape
    out = []
    # COCO's column-major RLE of each mask, compressed by pycocotools (one call for all)
    keys = ids.tolist()
    rles = (
        mask_utils.frPyObjects([{"size": [h, w], "counts": runs[k]} for k in keys], h, w)
        if keys
        else []
    )
    for j, (k, n, (x0, y0, x1, y1), rle) in enumerate(
        zip(keys, counts.tolist(), boxes.tolist(), rles, strict=True)
    ):
        ann: dict[str, Any] = {
            "id": first_id + j,
            "image_id": image_id,
            "category_id": int(inst_class[k]),
            "instance_id": int(k),
            "bbox": [int(x0), int(y0), int(x1 - x0 + 1), int(y1 - y0 + 1)],
            "area": int(n),
            "segmentation": {
                "size": [int(s) for s in rle["size"]],
                "counts": rle["counts"].decode(),
            },
            "iscrowd": 0,
        }
        ann.update(extra.get(int(k), {"visible_fraction": 0.0, "truncated": 0.0}))
        out.append(ann)
    return out


class EyeLabels:
    """The label outputs of one eye of a camera: id renders, PNGs, COCO records."""

    def __init__(
        self,
        scene: Scene,
        model: CameraModel,
        plan: RenderPlan,
        folder: str,
        image_dir: str,
        *,
        write_files: bool,
        near: float = 0.01,
    ) -> None:
        labels: SceneLabels = scene_labels(scene)
        self.near = near
        self.model, self.plan = model, plan
        self.folder, self.image_dir = folder, image_dir  # "<cam>/" (or ""), "images/"
        self.write_files = write_files
        self.tri_inst = np.concatenate([[0], labels.triangle_instance]).astype(np.uint16)
        self.inst_class = instance_classes(labels)
        self.classes = labels.classes
        self.images: list[dict[str, Any]] = []
        self.annotations: list[dict[str, Any]] = []
        self.samples = surface_samples(scene)

    # -------------------------------------------------------------- GL thread
    def render(
        self,
        renderer: FrameRenderer,
        T_world_optical: F64,
        instants_ns: NDArray[np.int64],
        near: float,
    ) -> list[NDArray[np.uint32]]:
        """The id renders of the virtual view at each pose ``T_world_optical[k]``."""
        p = self.plan
        out = []
        for k in range(len(T_world_optical)):
            res = renderer.render(
                T_world_optical[k], p.K, p.width, p.height, color=False, depth=False,
                near=near, t=float(instants_ns[k]) * 1e-9, ids=True,
            )  # fmt: skip
            assert res.ids is not None
            out.append(res.ids)
        return out

    # ------------------------------------------------------------ any thread
    def instance_image(self, raws: list[NDArray[np.uint32]], pick: NDArray[np.int64]) -> U16:
        """(H, W) uint16 instance ids at the output pixels: row ``r`` from render
        ``pick[r]`` (through the lens, nearest)."""
        h = self.model.height
        out = np.empty((h, self.model.width), dtype=np.uint16)
        for k in np.unique(pick).tolist():
            view = self.tri_inst[raws[k]]
            img = remap_view(self.plan, view, nearest=True, exact=True)
            rows = pick == k
            out[rows] = img[rows]
        return out

    def frame(
        self, ctx: SimContext, index: int, t_ns: int, inst: U16, T_world_optical: F64
    ) -> dict[str, Any]:
        """Frame ``index`` (any thread): its PNGs (if writing files), its COCO image and
        annotations, and its semantic image (for the bag)."""
        sem = self.inst_class[inst]
        name = f"{index:08d}.png"
        image_id = index + 1
        extra = self._visibility(inst, T_world_optical)
        anns = coco_annotations(inst, image_id, 0, self.inst_class, extra)
        if self.write_files:
            write_png(ctx.path(f"{self.folder}semantic/{name}"), sem)
            write_png(ctx.path(f"{self.folder}instance/{name}"), inst)
        return {
            "image": {
                "id": image_id,
                "file_name": f"{self.image_dir}{name}",
                "width": int(self.model.width),
                "height": int(self.model.height),
                "t_ns": int(t_ns),
            },
            "annotations": anns,
            "semantic": sem,
        }

    def _visibility(self, inst: U16, T_world_optical: F64) -> dict[int, dict[str, float]]:
        pts, ids = self.samples
        if ids.size == 0:
            return {}
        T = np.linalg.inv(T_world_optical)
        pc = pts @ T[:3, :3].T + T[:3, 3]
        front = pc[:, 2] > self.near
        uv = np.full((ids.size, 2), -1.0)
        uv[front] = self.model.project(pc[front])
        h, w = inst.shape
        uv = np.nan_to_num(np.clip(uv, -2.0, 2.0 * max(h, w)), nan=-2.0)
        u = np.floor(uv[:, 0] + 0.5).astype(np.int64)
        v = np.floor(uv[:, 1] + 0.5).astype(np.int64)
        inside = front & (u >= 0) & (u < w) & (v >= 0) & (v < h)
        seen = np.zeros(ids.size, dtype=bool)
        seen[inside] = inst[v[inside], u[inside]] == ids[inside]
        size = int(ids.max()) + 1
        n_front = np.bincount(ids[front], minlength=size)
        n_in = np.bincount(ids[inside], minlength=size)
        n_seen = np.bincount(ids[seen], minlength=size)
        ks = np.unique(inst).astype(np.int64)
        ks = ks[(ks > 0) & (ks < size)]
        out = {}
        for k, s, i, f in zip(
            ks.tolist(), n_seen[ks].tolist(), n_in[ks].tolist(), n_front[ks].tolist(),
            strict=True,
        ):  # fmt: skip
            vis = s / i if i else 0.0
            trunc = 1.0 - i / f if f else 0.0
            out[k] = {"visible_fraction": round(vis, 4), "truncated": round(trunc, 4)}
        return out

    def add(self, record: dict[str, Any]) -> None:
        """Keep frame ``record``'s COCO entries (in frame order)."""
        self.images.append(record["image"])
        base = len(self.annotations) + 1
        for j, ann in enumerate(record["annotations"]):
            ann["id"] = base + j
            self.annotations.append(ann)

    def close(self, ctx: SimContext) -> None:
        """Write ``annotations.json`` (atomically)."""
        if not self.write_files:
            return
        doc = {
            "info": {"description": "roslan ground-truth labels (docs/guide/labels.md)"},
            "images": self.images,
            "categories": [
                {"id": c.id, "name": c.name, "supercategory": "object"}
                for c in self.classes
                if c.id >= 2
            ],
            "annotations": self.annotations,
        }
        atomic_write_text(ctx.path(f"{self.folder}annotations.json"), json.dumps(doc) + "\n")


class CameraLabels:
    """The label outputs of a camera sensor's eyes, run from its frame loop
    (:meth:`~.common.CameraBase._frames`): :meth:`render` on the GL thread, :meth:`post`
    on any, :meth:`messages` and :meth:`add` in frame order."""

    def __init__(self, ctx: SimContext, camera: Any) -> None:
        c = camera.config
        self.camera = camera
        self.exposure = float(getattr(c, "exposure_time", 0.0))
        self.readout = float(c.readout_time)
        self.samples = int(getattr(c, "exposure_samples", getattr(c, "readout_samples", 1)))
        self.near = float(c.near_clip)
        writes = ctx.files is not None
        self.eyes: list[tuple[Any, EyeLabels]] = []
        for e in camera._eyes:
            name = f"{c.name}_{e.suffix}" if e.suffix else c.name
            if c.type == "depth_camera":
                folder, image_dir = f"depth/{c.name}/", ""
            else:
                folder, image_dir = ctx.camera_folder(name), "images/"
            lab = EyeLabels(
                ctx.scene, e.model, e.plan, folder, image_dir, write_files=writes, near=self.near
            )
            self.eyes.append((e, lab))

    def _plan(self, t_ns: int, height: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """The id render instants of frame ``t_ns`` and each output row's render."""
        from roslan.sensors.cameras.shutter import shutter_plan

        plan = shutter_plan(t_ns, self.exposure, self.readout, self.samples, height)
        n = plan.instants_ns.size
        if plan.weights is None:
            pick = np.full(height, (n - 1) // 2, dtype=np.int64)
        else:
            pick = np.argmax(plan.weights, axis=1).astype(np.int64)
        used, inv = np.unique(pick, return_inverse=True)
        return plan.instants_ns[used], inv.reshape(-1).astype(np.int64)

    def render(self, ctx: SimContext, t_ns: int) -> list[Any]:
        """Every eye's id renders of frame ``t_ns`` (the GL thread)."""
        renderer = ctx.renderer()
        T_bs = self.camera._T_body_sensor
        jobs = []
        for e, lab in self.eyes:
            instants, pick = self._plan(t_ns, e.model.height)
            T = pose_matrices(ctx, instants) @ T_bs @ e.T_sensor_optical
            raws = lab.render(renderer, T, instants, self.near)
            mid = int(pick[e.model.height // 2])
            jobs.append((raws, pick, T[mid]))
        return jobs

    def post(self, ctx: SimContext, i: int, t_ns: int, jobs: list[Any]) -> list[dict[str, Any]]:
        """Every eye's label images and records of frame ``i`` (any thread)."""
        out = []
        for (_, lab), (raws, pick, T_mid) in zip(self.eyes, jobs, strict=True):
            inst = lab.instance_image(raws, pick)
            rec = lab.frame(ctx, i, t_ns, inst, T_mid)
            rec["instance"] = inst
            out.append(rec)
        return out

    def messages(self, ctx: SimContext, t_ns: int, seq: int, recs: list[dict[str, Any]]) -> Any:
        """The bag messages of frame ``seq`` (in frame order) and its COCO entries kept."""
        stamp = ctx.stamp(t_ns)
        for (e, lab), rec in zip(self.eyes, recs, strict=True):
            lab.add(rec)
            anns = rec["annotations"]
            boxes = np.array([a["bbox"] for a in anns], dtype=np.float64).reshape(-1, 4)
            classes = np.array([a["category_id"] for a in anns], dtype=np.int64)
            insts = np.array([a["instance_id"] for a in anns], dtype=np.int64)
            yield from label_messages(
                t_ns, stamp, seq, e.topic, e.frame, rec["semantic"], rec["instance"],
                (boxes, classes, insts),
            )  # fmt: skip

    def close(self, ctx: SimContext) -> None:
        for _, lab in self.eyes:
            lab.close(ctx)
