"""Frame and stereo cameras rendered with the shared OpenGL rasterizer.

Every frame: the closed-form trajectory gives the body pose at the stamp (or, with an
exposure or a rolling shutter, at ``exposure_samples`` render instants spread over the
shutter window, every row then integrating its own exposure window from the nearest
render along the exact per-pixel motion: motion blur and rolling shutter,
:mod:`.row_exposure`);
``T_world_optical = T_world_body @ T_body_sensor @ T_sensor_optical``; the renderer
draws a pinhole view (larger than the image when the lens distorts: see
:meth:`CameraModel.render_plan`) that ``cv2.remap`` turns into the distorted image.
Linear radiance -> gain -> shot (Poisson) and read (Gaussian) noise -> gamma/sRGB
encoding -> 8 bits.

Topics (``<topic>`` = the sensor's topic): ``<topic>/image_raw`` (sensor_msgs/Image)
and ``<topic>/camera_info`` (sensor_msgs/CameraInfo), frame ``<frame>_optical``.
Stereo: ``<topic>/left/...`` and ``<topic>/right/...`` in ``<frame>_left_optical`` /
``<frame>_right_optical``; the right camera sits ``baseline`` metres along the left
camera's optical x axis (its CameraInfo ``P[0, 3] = -fx * baseline``, ROS convention).

Image stamps are the middle of the shutter window (the middle row's exposure; global
shutter: the middle of the exposure). With ``exposure_time`` > 0 each frame's exposure
is written to ``exposures.txt`` next to ``images.txt``.

Dataset files:

* Event Camera Dataset layout: the OUTDIR root holds one camera's ``images.txt``
  (``t images/NNNNNNNN.png``), ``images/`` and ``calib.txt`` - the first event camera's
  when there is one, else the first camera's (stereo: the left eye;
  ``ctx.root_camera``); every other camera (each stereo eye: ``<name>_left``,
  ``<name>_right``) writes the same files in ``<name>/``;
* the run's calibration files (``calib/<name>.yaml``, ``calib/camchain.yaml``,
  ``calib.txt``): :func:`roslan.rundir.calibration.write_calibration`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, ValidationInfo, field_validator, model_validator

from roslan.config.base import FiniteFloat
from roslan.errors import SensorError
from roslan.io.ordered import Turn
from roslan.io.text import format_seconds
from roslan.render import REC709_LUMA, FrameRenderer
from roslan.sensors.base import LabelsKey, Message, SensorConfig, SimContext
from roslan.sensors.cameras.calibration import CalibCamera, load_calibration
from roslan.sensors.cameras.common import RAW_ROWS_FACTOR, CameraBase, Eye, Shot, pose_matrices
from roslan.sensors.cameras.config import CameraIntrinsics, intrinsics_model
from roslan.sensors.cameras.encoding import encode_image, srgb_lut
from roslan.sensors.cameras.model import T_LINK_OPTICAL, CameraModel
from roslan.sensors.cameras.remap import remap_view
from roslan.sensors.cameras.row_exposure import render_row_frame
from roslan.sensors.cameras.shutter import (
    AutoExposure,
    AutoExposureLoop,
    RollingShutterKeys,
    ShutterPlan,
    auto_exposure_sequence,
    band_extents,
    compose_bands,
    meter_level,
    meter_view,
    render_bands,
    shutter_plan,
)

__all__ = [
    "Camera",
    "CameraBase",
    "CameraConfig",
    "Eye",
    "StereoCamera",
    "StereoCameraConfig",
    "pose_matrices",
]

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]

Positive = Annotated[FiniteFloat, Field(gt=0)]
NonNegative = Annotated[FiniteFloat, Field(ge=0)]


# --------------------------------------------------------------------- configs
class _ImagingConfig(SensorConfig, LabelsKey, CameraIntrinsics, RollingShutterKeys):
    """Keys shared by the colour cameras."""

    encoding: Literal["mono8", "rgb8", "bgr8"] = "rgb8"
    exposure_time: NonNegative = 0.0
    """Exposure (s); > 0 blurs: every row integrates its own exposure window along the
    exact motion (:mod:`.row_exposure`). With ``auto_exposure``: the initial exposure, and
    the one at which ``gain`` maps the radiance 1:1 (an exposure ``E`` scales the image by
    ``E / exposure_time``)."""
    exposure_samples: Annotated[int, Field(ge=1, le=64)] = 8
    """Renders per frame, spread over the shutter window (exposure plus readout); every
    row is formed from the one nearest its window's middle, warped along each pixel's
    motion (more renders: shorter warps, fewer disocclusions; the accuracy knob). A
    global shutter takes one render, at the stamp."""
    auto_exposure: AutoExposure | None = None
    """Auto-exposure (:class:`~roslan.sensors.cameras.shutter.AutoExposure`); each
    frame's exposure is written to ``exposures.txt`` next to ``images.txt``."""
    gain: NonNegative = 1.0
    """Multiplies the linear radiance before noise and encoding."""
    gamma: Literal["srgb"] | Positive = "srgb"
    """``srgb`` (the sRGB transfer curve) or a power ``v = linear ** (1 / gamma)``; 1 = linear."""
    noise_std: NonNegative = 0.0
    """Gaussian read noise, standard deviation in linear units (full scale = 1)."""
    full_well: Positive | None = None
    """Photo-electrons at full scale; set to add Poisson shot noise."""
    write_images: bool = True
    """Write the PNG files and their index (``images.txt``)."""
    render_scale: Annotated[FiniteFloat, Field(gt=0.0, le=2.0)] | None = None
    """Distorted lenses: focal length of the virtual pinhole render relative to the
    camera's (1 = the image centre's sampling density everywhere: sharpest, 1.59x the
    pixels of a 640x480 k1 = -0.2 lens); None = as many render pixels as output pixels
    (:meth:`CameraModel.render_plan`). Ignored for pinhole cameras."""

    @model_validator(mode="after")
    def _shutter(self) -> _ImagingConfig:
        self._check_readout(self.rate)
        ae = self.auto_exposure
        if ae is not None:
            if self.exposure_time <= 0:
                msg = (
                    f"exposure_time = {self.exposure_time}: auto_exposure needs an initial "
                    "exposure > 0 (s), the one at which gain maps the radiance 1:1"
                )
                raise ValueError(msg)
            if ae.max_exposure > 1.0 / self.rate:
                msg = (
                    f"auto_exposure.max_exposure = {ae.max_exposure}: must not exceed the "
                    f"frame period 1 / rate = {1.0 / self.rate:.6g} s"
                )
                raise ValueError(msg)
        return self

    def max_exposure(self) -> float:
        """The longest exposure a frame may get (s)."""
        ae = self.auto_exposure
        return self.exposure_time if ae is None else ae.max_exposure

    @field_validator("exposure_time")
    @classmethod
    def _within_frame(cls, v: float, info: ValidationInfo) -> float:
        rate = info.data.get("rate")
        if isinstance(rate, float | int) and rate > 0 and v > 1.0 / rate:
            period = 1.0 / rate
            msg = (
                f"longer than the frame period 1 / rate = {period:.6g} s (rate {rate:g} Hz); "
                f"allowed: 0 to {period:.6g} s (seconds: 5 ms is 0.005)"
            )
            raise ValueError(msg)
        return v


