"""Label outputs of the event camera (``output.labels``).

- ``events.h5`` gains ``events/label`` (uint32, aligned with ``events/t``), the
  SemanticKITTI encoding ``class | instance << 16`` of the surface that caused each
  event: what its pixel sees (the Embree ray of the pixel's own, distorted, ray) at the
  pose of the render bracketing the event's time nearest to it, the render whose
  brightness change made it cross the threshold. Noise events (shot noise and leak
  events, :meth:`~roslan.events.model.EventGenerator._noise`) get class 1 ``noise``,
  instance 0; a ray that hits nothing gives 0.
- ``tracks.npy`` beside it: DSEC-Det's (and Prophesee's ``BBOX_DTYPE``) structured array
  :data:`TRACKS_DTYPE`, one row per instance visible in the camera's distorted view at
  each label instant (the APS frame instants, every ``1 / rate``, or every
  ``1 / label_rate``): ``t`` microseconds since the trajectory start (as ``events/t``),
  ``x, y, w, h`` the tight box of the instance's pixels (top-left corner, pixels),
  ``class_id``, ``class_confidence`` 1, ``track_id`` the instance id.
- The APS frames get ``instance/<frame>.png`` and ``semantic/<frame>.png`` (uint16) from
  the same ray-cast image at the frame's instant, and the bag topics of a frame camera's
  labels: ``<topic>/semantic``, ``<topic>/instance`` (mono16) and ``<topic>/detections``.

The id images are ray cast through every pixel's own ray (pixel centre), so they are the
distorted view exactly; the rays, poses and per-triangle table are those of every other
labelled sensor (:func:`roslan.scene.instances.scene_labels`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from roslan.events.sampling import camera_twist
from roslan.io.files import atomic_write_bytes
from roslan.io.images import write_png
from roslan.scene.classes import NOISE_CLASS_ID
from roslan.scene.instances import scene_labels
from roslan.sensors.cameras.labels import instance_boxes, instance_classes, label_messages

if TYPE_CHECKING:
    from roslan.events.model import EventBatch
    from roslan.sensors.base import Message, SimContext

__all__ = ["TRACKS_DTYPE", "EventLabels"]

TRACKS_DTYPE = np.dtype(
    [
        ("t", "<u8"),
        ("x", "<f4"),
        ("y", "<f4"),
        ("w", "<f4"),
        ("h", "<f4"),
        ("class_id", "u1"),
        ("class_confidence", "<f4"),
        ("track_id", "<u4"),
    ]
)
"""DSEC-Det's ``tracks.npy`` dtype (Prophesee's ``BBOX_DTYPE``)."""

F64 = NDArray[np.float64]
U32 = NDArray[np.uint32]


class EventLabels:
    """The label side of one event camera's stream (runs where ESIM runs, in order)."""

    def __init__(self, sensor: Any, ctx: SimContext, label_times: NDArray[np.int64]) -> None:
        labels = scene_labels(ctx.scene)
        tri_code = labels.triangle_class.astype(np.uint32) | (
            labels.triangle_instance.astype(np.uint32) << np.uint32(16)
        )
        self.code = np.concatenate([[0], tri_code]).astype(np.uint32)  # 0: nothing hit
        self.ctx = ctx
        self.caster = ctx.raycaster()  # (built here, on the sensor's own thread)
        self.traj = ctx.trajectory
        self.T_body_cam = sensor.T_body_cam
        cam = sensor.camera
        self.width, self.height = cam.width, cam.height
        x, y = cam.rays
        d = np.stack([x.ravel(), y.ravel(), np.ones(x.size)], axis=1)
        self.dirs = d / np.linalg.norm(d, axis=1, keepdims=True)  # optical frame
        self.label_times = np.asarray(label_times, dtype=np.int64)
        self.next_label = 0
        self.tracks: list[NDArray[Any]] = []
        self.folder = sensor._prefix(ctx)
        self.write_files = ctx.files is not None
        self.t_prev: int | None = None
        self.aps_index = 0
        self.topic, self.frame = sensor.config.topic, sensor.optical_frame
        self.inst_class = instance_classes(labels)  # instance id -> class id
        self._cached: tuple[int, NDArray[np.uint16], NDArray[np.uint16]] | None = None

    def _cast(self, t_ns: int, pix: NDArray[np.int64]) -> U32:
        """The codes of the surfaces pixels ``pix`` (flat indices) see at ``t_ns``."""
        T = camera_twist(self.traj, int(t_ns), self.T_body_cam)[0]
        d = self.dirs[pix] @ T[:3, :3].T
        o = np.broadcast_to(T[:3, 3], d.shape)
        tri = self.caster.cast(o, d, t=t_ns * 1e-9).triangle
        out: U32 = self.code[tri.astype(np.int64) + 1]
        return out

    def events(self, batch: EventBatch, noise: NDArray[np.bool_], t_ns: int) -> U32:
        """``events/label`` of ``batch``, the events of the interval ending at the render
        ``t_ns`` (``noise``: which are noise)."""
        out = np.zeros(batch.size, dtype=np.uint32)
        if batch.size:
            pix = batch.y.astype(np.int64) * self.width + batch.x
            prev = self.t_prev
            use_prev = (
                np.zeros(batch.size, bool) if prev is None else (batch.t - prev) < (t_ns - batch.t)
            )
            for mask, t in ((use_prev, prev), (~use_prev, t_ns)):
                sel = mask & ~noise
                if t is not None and sel.any():
                    out[sel] = self._cast(t, pix[sel])
            out[noise] = NOISE_CLASS_ID
        return out

    def instant(self, t_ns: int, aps: bool) -> list[Message]:
        """After the render ``t_ns``: the label instants up to it (tracks rows) and, for
        an APS frame at ``t_ns`` (``aps``), its instance and semantic PNGs and its bag
        messages (:func:`~.labels.label_messages`, as a frame camera's)."""
        times = self.label_times
        while self.next_label < times.size and times[self.next_label] <= t_ns:
            self._track(int(times[self.next_label]))
            self.next_label += 1
        out: list[Message] = []
        if aps:
            inst, sem = self._images(t_ns)
            if self.write_files:
                name = f"{self.aps_index:08d}.png"
                write_png(self.ctx.path(f"{self.folder}instance/{name}"), inst)
                write_png(self.ctx.path(f"{self.folder}semantic/{name}"), sem)
            ids, _, b = instance_boxes(inst)
            boxes = np.column_stack([b[:, :2], b[:, 2:] - b[:, :2] + 1]).astype(np.float64)
            dets = (boxes, self.inst_class[ids].astype(np.int64), ids)
            out += label_messages(
                t_ns, self.ctx.stamp(t_ns), self.aps_index, self.topic, self.frame, sem, inst,
                dets,
            )  # fmt: skip
            self.aps_index += 1
        self.t_prev = t_ns
        self._cached = None
        return out

    def _images(self, t_ns: int) -> tuple[NDArray[np.uint16], NDArray[np.uint16]]:
        """The instance and semantic images at ``t_ns`` (one full-frame cast per instant:
        a label instant that is also an APS instant reuses it)."""
        if self._cached is not None and self._cached[0] == t_ns:
            return self._cached[1], self._cached[2]
        code = self._cast(t_ns, np.arange(self.width * self.height)).reshape(
            self.height, self.width
        )
        inst, sem = (code >> 16).astype(np.uint16), (code & 0xFFFF).astype(np.uint16)
        self._cached = (t_ns, inst, sem)
        return inst, sem

    def _track(self, t_ns: int) -> None:
        inst, sem = self._images(t_ns)
        ids, _, boxes = instance_boxes(inst)
        if ids.size == 0:
            return
        # each instance's class: the semantic id at one of its pixels
        flat_i, flat_s = inst.reshape(-1), sem.reshape(-1)
        first = np.full(int(ids[-1]) + 1, -1, dtype=np.int64)
        order = np.arange(flat_i.size)[::-1]
        first[flat_i[order]] = order  # the first pixel of each id (the last write wins)
        rows = np.zeros(ids.size, dtype=TRACKS_DTYPE)
        rows["t"] = t_ns // 1000
        rows["x"], rows["y"] = boxes[:, 0], boxes[:, 1]
        rows["w"] = boxes[:, 2] - boxes[:, 0] + 1
        rows["h"] = boxes[:, 3] - boxes[:, 1] + 1
        rows["class_id"] = np.minimum(flat_s[first[ids]], 255)
        rows["class_confidence"] = 1.0
        rows["track_id"] = ids
        self.tracks.append(rows)

    def close(self) -> None:
        """Write ``tracks.npy`` (atomically)."""
        if not self.write_files:
            return
        import io

        arr = np.concatenate(self.tracks) if self.tracks else np.zeros(0, TRACKS_DTYPE)
        buf = io.BytesIO()
        np.save(buf, arr, allow_pickle=False)
        atomic_write_bytes(self.ctx.path(f"{self.folder}tracks.npy"), buf.getvalue())
