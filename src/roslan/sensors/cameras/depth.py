"""Depth camera: 32FC1 z-depth in metres rendered with the shared OpenGL rasterizer.

Dataset files: ``depth/<name>/NNNNNNNN.png`` (16-bit, millimetres, 0 = no return) and
``depth_<name>.txt``; ``calib/<name>.yaml`` (ROS camera_info).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Annotated, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, model_validator

from roslan.config.base import FiniteFloat
from roslan.io.ordered import Turn
from roslan.render import FrameRenderer
from roslan.sensors.base import LabelsKey, Message, SensorConfig, SimContext
from roslan.sensors.cameras.common import (
    CameraBase,
    Eye,
    Shot,
    pose_matrices,
)
from roslan.sensors.cameras.config import CameraIntrinsics
from roslan.sensors.cameras.depth_readout import render_depth_rows
from roslan.sensors.cameras.model import T_LINK_OPTICAL
from roslan.sensors.cameras.remap import remap_view
from roslan.sensors.cameras.shutter import RollingShutterKeys, shutter_plan

__all__ = ["DepthCamera", "DepthCameraConfig"]

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]

Positive = Annotated[FiniteFloat, Field(gt=0)]
NonNegative = Annotated[FiniteFloat, Field(ge=0)]


class DepthCameraConfig(SensorConfig, LabelsKey, CameraIntrinsics, RollingShutterKeys):
    """``type: depth_camera``: 32FC1 z-depth in metres, NaN where nothing is measured (REP 118).

    With ``readout_time`` > 0 (a rolling shutter) every row is read at its own instant:
    ``readout_samples`` renders spread over the readout, each row formed from the one
    nearest its instant, moved along the exact motion to that instant
    (:mod:`~roslan.sensors.cameras.depth_readout`)."""

    type: Literal["depth_camera"] = "depth_camera"
    min_range: NonNegative = 0.0
    """Closer returns are NaN (m)."""
    max_range: Positive | None = None
    """Farther returns are NaN (m); unset: unlimited."""
    noise_std: NonNegative = 0.0
    """Gaussian depth noise, m."""
    noise_quadratic: NonNegative = 0.0
    """Extra noise standard deviation per m^2 of depth (structured-light/stereo-like)."""
    write_images: bool = True
    """Write ``depth/<name>/NNNNNNNN.png`` (16-bit mm) and ``depth_<name>.txt``."""
    readout_samples: Annotated[int, Field(ge=1, le=64)] = 8
    """Renders per frame over the rolling shutter's readout (unused without one): the
    accuracy knob of the rows' warps (parallax near depth edges shrinks with it)."""

    @model_validator(mode="after")
    def _ranges(self) -> DepthCameraConfig:
        self._check_readout(self.rate)
        if self.max_range is not None and self.max_range <= self.min_range:
            msg = f"max_range = {self.max_range}: must be greater than min_range = {self.min_range}"
            raise ValueError(msg)
        return self


def _non_affine(inv: F32, tol: float = 1e-3) -> F32:
    """1.0 where inverse depth ``inv`` (H, W; 0 = nothing hit) is not affine across a
    pixel's 4-neighbourhood: a second difference above ``tol`` times the largest of the
    five values (float32 rounding of a plane's 1/z is ~1e-7 of it), else 0.0. On the image
    border only the difference along the border is used."""
    p = np.pad(inv, 1, mode="edge")
    c = p[1:-1, 1:-1]
    w, e_, n, s_ = p[1:-1, :-2], p[1:-1, 2:], p[:-2, 1:-1], p[2:, 1:-1]
    d2x = np.abs(w + e_ - 2.0 * c)
    d2y = np.abs(n + s_ - 2.0 * c)
    # on the border the repeated edge value would turn a plane's slope into a crease
    d2x[:, [0, -1]] = 0.0
    d2y[[0, -1], :] = 0.0
    d2 = np.maximum(d2x, d2y)
    top = np.maximum(np.maximum(np.maximum(w, e_), np.maximum(n, s_)), c)
    return (d2 > tol * top).astype(np.float32)