class CameraConfig(_ImagingConfig):
    """``type: camera``: a frame camera (mono8/rgb8/bgr8)."""

    type: Literal["camera"] = "camera"


class StereoCameraConfig(_ImagingConfig):
    """``type: stereo_camera``: two identical, rectified (parallel) cameras.

    ``calibration`` / inline keys describe the left camera; the right one uses
    ``calibration_right`` if given, else ``cam1`` of the same file when it is a Kalibr
    camchain with two cameras, else the left intrinsics. The right camera sits
    ``baseline`` m along the left optical x axis.
    """

    type: Literal["stereo_camera"] = "stereo_camera"
    baseline: Positive = 0.12
    calibration_right: Path | None = None

    @model_validator(mode="after")
    def _right(self) -> StereoCameraConfig:
        if self.calibration_right is not None and not self.calibration_right.is_absolute():
            base = self.calibration.parent if self.calibration is not None else None
            if base is not None and (base / self.calibration_right).exists():
                object.__setattr__(self, "calibration_right", base / self.calibration_right)
        return self

    def right_model(self) -> CameraModel:
        name = f"{self.name}_right"
        if self.calibration_right is not None:
            return load_calibration(self.calibration_right, name=name)
        if self.calibration is not None and self.calibration_camera is None:
            try:
                return load_calibration(self.calibration, camera="cam1", name=name)
            except SensorError:
                pass
        return intrinsics_model(self, name=name, source=self._source())

    def calibration_cameras(self) -> list[CalibCamera]:
        try:
            left = self.camera_model()
            right = self.right_model()
        except SensorError as err:
            raise ValueError(str(err)) from None
        left = _renamed(left, f"{self.name}_left")
        T_left = self.T_base_optical()
        T_lr = np.eye(4)
        T_lr[0, 3] = self.baseline
        topic = self.topic
        return [
            CalibCamera(f"{self.name}_left", left, T_left, f"{topic}/left/image_raw"),
            CalibCamera(
                f"{self.name}_right",
                right,
                T_left @ T_lr,
                f"{topic}/right/image_raw",
                -right.fx * self.baseline,
            ),
        ]


