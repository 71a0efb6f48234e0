"""Shared machinery of the frame, stereo and depth cameras: eyes, stamps, dataset files,
messages, and the frame loop that runs each frame's post-render work on the sensor's
thread pool.

**Frames on threads.** The OpenGL context belongs to the sensor's own thread, so every
render stays there, in time order. What follows a frame's renders (lens remap and
rolling-shutter composition, noise, 8-bit encoding, the PNG file) is independent of the
other frames and runs on an :class:`~roslan.io.ordered.OrderedPool` of
``ctx.sensor_threads`` threads while the next frame renders; the frames come back in
order, so ``images.txt``, the PNG files and every message are the same whatever the
number of threads (1: all inline, in the order of earlier versions). The noise draws of a
sensor's random generator happen inside the pool's ordered turn (frame after frame, eye
after eye), so its stream is the one an inline run draws.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import IO, Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from roslan.errors import RenderError, SensorError
from roslan.io.images import write_png
from roslan.io.messages import MessageStore
from roslan.io.ordered import OrderedPool, Turn
from roslan.io.text import format_seconds
from roslan.sensors.base import (
    Message,
    SimContext,
    StaticTransform,
    TopicSpec,
    paced,
    sample_times_ns,
)
from roslan.sensors.cameras.model import CameraModel, RenderPlan, pose_matrices
from roslan.sensors.cameras.row_exposure import RowShot, output_rays
from roslan.sensors.cameras.shutter import shutter_plan
from roslan.sensors.clock import Grid
from roslan.sensors.measurements import Frame

__all__ = ["CAMERA_INFO", "IMAGE", "RAW_ROWS_FACTOR", "CameraBase", "Eye", "Shot", "pose_matrices"]

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]

IMAGE = "sensor_msgs/msg/Image"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"

RAW_ROWS_FACTOR = 4
"""On a thread pool, a rolling-shutter frame's renders (frame and stereo cameras; depth:
full views) are handed over unremapped when
their rows total at most this many times the virtual view's height; beyond (many samples
of a long exposure) they are remapped and added on the sensor's thread as they are drawn,
one band in memory at a time (the same arithmetic in the same order: the same bytes)."""


@dataclass
class Eye:
    """One physical camera of a sensor: intrinsics, extrinsics, render plan, outputs."""

    suffix: str  # '' or 'left' / 'right'
    model: CameraModel
    T_sensor_optical: F64  # pose of the optical frame in the sensor link frame
    topic: str  # prefix: <topic>[/left]
    frame: str  # optical frame id
    Tx: float = 0.0
    plan: RenderPlan | None = None
    files: str = ""  # PNG folder: images, <name>/images or depth/<name>
    index_fh: IO[str] | None = None
    exposure_fh: IO[str] | None = None  # exposures.txt: t exposure
    rays: tuple[F32, F32] | None = None  # (x, y) of every output pixel's ray (row_exposure)
    scratch: threading.local = field(default_factory=threading.local, repr=False)

    def buffer(self, key: str, shape: tuple[int, ...]) -> F32:
        """A float32 work array of ``shape`` reused from frame to frame by the calling
        thread (each thread has its own): fresh multi-MB arrays every frame cost page
        faults (thousands per 640x480 frame when glibc returns the freed memory)."""
        arrays: dict[str, F32] = self.scratch.__dict__
        a = arrays.get(key)
        if a is None or a.shape != shape:
            a = arrays[key] = np.empty(shape, dtype=np.float32)
        return a


class Shot(NamedTuple):
    """One eye's finished frame: the message data and whether a PNG file was written."""

    eye: Eye
    data: NDArray[Any]
    encoding: str
    png: bool