class DepthCamera(CameraBase):
    """``type: depth_camera``: 32FC1 metres, NaN where nothing is measured (REP 118)."""

    config: DepthCameraConfig

    def __init__(self, config: DepthCameraConfig) -> None:
        self.config = config
        c = config
        self._setup_eyes(
            [Eye("", config.camera_model(), T_LINK_OPTICAL.copy(), c.topic, f"{c.frame}_optical")]
        )

    def render_depth(
        self, renderer: FrameRenderer, e: Eye, T_world_body: F64, t: float | None = None
    ) -> F32:
        """(H, W) float32 metric z-depth (inf: nothing hit) of eye ``e`` at one body pose
        (4, 4), of the scene at trajectory time ``t`` (s; None: t = 0)."""
        return self._depth_view(e, self._render_raw(renderer, e, T_world_body, t))

    def _render_raw(
        self, renderer: FrameRenderer, e: Eye, T_world_body: F64, t: float | None = None
    ) -> F32:
        """The render of :meth:`render_depth` (a fresh array of the virtual view)."""
        assert e.plan is not None
        T = T_world_body @ self._T_body_sensor @ e.T_sensor_optical
        z = renderer.render(
            T,
            e.plan.K,
            e.plan.width,
            e.plan.height,
            color=False,
            depth=True,
            near=self.config.near_clip,
            supersampling=self.config.supersampling,
            t=t,
        ).depth
        assert z is not None
        return z

    def _depth_view(self, e: Eye, z: F32) -> F32:
        """The rest of :meth:`render_depth` (any thread): the render ``z`` through the lens."""
        assert e.plan is not None
        if e.plan.identity:
            return np.asarray(z, dtype=np.float32)
        # Inverse depth is affine in the image on a plane, so bilinear interpolation of 1/z
        # is exact there. Where it is not affine (silhouettes against other surfaces or
        # nothing, creases, strong curvature) a blend would be a depth no surface has (a
        # "flying pixel"): output pixels with such a render pixel among their bilinear
        # taps take the nearest render pixel's depth instead.
        with np.errstate(divide="ignore"):
            inv = np.reciprocal(z)
        flag = remap_view(e.plan, _non_affine(inv))
        lin = remap_view(e.plan, inv)
        near = remap_view(e.plan, inv, nearest=True, exact=True)
        edge = flag > 0.0
        lin[edge] = near[edge]
        with np.errstate(divide="ignore"):
            out: F32 = np.reciprocal(lin)
        return out

    def rolling_depth(self, ctx: SimContext, renderer: FrameRenderer, e: Eye, t_ns: int) -> F32:
        """The depth frame stamped ``t_ns``: one render at the stamp (global shutter),
        else every row at its own instant, from the render nearest it warped along the
        exact motion (:mod:`.depth_readout`)."""
        return self.depth_raw(ctx, renderer, e, t_ns, inline=True)()

    def depth_raw(
        self, ctx: SimContext, renderer: FrameRenderer, e: Eye, t_ns: int, *, inline: bool
    ) -> Callable[[], F32]:
        """:meth:`rolling_depth` in two steps: the renders now (this thread), the rest as a
        call for any thread (``inline``: all of it now)."""
        c = self.config
        plan = shutter_plan(t_ns, 0.0, c.readout_time, c.readout_samples, e.model.height)
        if plan.global_shutter:
            T_wb = pose_matrices(ctx, plan.instants_ns)
            z0 = self._render_raw(renderer, e, T_wb[0], float(plan.instants_ns[0]) * 1e-9)
            return lambda: self._depth_view(e, z0)
        shot = self._row_shot(ctx, e, t_ns, 0.0, c.readout_time, c.readout_samples)
        compose = render_depth_rows(renderer, shot, c.near_clip, _non_affine, c.supersampling)
        shape = (e.model.height, e.model.width)
        if inline:
            z = compose(np.empty(shape, np.float32))
            return lambda: z
        return lambda: compose(np.empty(shape, np.float32))

    def messages(self, ctx: SimContext) -> Iterator[Message]:
        """The depth frames: renders on this thread, the rest on the sensor's pool
        (:meth:`CameraBase._frames`); noise drawn frame after frame."""
        c = self.config
        rng = ctx.rng(f"depth_camera/{c.name}")
        renderer = self._plans(ctx)
        e = self._eyes[0]
        writes = c.write_images and ctx.files is not None  # (None: a run recording nothing)
        if writes:
            self._open_index(ctx, e, "depth")

        def render(inline: bool, i: int, t: int) -> Callable[[], F32]:
            return self.depth_raw(ctx, renderer, e, t, inline=inline)

        def post(turn: Turn, i: int, t: int, compose: Callable[[], F32]) -> list[Shot]:
            z = compose()
            if c.noise_std > 0 or c.noise_quadratic > 0:
                sigma = c.noise_std + c.noise_quadratic * np.where(np.isfinite(z), z, 0.0) ** 2
                with turn:  # the draws in frame order, whatever the threads
                    draw = rng.normal(0.0, 1.0, size=z.shape)
                z = (z + draw * sigma).astype(np.float32)
            bad = ~np.isfinite(z) | (z < c.min_range)
            if c.max_range is not None:
                bad |= z > c.max_range
            z[bad] = np.nan
            if writes:
                mm = np.where(bad, 0.0, np.round(np.clip(z, 0.0, 65.535) * 1000.0))
                self._png(ctx, e, i, np.nan_to_num(mm).astype(np.uint16))
            return [Shot(e, z.astype("<f4"), "32FC1", writes)]

        yield from self._frames(ctx, self._grid(ctx), render, post)