def _renamed(m: CameraModel, name: str) -> CameraModel:
    return CameraModel(m.width, m.height, m.K, m.D, m.distortion_model, name, m.source)


_LUMA = np.asarray(REC709_LUMA, dtype=np.float32)  # Rec. 709, linear


class _ImagingCamera(CameraBase):
    """Colour/mono camera pipeline (frame and stereo cameras)."""

    config: _ImagingConfig

    def _init_imaging(self) -> None:
        self._lut = srgb_lut(self.config.gamma)

    def render_linear(
        self,
        renderer: FrameRenderer,
        e: Eye,
        T_world_body: F64,
        shutter: ShutterPlan | None = None,
    ) -> F32:
        """Linear radiance of eye ``e`` averaged over the body poses (N, 4, 4): (H, W, 3),
        or (H, W) Rec. 709 luminance for ``mono8`` (the renderer's one-channel path).
        With a rolling ``shutter`` (N renders at its instants), each row averages the
        poses with its own weights, rendering only the rows each pose serves.

        The array is one of ``e``'s work buffers: valid (and modifiable) until the next
        call for ``e``."""
        return self.render_raw(renderer, e, T_world_body, shutter, inline=True)()

    def render_raw(
        self,
        renderer: FrameRenderer,
        e: Eye,
        T_world_body: F64,
        shutter: ShutterPlan | None = None,
        *,
        inline: bool,
    ) -> Callable[[], F32]:
        """:meth:`render_linear` in two steps: the renders, now (this thread: the GL
        context's), and the rest (lens remap, rolling-shutter composition) as a call for
        any thread, returning the work buffer of the thread that calls it. ``inline``:
        the call comes next, on this thread (which may then hand over its own buffers and
        draw the rolling-shutter bands lazily, one in memory at a time)."""
        p = e.plan
        assert p is not None
        c = self.config
        mono = c.encoding == "mono8"
        if shutter is not None and not shutter.global_shutter:
            T_opt = T_world_body @ self._T_body_sensor @ e.T_sensor_optical
            out_shape = (e.model.height, e.model.width, *(() if mono else (3,)))
            bands = render_bands(renderer, p, T_opt, shutter, mono, c.near_clip, c.supersampling)
            if not inline:
                rows = sum(b - a for *_, a, b in band_extents(p, shutter))
                if rows > RAW_ROWS_FACTOR * p.height:  # composed here, band by band
                    lin = compose_bands(p, shutter, bands, np.empty(out_shape, np.float32), mono)
                    return lambda: lin
                bands = iter(list(bands))  # drawn now
            return lambda: compose_bands(p, shutter, bands, e.buffer("rolling", out_shape), mono)
        shape = (p.height, p.width) if mono else (p.height, p.width, 3)
        acc: F32 | None = e.buffer("render", shape) if inline else None  # else a fresh one
        for i, T_wb in enumerate(T_world_body):
            T = T_wb @ self._T_body_sensor @ e.T_sensor_optical
            res = renderer.render(
                T,
                p.K,
                p.width,
                p.height,
                color=not mono,
                depth=False,
                luminance=mono,
                out=acc if i == 0 else e.buffer("sub", shape),
                near=c.near_clip,
                supersampling=c.supersampling,
                t=None if shutter is None else float(shutter.instants_ns[i]) * 1e-9,
            )
            img = res.luminance if mono else res.color
            assert img is not None
            if i == 0:
                acc = img
            else:
                assert acc is not None
                acc += img
        assert acc is not None
        view: F32 = acc
        if len(T_world_body) > 1:
            view *= np.float32(1.0 / len(T_world_body))
        if p.identity:
            return lambda: view
        return lambda: self._remap(e, view)

    def _remap(self, e: Eye, acc: F32) -> F32:
        """The virtual pinhole view ``acc`` through the lens maps, into a work buffer."""
        p = e.plan
        assert p is not None
        # straight from the readback buffer into a reused output (no copies)
        out = e.buffer("remap", (e.model.height, e.model.width, *acc.shape[2:]))
        remap_view(p, acc, dst=out)
        return out

    def finish_image(self, lin: F32, rng: np.random.Generator, exposure: float | None = None) -> U8:
        """Gain, noise and encoding of a linear image (H, W, 3) or luminance (H, W) ->
        uint8 (H, W[, 3]). With auto-exposure, ``exposure`` (s) scales the radiance by
        ``exposure / exposure_time``."""
        lin, gain = self.add_noise(lin, rng, exposure)
        return self.encode(lin, gain)

    @property
    def noisy(self) -> bool:
        """Whether frames draw from the random generator (shot or read noise)."""
        return self.config.full_well is not None or self.config.noise_std > 0

    def add_noise(
        self, lin: F32, rng: np.random.Generator, exposure: float | None = None
    ) -> tuple[F32, float]:
        """The first half of :meth:`finish_image`: the linear image with its noise drawn
        (``lin`` may be modified) and the gain still to apply."""
        c = self.config
        if c.encoding == "mono8" and lin.ndim == 3:
            lin = lin @ _LUMA
        gain = c.gain
        if exposure is not None and c.auto_exposure is not None:
            gain *= exposure / c.exposure_time
        if self.noisy and gain != 1.0:
            lin *= np.float32(gain)  # before the noise
            gain = 1.0
        if c.full_well is not None:
            fw = float(c.full_well)
            lin = (rng.poisson(np.clip(lin, 0.0, None) * fw) / fw).astype(np.float32)
        if c.noise_std > 0:
            lin += rng.normal(0.0, c.noise_std, size=lin.shape).astype(np.float32)
        return lin, gain

    def encode(self, lin: F32, gain: float) -> U8:
        """The second half of :meth:`finish_image`: gain (noise-free), clip, sRGB/gamma
        codes and bgr order in one pass."""
        return encode_image(lin, self._lut, gain=gain, reverse=self.config.encoding == "bgr8")

    def exposures(self, ctx: SimContext, stamps: NDArray[np.int64]) -> F64:
        """Exposure (s) of each frame: ``exposure_time``, or the auto-exposure sequence
        fixed up front by a metering pass (:mod:`.shutter`): the first eye's linear
        luminance at each stamp over the central part of its view
        (:func:`~.shutter.meter_view`)."""
        c = self.config
        ae = c.auto_exposure
        if ae is None or stamps.size == 0:
            return np.full(stamps.size, c.exposure_time)
        renderer = ctx.renderer()
        e = self._eyes[0]
        K, w, h = meter_view(e.model.K, e.model.width, e.model.height)
        T_opt = pose_matrices(ctx, stamps) @ self._T_body_sensor @ e.T_sensor_optical
        scale = c.gain / c.exposure_time

        def meter(k: int, exposure: float) -> float:
            res = renderer.render(
                T_opt[k],
                K,
                w,
                h,
                color=False,
                depth=False,
                luminance=True,
                near=c.near_clip,
                t=float(stamps[k]) * 1e-9,
            )
            assert res.luminance is not None
            return meter_level(res.luminance, scale * exposure)

        return auto_exposure_sequence(meter, int(stamps.size), c.exposure_time, ae, c.rate)

    def _exposure_source(self, ctx: SimContext) -> Callable[[int, int], float]:
        """``exposure(i, t)`` of frame ``i`` stamped ``t``, asked in frame order: the
        metering pass over every stamp up front when the whole trajectory is known
        (:meth:`exposures`), else the same loop frame by frame, each frame metered at its
        own stamp (causal)."""
        c, clock = self.config, ctx.clock
        ae = c.auto_exposure
        if ae is None:
            return lambda i, t: float(c.exposure_time)
        if clock.lookahead and clock.end_ns is not None:
            table = self.exposures(ctx, self._stamps(clock.end_ns))
            return lambda i, t: float(table[i])
        renderer = ctx.renderer()
        e = self._eyes[0]
        K, w, h = meter_view(e.model.K, e.model.width, e.model.height)
        scale = c.gain / c.exposure_time
        loop = AutoExposureLoop(c.exposure_time, ae, c.rate)

        def exposure(i: int, t: int) -> float:
            now = loop.exposure
            T_opt = pose_matrices(ctx, np.array([t])) @ self._T_body_sensor @ e.T_sensor_optical
            res = renderer.render(
                T_opt[0],
                K,
                w,
                h,
                color=False,
                depth=False,
                luminance=True,
                near=c.near_clip,
                t=t * 1e-9,
            )
            assert res.luminance is not None
            loop.update(meter_level(res.luminance, scale * now))
            return now

        return exposure

    def eye_poses(
        self, ctx: SimContext, e: Eye, t_ns: int, exposure: float
    ) -> tuple[ShutterPlan, F64]:
        """The shutter plan of eye ``e``'s frame stamped ``t_ns`` and the body poses
        (N, 4, 4) at its render instants."""
        c = self.config
        plan = shutter_plan(t_ns, exposure, c.readout_time, c.exposure_samples, e.model.height)
        return plan, pose_matrices(ctx, plan.instants_ns)

    def frame_linear(
        self, ctx: SimContext, renderer: FrameRenderer, e: Eye, t_ns: int, exposure: float
    ) -> F32:
        """Linear radiance of eye ``e``'s frame stamped ``t_ns`` at ``exposure`` (s): (H, W,
        3), or (H, W) luminance for ``mono8``; a work buffer of ``e`` (valid until the next
        call for ``e``)."""
        return self.frame_raw(ctx, renderer, e, t_ns, exposure, inline=True)()

    def frame_raw(
        self,
        ctx: SimContext,
        renderer: FrameRenderer,
        e: Eye,
        t_ns: int,
        exposure: float,
        *,
        inline: bool,
    ) -> Callable[[], F32]:
        """:meth:`frame_linear` in two steps: the renders now (this thread), the rest as a
        call for any thread. Without exposure and readout: one render at the stamp
        (:meth:`render_raw`); else every row integrates its own exposure window from the
        ``exposure_samples`` renders (:mod:`.row_exposure`)."""
        c = self.config
        if exposure <= 0.0 and c.readout_time <= 0.0:
            plan, T_wb = self.eye_poses(ctx, e, t_ns, exposure)
            return self.render_raw(renderer, e, T_wb, plan, inline=inline)
        mono = c.encoding == "mono8"
        shot = self._row_shot(ctx, e, t_ns, exposure, c.readout_time, c.exposure_samples)
        compose = render_row_frame(renderer, shot, mono, c.near_clip, c.supersampling)
        shape = (e.model.height, e.model.width, *(() if mono else (3,)))
        return lambda: compose(e.buffer("rows", shape))

    def messages(self, ctx: SimContext) -> Iterator[Message]:
        """Every eye's frames: renders on this thread, the rest on the sensor's pool
        (:meth:`CameraBase._frames`); noise drawn eye after eye, frame after frame."""
        c = self.config
        rng = ctx.rng(f"{c.type}/{c.name}")
        renderer = self._plans(ctx)
        grid = self._grid(ctx)
        exposure_of = self._exposure_source(ctx)
        writes = c.write_images and ctx.files is not None  # (None: a run recording nothing)
        if writes:
            for e in self._eyes:
                self._open_index(ctx, e, "image")

        def render(inline: bool, i: int, t: int) -> tuple[float, list[Callable[[], F32]]]:
            exposure = exposure_of(i, t)
            for e in self._eyes:
                if e.exposure_fh is not None:
                    e.exposure_fh.write(f"{format_seconds(np.array([t]))[0]} {exposure:.9f}\n")
            composes = []
            for e in self._eyes:
                composes.append(self.frame_raw(ctx, renderer, e, t, exposure, inline=inline))
            return exposure, composes

        def post(
            turn: Turn, i: int, t: int, job: tuple[float, list[Callable[[], F32]]]
        ) -> list[Shot]:
            exposure, composes = job
            lins = [compose() for compose in composes]
            if self.noisy:
                with turn:  # the draws in frame order, whatever the threads
                    noisy = [self.add_noise(lin, rng, exposure) for lin in lins]
            else:
                noisy = [self.add_noise(lin, rng, exposure) for lin in lins]
            shots = []
            for e, (lin, gain) in zip(self._eyes, noisy, strict=True):
                img = self.encode(lin, gain)
                if writes:
                    self._png(ctx, e, i, img)
                shots.append(Shot(e, img, c.encoding, writes))
            return shots

        yield from self._frames(ctx, grid, render, post)


class Camera(_ImagingCamera):
    """``type: camera``."""

    def __init__(self, config: CameraConfig) -> None:
        self.config = config
        model = config.camera_model()
        c = config
        self._setup_eyes([Eye("", model, T_LINK_OPTICAL.copy(), c.topic, f"{c.frame}_optical")])
        self._init_imaging()


class StereoCamera(_ImagingCamera):
    """``type: stereo_camera``: left and right images of the same instant."""

    def __init__(self, config: StereoCameraConfig) -> None:
        self.config = config
        cams = config.calibration_cameras()
        c = config
        T_lr = np.eye(4)
        T_lr[0, 3] = c.baseline
        self._setup_eyes(
            [
                Eye(
                    "left",
                    cams[0].model,
                    T_LINK_OPTICAL.copy(),
                    f"{c.topic}/left",
                    f"{c.frame}_left_optical",
                ),
                Eye(
                    "right",
                    cams[1].model,
                    T_LINK_OPTICAL @ T_lr,
                    f"{c.topic}/right",
                    f"{c.frame}_right_optical",
                    cams[1].Tx,
                ),
            ]
        )
        self._init_imaging()
