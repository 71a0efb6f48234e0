"""Event camera (``type: event_camera``): ESIM on the shared OpenGL renderer.

The sensor renders grayscale linear luminance (Rec. 709 weights of the renderer's
linear radiance) along the closed-form trajectory at adaptively chosen instants
(:class:`~roslan.events.sampling.AdaptiveSampler`: brightness or exact optical flow
from depth + camera twist), feeds the frames to the vectorized pixel model
(:class:`~roslan.events.model.EventGenerator`) and streams:

* ``<topic>/events``: dvs_msgs/EventArray packets of ``packet_duration`` seconds (or
  ``packet_events`` events), stamped with their last event (as rpg_dvs_ros does),
  packed with NumPy straight to wire bytes;
* ``<topic>/camera_info`` at ``rate``; ``<topic>/image_raw`` APS frames (mono8) at
  ``rate`` when ``aps``; ``<topic>/event_image`` (rgb8 event frames for bag viewers,
  :mod:`roslan.sensors.cameras.event_image`) at ``rate`` when ``event_image``;
  ``<topic>/optic_flow`` (32FC2, px/s) and ``<topic>/depthmap``
  (32FC1, m) at ``ground_truth_rate`` when enabled, also as files: DSEC optical-flow PNGs
  in ``flow/`` (the true displacement over ``flow_interval``,
  :mod:`roslan.sensors.cameras.flow_truth`) and an MVSEC-style ``depth.h5``
  (:mod:`roslan.sensors.cameras.event_truth`);
* dataset files (Event Camera Dataset layout): the first event camera's at the OUTDIR
  root, every other one's in ``<name>/``: ``events.txt``, ``events.h5``, APS frames in
  ``images.txt`` + ``images/NNNNNNNN.png``; the run writes its ``calib.txt``,
  ``calib/<name>.yaml`` and ``calib/camchain.yaml``
  (:func:`roslan.rundir.calibration.write_calibration`).

Headers are in ``<frame>_optical`` (z forward, x right, y down).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from roslan.events.files import EventH5Writer, EventTextWriter
from roslan.events.model import EventBatch
from roslan.events.ros import EVENT_ARRAY
from roslan.events.sampling import (
    AdaptiveSampler,
    camera_twist,
    max_flow_speed,
    motion_field,
    pixel_rays,
)
from roslan.io.background import BackgroundSink
from roslan.io.images import write_png
from roslan.io.messages import MessageStore
from roslan.sensors.base import (
    Message,
    SimContext,
    StaticTransform,
    TopicSpec,
    sample_times_ns,
)
from roslan.sensors.cameras.event_causal import ForcedInstants, causal_instants
from roslan.sensors.cameras.event_chains import ChainFarm, Instant, brightness_instants
from roslan.sensors.cameras.event_config import EventCameraConfig
from roslan.sensors.cameras.event_stream import AfterRender
from roslan.sensors.cameras.event_truth import DepthH5Writer, FlowPngWriter
from roslan.sensors.cameras.flow_truth import FlowTruth, depth_on_rays, flow_end_times
from roslan.sensors.cameras.model import T_LINK_OPTICAL, CameraModel, RenderPlan
from roslan.sensors.cameras.remap import remap_result, remap_view
from roslan.sensors.cameras.scene_motion import object_ids, relative_velocity

__all__ = ["EventCamera"]

_STAGE_BACKLOG = 4
"""Rendered instants waiting for the helper thread at most (bounded memory: a frame and its
depth, ~0.7 MB for a DAVIS346)."""

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]


class _Camera:
    """The sensor geometry (:class:`CameraModel`) and how to render it.

    A pinhole camera renders directly; a distorted one renders the virtual pinhole view
    of :meth:`CameraModel.render_plan` and remaps it (bilinear for luminance, nearest
    for depth; the ground truth's depth is ray cast along the output pixels' rays). The
    flow of a distorted camera is the motion field of each output pixel's ray pushed
    through the lens model (central differences of ``project``).
    """

    def __init__(self, model: CameraModel) -> None:
        self.model = model
        self.width, self.height = model.width, model.height
        self.K = model.K
        self.plan: RenderPlan | None = None
        if model.is_pinhole:
            self.rays = pixel_rays(self.K, self.width, self.height)
        else:
            u, v = np.meshgrid(
                np.arange(self.width, dtype=np.float64), np.arange(self.height, dtype=np.float64)
            )
            xy = model.undistort_normalized(np.stack([u.ravel(), v.ravel()], axis=1))
            self.rays = (
                xy[:, 0].reshape(self.height, self.width),
                xy[:, 1].reshape(self.height, self.width),
            )

    def render_plan(self, max_size: int | None) -> RenderPlan:
        if self.plan is None:
            self.plan = self.model.render_plan(max_size)
        return self.plan

    def remap(self, img: NDArray[Any], *, nearest: bool = False) -> NDArray[Any]:
        """``img`` of the virtual view at the output pixels (:func:`.remap.remap_view`)."""
        if self.plan is None:
            return img
        return remap_view(self.plan, img, nearest=nearest)

    def max_flow_speed(self, depth: NDArray[np.floating], v: F64, w: F64) -> float:
        """``max |flow|`` of the output pixels, px/s (one pass for a pinhole camera)."""
        if self.model.is_pinhole:
            return max_flow_speed(depth, self.K, v, w, self.rays)
        f = self.flow(depth, v, w)
        return float(np.max(np.hypot(f[..., 0], f[..., 1])))

    def flow(self, depth: NDArray[np.floating], v: F64, w: F64) -> NDArray[np.float32]:
        """(H, W, 2) float32 image motion of the output pixels, px/s."""
        if self.model.is_pinhole:
            return motion_field(depth, self.K, v, w, self.rays)
        f = motion_field(depth, np.eye(3), v, w, self.rays).astype(np.float64)
        h = 1e-4  # s: the lens is smooth at this scale
        x, y = self.rays
        ones = np.ones(x.size)
        a = self.model.project(
            np.stack([(x - h * f[..., 0]).ravel(), (y - h * f[..., 1]).ravel(), ones], 1)
        )
        b = self.model.project(
            np.stack([(x + h * f[..., 0]).ravel(), (y + h * f[..., 1]).ravel(), ones], 1)
        )
        return ((b - a) / (2 * h)).reshape(self.height, self.width, 2).astype(np.float32)


class EventCamera:
    """The event camera sensor (see the module docstring)."""

    def __init__(self, config: EventCameraConfig) -> None:
        self.config = config
        self.params = config.model_params()
        self.camera = _Camera(config.camera_model())
        self._writers: list[EventTextWriter | EventH5Writer] = []
        self._images_fh: IO[str] | None = None
        self._folder = ""  # '' (OUTDIR root) or '<name>/'
        self._sink: BackgroundSink | None = None
        self._truth: list[FlowPngWriter | DepthH5Writer] = []
        self._flow_file: FlowPngWriter | None = None
        self._depth_file: DepthH5Writer | None = None
        self.flow_truth: FlowTruth | None = None
        """The DSEC flow maps' maker (``optic_flow``), fed by the event stream."""
        self.stats: dict[str, float] = {}
        self._T_body_cam: F64 | None = None
        self.last_ids: NDArray[np.int32] | None = None
        """The object each output pixel saw in the last :meth:`render` (a scene whose
        objects move and a render with depth only; else None)."""
        self._stage: BackgroundSink | None = None
        self._farm: ChainFarm | None = None
        self.pipelined = True
        """Run ESIM, packets and messages on a helper thread beside the renders (False:
        everything on the calling thread; same stream either way)."""
        self.render_here = True
        """With render helpers, render chains here while none is ready (False: only the
        helpers render, :class:`~roslan.sensors.cameras.event_chains.ChainFarm`; same
        stream either way)."""

    # -------------------------------------------------------------- interface
    @property
    def optical_frame(self) -> str:
        return f"{self.config.frame}_optical"

    def topics(self) -> list[TopicSpec]:
        c, t = self.config, self.config.topic
        out = [
            TopicSpec(f"{t}/events", EVENT_ARRAY),
            TopicSpec(f"{t}/camera_info", "sensor_msgs/msg/CameraInfo"),
        ]
        if c.has_aps:
            out.append(TopicSpec(f"{t}/image_raw", "sensor_msgs/msg/Image"))
            if getattr(c, "writes_labels", False):
                from roslan.sensors.cameras.labels import label_topics

                out += [TopicSpec(n, m) for n, m in label_topics(t)]
        if c.event_image:
            out.append(TopicSpec(f"{t}/event_image", "sensor_msgs/msg/Image"))
        if c.optic_flow:
            out.append(TopicSpec(f"{t}/optic_flow", "sensor_msgs/msg/Image"))
        if c.depthmap:
            out.append(TopicSpec(f"{t}/depthmap", "sensor_msgs/msg/Image"))
        return out

    def static_transforms(self) -> list[StaticTransform]:
        return [StaticTransform(self.config.frame, self.optical_frame, T_LINK_OPTICAL.copy())]

    @property
    def T_body_cam(self) -> F64:
        """(4, 4) pose of the optical frame in base_link."""
        return self.config.T_base_optical()

    def _prefix(self, ctx: SimContext) -> str:
        """'' for the OUTDIR-root camera (the first event camera), else '<name>/'."""
        return ctx.camera_folder(self.config.name)

    # -------------------------------------------------------------- rendering
    def render(
        self, ctx: SimContext, t_ns: int, *, need_depth: bool, exact_depth: bool = False
    ) -> tuple[F32, F32 | None, F64, F64]:
        """Luminance (H, W), depth (H, W) or None, camera v and w (optical frame) at ``t_ns``
        (``exact_depth``: a distorted camera's depth along each pixel's own ray, ray cast,
        for the ground truth; else that of the nearest ray of the virtual render). With a
        depth, ``v`` is the camera's velocity relative to each pixel's surface point
        (:func:`~.scene_motion.relative_velocity`: ``v`` (3,) itself in a static scene)."""
        cam = self.camera
        renderer = ctx.renderer()
        plan = cam.render_plan(renderer.max_size)
        if self._T_body_cam is None:  # (the property builds it from the config each time)
            self._T_body_cam = self.T_body_cam
        T_wc, v, w = camera_twist(ctx.trajectory, t_ns, self._T_body_cam)
        view = ctx.scene.at(t_ns * 1e-9)
        moving = need_depth and not view.is_static  # (the object of each pixel wanted)
        # luminance-only pass: one shaded channel, the cheapest read back (roslan.render.gl)
        res = renderer.render(
            T_wc,
            plan.K,
            plan.width,
            plan.height,
            color=False,
            depth=need_depth,
            luminance=True,
            near=self.config.near_clip,
            supersampling=self.config.supersampling,
            t=t_ns * 1e-9,
            **({"ids": True} if moving else {}),
        )
        assert res.luminance is not None
        out = res if cam.plan is None else remap_result(cam.plan, res)
        lum, depth = out.luminance, out.depth
        assert lum is not None
        self.last_ids = None if out.ids is None else object_ids(view, out.ids)
        if depth is not None and exact_depth and not cam.model.is_pinhole:
            depth = depth_on_rays(ctx.raycaster(), T_wc, cam.rays, t=t_ns * 1e-9)
        if depth is not None:  # the scene's own motion (a static scene: v itself)
            v = relative_velocity(view, T_wc, v, depth, cam.rays, self.last_ids)
        return lum, depth, v, w

    # -------------------------------------------------------------- stream
    def messages(self, ctx: SimContext) -> Iterator[Message]:
        try:
            yield from self._stream(ctx)
        except BaseException:  # failed or abandoned run: no more writes into its folder
            if self._farm is not None:
                farm, self._farm = self._farm, None
                farm.kill()
            if self._stage is not None:
                stage, self._stage = self._stage, None
                stage.abort()
            if self._sink is not None:
                sink, self._sink = self._sink, None
                sink.abort()
            raise

    def _stream(self, ctx: SimContext) -> Iterator[Message]:
        c = self.config
        self.stats = {}
        gt_rate = c.ground_truth_rate or c.rate
        # closed loop: instants rendered as the horizon reaches them (event_causal.py)
        causal = None if ctx.clock.lookahead else ForcedInstants(c, ctx.clock)
        end: int | None = None
        if causal is None:
            end = int(ctx.trajectory.duration_ns)
            info_times = sample_times_ns(c.rate, end)
            gt_times = (
                sample_times_ns(gt_rate, end)
                if (c.optic_flow or c.depthmap)
                else np.zeros(0, np.int64)
            )
            # the ends of the DSEC flow maps' intervals are rendered too (their depth)
            flow_ends = (
                flow_end_times(gt_times, c.flow_interval_ns, end)
                if c.optic_flow
                else np.zeros(0, np.int64)
            )
            truth_times = np.union1d(gt_times, flow_ends)
            forced = np.union1d(info_times, truth_times)
            sampler = AdaptiveSampler(
                c.sampling, c.adaptive_lambda, c.min_rate, c.max_rate, end, forced
            )
        else:
            sampler = causal.cover(0)
            info_times, gt_times = causal.info, causal.gt
        self._open_files(ctx, end)
        # dataset files are written beside the rendering, in order (io/background.py)
        self._sink = BackgroundSink(f"{c.name}-files")
        # ESIM, packets, messages and file writes of an instant do not feed back into the
        # next render (but for brightness sampling, which reads ESIM's state): they run
        # on a helper thread, in order, beside the next render (docs/performance.md)
        pipelined = self.pipelined and c.sampling != "brightness" and causal is None
        post = AfterRender(self, ctx, info_times, gt_times, gt_rate, pipelined=pipelined)
        stage = None
        if pipelined:
            stage = self._stage = BackgroundSink(f"{c.name}-esim", backlog=_STAGE_BACKLOG)
        n_frames = n_capped = 0
        t = 0
        farm: ChainFarm | None = None
        instants: Iterator[Instant | Message]
        if causal is not None:
            causal.listeners.append(post.follow)
            post.follow(causal)
            instants = causal_instants(self, ctx, causal, post.gen, post.floor)
        elif c.sampling == "brightness":  # the next instant reads ESIM's state
            instants = brightness_instants(self, ctx, sampler, set(truth_times.tolist()), post.gen)
        else:  # independent chains, rendered here and by render helper processes
            helpers = ctx.render_helpers(c.name)
            farm = ChainFarm(self, ctx, sampler, truth_times, helpers, render_here=self.render_here)
            self._farm = farm
            instants = farm.instants()
        for inst in instants:
            if isinstance(inst, Message):
                yield from post.take()
                yield inst  # wait for the horizon
                continue
            t = inst.t
            n_frames += 1
            n_capped += inst.capped
            if stage is None:
                post.step(t, inst.lum, inst.depth, inst.flow, inst.ids)
            else:
                stage.submit(post.step, t, inst.lum, inst.depth, inst.flow, inst.ids)
            yield from post.take()
        if farm is not None:
            self._farm = None
            farm.close()  # the helpers exit (and any failure to is an error)
        if stage is not None:
            self._stage = None
            stage.close()  # the instants still queued, and any error of one
        post.finish(t)
        yield from post.take()
        self.stats.update(
            frames=n_frames,
            events=post.n_events,
            dropped=post.gen.n_dropped,
            capped=n_capped + self.stats.get("capped", 0),
            duration_s=(t if end is None else end) * 1e-9,
        )

    def _open_files(self, ctx: SimContext, end_ns: int | None) -> None:
        """Open the dataset files: events, APS listing, ground truth (none in a run
        that records no files)."""
        c, W, H = self.config, self.camera.width, self.camera.height
        prefix = self._folder = self._prefix(ctx)
        if ctx.files is None:
            self._flow_file = self._depth_file = None
            self.flow_truth = None
            return
        stem = "events" if not prefix else f"{prefix}events"
        if c.write_txt:
            self._writers.append(EventTextWriter(ctx.path(f"{stem}.txt")))
        if c.write_h5:
            self._writers.append(
                EventH5Writer(
                    ctx.path(f"{stem}.h5"),
                    W,
                    H,
                    t_offset_ns=ctx.start_time_ns,
                    exact_ns=c.sub_microsecond_times,
                )
            )
        if c.has_aps:
            self._images_fh = ctx.path(f"{prefix}images.txt").open(
                "w", encoding="utf-8", newline="\n"
            )
        self._truth_writers(ctx, prefix, end_ns)

    def _truth_writers(self, ctx: SimContext, prefix: str, end_ns: int | None) -> None:
        """Open the ground-truth file writers this camera's config asks for."""
        c, cam = self.config, self.camera
        self._flow_file = self._depth_file = None
        self.flow_truth = None
        if c.optic_flow:
            flow_dir = ctx.path(f"{prefix}flow/forward_timestamps.txt").parent
            self._flow_file = FlowPngWriter(flow_dir, ctx.start_time_ns)
            self._truth.append(self._flow_file)
            traj, T_body_cam = ctx.trajectory, self.T_body_cam

            def pose(t_ns: int) -> F64:
                return camera_twist(traj, t_ns, T_body_cam)[0]

            self.flow_truth = FlowTruth(
                cam.model,
                cam.rays,
                pose,
                self._flow_file,
                c.flow_interval_ns,
                end_ns,
                sky_valid=c.flow_sky == "valid",
                scene=ctx.scene,
            )
        if c.depthmap:
            path = ctx.path(f"{prefix}depth.h5")
            self._depth_file = DepthH5Writer(path, cam.width, cam.height, ctx.start_time_ns)
            self._truth.append(self._depth_file)

    def _truth_msgs(
        self,
        ctx: SimContext,
        t: int,
        flow: F32 | None,
        depth: F32 | None,
        gt_times: NDArray[np.int64],
        gt_rate: float,
    ) -> list[Message]:
        """The optic-flow / depth messages of ground-truth instant ``t``; the depth file
        is written by the background sink (the DSEC flow maps: :attr:`flow_truth`)."""
        c, sink, out = self.config, self._sink, []
        assert sink is not None
        if c.optic_flow and flow is not None:
            out.append(self._image_msg(ctx, t, flow, "32FC2"))
        if c.depthmap and depth is not None:
            d = np.where(np.isfinite(depth), depth, np.float32(np.nan)).astype(np.float32)
            out.append(self._image_msg(ctx, t, d, "32FC1"))
            if self._depth_file is not None:
                sink.submit(self._depth_file.write, t, d)
        return out

    # -------------------------------------------------------------- messages
    def _camera_info_msg(self, ctx: SimContext, t_ns: int) -> Message:
        model, frame, stamp = self.camera.model, self.optical_frame, ctx.stamp(t_ns)

        def build(store: MessageStore) -> Any:
            return model.camera_info(store, frame, stamp)

        return Message(
            t_ns, f"{self.config.topic}/camera_info", "sensor_msgs/msg/CameraInfo", build
        )

    def _image_msg(self, ctx: SimContext, t_ns: int, data: NDArray[Any], encoding: str) -> Message:
        topic = {
            "mono8": "image_raw",
            "rgb8": "event_image",
            "32FC2": "optic_flow",
            "32FC1": "depthmap",
        }[encoding]
        frame, stamp = self.optical_frame, ctx.stamp(t_ns)

        def build(store: MessageStore) -> bytes:
            return store.image(frame, stamp, data, encoding)

        return Message(t_ns, f"{self.config.topic}/{topic}", "sensor_msgs/msg/Image", build)

    def _write_events(self, batch: EventBatch, labels: NDArray[np.uint32] | None = None) -> None:
        for wr in self._writers:
            if labels is not None and isinstance(wr, EventH5Writer):
                wr.write(batch, labels)
            else:
                wr.write(batch)

    def _write_image(self, ctx: SimContext, t_ns: int, aps: NDArray[np.uint8], index: int) -> None:
        rel = f"images/{index:08d}.png"
        write_png(ctx.path(f"{self._folder}{rel}"), aps)
        assert self._images_fh is not None
        s, ns = divmod(int(t_ns), 1_000_000_000)
        self._images_fh.write(f"{s}.{ns:09d} {rel}\n")

    def close(self, ctx: SimContext) -> None:
        if self._sink is not None:
            sink, self._sink = self._sink, None
            sink.close()  # the last writes, and any error of one
        for wr in self._writers:
            wr.close()
        self._writers = []
        for tw in self._truth:
            tw.close()
        self._truth = []
        if self._images_fh is not None and not self._images_fh.closed:
            self._images_fh.close()