class CameraBase:
    """Shared machinery of the three camera sensors."""

    config: Any
    _eyes: list[Eye]

    def _row_shot(
        self, ctx: SimContext, e: Eye, t_ns: int, exposure: float, readout: float, samples: int
    ) -> RowShot:
        """Eye ``e``'s row formation of the frame stamped ``t_ns`` (:mod:`.row_exposure`):
        its output rays (made once) and its optical poses from the trajectory."""
        p = e.plan
        assert p is not None
        if e.rays is None:
            e.rays = output_rays(p, e.model.width, e.model.height)
        T_bo = self._T_body_sensor @ e.T_sensor_optical

        def poses(t: NDArray[np.int64]) -> F64:
            out: F64 = pose_matrices(ctx, t) @ T_bo
            return out

        return RowShot(p, e.rays, poses, t_ns, exposure, readout, samples)

    def _setup_eyes(self, eyes: list[Eye]) -> None:
        self._eyes = eyes
        self._T_body_sensor = self.config.pose.matrix()

    def topics(self) -> list[TopicSpec]:
        out = []
        for e in self._eyes:
            out += [
                TopicSpec(f"{e.topic}/image_raw", IMAGE),
                TopicSpec(f"{e.topic}/camera_info", CAMERA_INFO),
            ]
            if getattr(self.config, "writes_labels", False):
                from roslan.sensors.cameras.labels import label_topics

                out += [TopicSpec(t, m) for t, m in label_topics(e.topic)]
        return out

    def static_transforms(self) -> list[StaticTransform]:
        # base_link -> frame comes from the extrinsics (pipeline); the eyes are ours
        frame = self.config.frame
        return [StaticTransform(frame, e.frame, e.T_sensor_optical.copy()) for e in self._eyes]

    def _plans(self, ctx: SimContext) -> Any:
        renderer = ctx.renderer()
        for e in self._eyes:
            if e.plan is None:
                try:
                    e.plan = e.model.render_plan(
                        renderer.max_size, scale=getattr(self.config, "render_scale", None)
                    )
                except SensorError as err:
                    msg = f"sensors: {self.config.name}: {err}"
                    raise SensorError(msg) from None
                try:
                    renderer.check_size(e.plan.width, e.plan.height)
                except RenderError as err:
                    msg = f"sensor {self.config.name!r}: resolution: {err}"
                    raise SensorError(msg) from None
        return renderer

    def _grid(self, ctx: SimContext) -> Grid:
        """The image stamps (:meth:`_stamps`) as the horizon reveals them: a frame is
        rendered once its whole shutter window lies before the horizon."""
        lead = max(0, int(self._window_offsets().max()))
        return ctx.clock.grid(self._stamps, lead_ns=lead)

    def _stamps(self, end: int) -> NDArray[np.int64]:
        """Image stamps every ``1 / rate`` from 0 whose every rendered instant (the
        longest shutter window's) lies within a run ending at ``end`` (ns; the ground
        truth covers them)."""
        stamps = sample_times_ns(self.config.rate, end)
        offs = self._window_offsets()
        if stamps.size == 0:
            return stamps
        keep = (stamps + int(offs.min()) >= 0) & (stamps + int(offs.max()) <= end)
        return stamps[keep]

    def _window_offsets(self) -> NDArray[np.int64]:
        """Render instants of the longest shutter window, relative to the stamp (ns)."""
        c = self.config
        exposure = c.max_exposure() if hasattr(c, "max_exposure") else 0.0
        samples = int(getattr(c, "exposure_samples", getattr(c, "readout_samples", 1)))
        height = self._eyes[0].model.height
        return shutter_plan(0, exposure, c.readout_time, samples, height).instants_ns

    def _open_index(self, ctx: SimContext, e: Eye, kind: str) -> None:
        if kind == "depth":
            e.files = f"depth/{self.config.name}"
            e.index_fh = ctx.path(f"depth_{self.config.name}.txt").open(
                "w", encoding="utf-8", newline="\n"
            )
            return
        name = f"{self.config.name}_{e.suffix}" if e.suffix else self.config.name
        folder = ctx.camera_folder(name)  # '' at the OUTDIR root, else '<name>/'
        e.files = f"{folder}images"
        e.index_fh = ctx.path(f"{folder}images.txt").open("w", encoding="utf-8", newline="\n")
        if getattr(self.config, "exposure_time", 0.0) > 0:
            e.exposure_fh = ctx.path(f"{folder}exposures.txt").open(
                "w", encoding="utf-8", newline="\n"
            )

    def _png(self, ctx: SimContext, e: Eye, index: int, img: NDArray[Any]) -> None:
        """Write frame ``index``'s PNG file (any thread; its index line: :meth:`_listed`)."""
        if img.ndim == 3 and getattr(self.config, "encoding", "rgb8") == "bgr8":
            img = img[..., ::-1]  # the topic's bgr8 data; a PNG file holds RGB
        write_png(ctx.path(f"{e.files}/{index:08d}.png"), img)

    def _label_outputs(self, ctx: SimContext) -> Any:
        """The sensor's :class:`~.labels.CameraLabels` when it writes labels, else None."""
        if not getattr(self.config, "writes_labels", False):
            return None
        from roslan.sensors.cameras.labels import CameraLabels

        self._labels = CameraLabels(ctx, self)
        return self._labels

    def _listed(self, e: Eye, index: int, t_ns: int) -> None:
        """Frame ``index``'s line in the eye's index file (in frame order)."""
        # images.txt lists paths relative to its own folder; depth_<name>.txt to OUTDIR
        rel = f"{e.files}/{index:08d}.png"
        listed = rel if e.files.startswith("depth/") else f"images/{index:08d}.png"
        assert e.index_fh is not None
        e.index_fh.write(f"{format_seconds(np.array([t_ns]))[0]} {listed}\n")

    def close(self, ctx: SimContext) -> None:
        labels = getattr(self, "_labels", None)
        if labels is not None:
            labels.close(ctx)
        for e in self._eyes:
            for fh in (e.index_fh, e.exposure_fh):
                if fh is not None and not fh.closed:
                    fh.close()

    def _messages(
        self, ctx: SimContext, t_ns: int, seq: int, e: Eye, data: NDArray[Any], encoding: str
    ) -> list[Message]:
        stamp = ctx.stamp(t_ns)
        frame = e.frame

        def build_image(store: MessageStore) -> Any:
            return store.image(frame, stamp, data, encoding, seq)

        def build_info(store: MessageStore) -> Any:
            return e.model.camera_info(store, e.frame, stamp, seq, e.Tx)

        return [
            Message(t_ns, f"{e.topic}/image_raw", IMAGE, build_image),
            Message(t_ns, f"{e.topic}/camera_info", CAMERA_INFO, build_info),
        ]

    def _frames(
        self,
        ctx: SimContext,
        grid: Grid,
        render: Callable[[bool, int, int], Any],
        post: Callable[[Turn, int, int, Any], list[Shot]],
    ) -> Iterator[Message]:
        """The messages of the frames at the instants of ``grid`` (waiting for the horizon
        where it must, every frame submitted so far published first):
        ``render(inline, i, t)`` on this
        thread (every renderer call; ``inline``: ``post`` runs right after, on this
        thread, so work buffers of this thread may be handed over), then
        ``post(turn, i, t, job)`` on the sensor's pool (random draws inside ``turn``),
        its :class:`Shot` list listed and published in frame order."""
        pool: OrderedPool[tuple[int, int, list[Shot]]] = OrderedPool(
            ctx.sensor_threads, f"{self.config.name}-frames"
        )
        labels = self._label_outputs(ctx)
        recs: dict[int, Any] = {}  # frame -> its label records (the labels' post)
        if labels is not None:
            render_image = render

            def render(inline: bool, i: int, t: int) -> Any:
                return render_image(inline, i, t), labels.render(ctx, t)

        def task(turn: Turn, i: int, t: int, job: Any) -> tuple[int, int, list[Shot]]:
            if labels is None:
                return i, t, post(turn, i, t, job)
            recs[i] = labels.post(ctx, i, t, job[1])
            return i, t, post(turn, i, t, job[0])

        def emit(done: list[tuple[int, int, list[Shot]]]) -> Iterator[Message]:
            for i, t, shots in done:
                for s in shots:
                    if s.png:
                        self._listed(s.eye, i, t)
                    ctx.clock.tap(self.config.name, Frame(t, s.data, s.eye.suffix))
                    yield from self._messages(ctx, t, i, s.eye, s.data, s.encoding)
                if labels is not None:
                    yield from labels.messages(ctx, t, i, recs.pop(i))

        last = [-1]
        try:
            for item in paced(grid, 1, lambda: last[0] + 1):
                if isinstance(item, Message):
                    yield from emit(pool.finish())  # every frame rendered, then wait
                    yield item
                    continue
                i, t = item[0], int(item[1][0])
                last[0] = t
                job = render(pool.inline, i, t)
                yield from emit(pool.submit(task, i, t, job))
            yield from emit(pool.finish())
        finally:
            pool.close()  # a failed or abandoned run: no write into its folder after this
