"""DSEC optical-flow ground truth: the true displacement of every pixel's scene point.

A flow map from ``t0`` to ``t1 = t0 + flow_interval`` (DSEC, Gehrig et al. 2021: the
pixel displacement from ``from_timestamp_us`` to ``to_timestamp_us``) is built from what
the event camera renders anyway:

1. every output pixel ``(u, v)`` (integer coordinates at pixel centres, the pixel
   coordinates of ``events.h5``'s ``x, y``: *distorted*, raw sensor pixels) is
   back-projected along its ray through the lens model with the depth at ``t0``
   (z along the optical axis; a distorted camera's ground-truth depth is ray cast along
   each output ray, :func:`depth_on_rays`): a 3-D point, fixed in the world;
2. the point is moved into the camera at ``t1`` (the ground-truth poses at ``t0`` and
   ``t1`` and the camera's mount, exactly what ``groundtruth.txt`` and
   ``calib/extrinsics.yaml`` hold) and projected through the same lens model,
   distortion included: ``flow = p1 - (u, v)``.

So touchdown, the hold and flapping inside an interval come out right by construction
(the interval's end points are all that matters, as in DSEC).

A pixel is **invalid** (DSEC's ``valid = 0``) where

* its point is behind the camera at ``t1`` or leaves the image (``p1`` outside
  ``[-0.5, W - 0.5) x [-0.5, H - 0.5)``);
* its point is **occluded** at ``t1``: it lies more than :data:`OCCLUSION_TOLERANCE`
  (relative) behind every one of the surfaces the camera sees at ``t1`` on the 3x3 pixels
  around ``p1``'s nearest pixel (the depth test against the ``t1`` depth; nothing hit
  counts as infinitely far). Comparing with the farthest of the nine keeps a surface
  seen at a grazing angle visible (where one pixel spans metres of floor); the price is
  that a point hidden by about a pixel or less behind an occluding edge counts as
  visible (its flow is still its true displacement);
* the displacement is outside the PNG's range (``-256 <= flow < 256`` px);
* nothing is hit at ``t0`` (sky) with ``flow_sky: invalid`` (the default, as DSEC marks
  pixels without ground truth). With ``flow_sky: valid`` the flow of such a pixel is that
  of the point at infinity in its direction (the rotation alone), invalid where the
  camera sees a surface at ``t1`` on all nine pixels around ``p1``.

:class:`FlowTruth` makes the maps causally: at a ground-truth instant ``t0`` it keeps
the depth and the pose, and it writes the map when the run reaches ``t1`` (a forced
render instant of the event camera, so its depth is rendered exactly there). Memory: the
maps whose interval is open, ``flow_interval * ground_truth_rate + 1`` depth images at most.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import NDArray

from roslan.sensors.cameras.scene_motion import require_ids

if TYPE_CHECKING:
    from roslan.render.base import BeamCaster
    from roslan.scene.model import Scene
    from roslan.sensors.cameras.event_truth import FlowPngWriter
    from roslan.sensors.cameras.model import CameraModel

__all__ = [
    "OCCLUSION_TOLERANCE",
    "FlowTruth",
    "depth_on_rays",
    "displacement_flow",
    "flow_end_times",
]

OCCLUSION_TOLERANCE = 0.02
"""A point is occluded at ``t1`` where its depth exceeds the depth seen there by more than
this fraction (2 %)."""

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]


def flow_end_times(gt_times: NDArray[np.int64], interval_ns: int, end_ns: int) -> NDArray[np.int64]:
    """``t0 + interval`` of every ground-truth instant ``t0`` whose interval ends inside the
    run (``<= end_ns``): the instants the event camera must render for its flow maps."""
    t1 = np.asarray(gt_times, np.int64) + np.int64(interval_ns)
    out: NDArray[np.int64] = t1[t1 <= end_ns]
    return out


def depth_on_rays(
    caster: BeamCaster, T_world_cam: F64, rays: tuple[F64, F64], *, t: float | None = None
) -> F32:
    """z-depth (m, optical axis; ``inf``: nothing hit) of the scene along each output
    pixel's own ray, ray cast (Embree: the triangles the rasterizer draws).

    A distorted camera renders a virtual pinhole view and remaps it; a remapped depth is
    that of a neighbouring ray, up to half a virtual pixel off, which puts the
    back-projected points beside the surfaces where the depth varies fast (a floor seen
    at a grazing angle, edges). The ground truth casts the output pixels' rays instead.

    Args:
        caster: the scene's ray caster.
        T_world_cam: (4, 4) pose of the optical frame.
        rays: (H, W) normalized pinhole ``x``, ``y`` of each output pixel's ray.
        t: trajectory time (s) of the view: the scene is cast as it is then.
    """
    x, y = rays
    T = np.asarray(T_world_cam, np.float64)
    # direction (x, y, 1) in the camera, in the world: the distance along it is z
    d = np.stack([T[k, 0] * x.ravel() + T[k, 1] * y.ravel() + T[k, 2] for k in range(3)], 1)
    o = np.broadcast_to(T[:3, 3], d.shape)
    hits = caster.cast(o, d, t=t)
    out: F32 = np.asarray(hits.distance, np.float32).reshape(x.shape)
    return out


def _farthest(inv: F64) -> F64:
    """The smallest inverse depth (the farthest surface; 0: nothing hit) of the 3x3 pixels
    around each pixel (a min filter, edges replicated)."""
    import cv2

    out = cv2.erode(inv, np.ones((3, 3), np.uint8), borderType=cv2.BORDER_REPLICATE)
    return np.asarray(out, np.float64)


class _Rays(NamedTuple):
    x: F64
    """(H, W) normalized pinhole x of each output pixel's ray (lens undone)."""
    y: F64
    x_range: tuple[float, float]
    """Bounds of the rays' x: a point outside them cannot be in the image (whatever a
    distortion polynomial does far outside its field of view)."""
    y_range: tuple[float, float]


def _rays(x: F64, y: F64) -> _Rays:
    pad_x = float(np.max(np.abs(np.diff(x, axis=1)))) if x.shape[1] > 1 else 1.0
    pad_y = float(np.max(np.abs(np.diff(y, axis=0)))) if y.shape[0] > 1 else 1.0
    return _Rays(
        x,
        y,
        (float(x.min()) - pad_x, float(x.max()) + pad_x),
        (float(y.min()) - pad_y, float(y.max()) + pad_y),
    )


def displacement_flow(
    model: CameraModel,
    rays: tuple[F64, F64] | _Rays,
    depth0: NDArray[np.floating],
    depth1: NDArray[np.floating],
    T_c1_c0: F64,
    *,
    sky_valid: bool = False,
    carry: Callable[[F64, NDArray[np.intp]], F64] | None = None,
) -> F64:
    """The flow map of the module docstring.

    Args:
        model: the lens model (pixels of the output image).
        rays: (H, W) normalized pinhole ``x``, ``y`` of each output pixel's ray.
        depth0, depth1: (H, W) z-depth (m, optical axis) at ``t0`` and ``t1``; not finite
            or <= 0: nothing hit.
        T_c1_c0: (4, 4) pose of the optical frame at ``t0`` in the one at ``t1``.
        sky_valid: ``flow_sky: valid`` (flow of the points at infinity where nothing is hit).
        carry: the scene's own motion, or None (a static scene: the points stay where they
            are): ``carry(P0, pixels)`` gives where the surface points ``P0`` (N, 3, the
            camera frame at ``t0``) seen at flat pixel indices ``pixels`` (N,) are at
            ``t1``, in the same frame (:meth:`FlowTruth._carry`).
    Returns:
        (H, W, 2) float64 displacement ``p1 - p0``, px; NaN where invalid (the range of
        the PNG is checked by the encoder).
    """
    r = rays if isinstance(rays, _Rays) else _rays(rays[0], rays[1])
    d0 = np.asarray(depth0, np.float64)
    H, W = d0.shape
    hit = np.isfinite(d0) & (d0 > 0)
    idx = np.flatnonzero((hit | sky_valid).ravel())
    z0 = np.where(hit, d0, 1.0).ravel()[idx]
    w = hit.ravel()[idx].astype(np.float64)  # homogeneous weight: 0 = point at infinity
    p0 = (r.x.ravel()[idx] * z0, r.y.ravel()[idx] * z0, z0)
    if carry is not None:  # surface points that move with their objects
        P = np.stack(p0, axis=1)
        on = w > 0
        P[on] = carry(P[on], idx[on])
        p0 = (P[:, 0], P[:, 1], P[:, 2])
    T = np.asarray(T_c1_c0, np.float64)
    # P1 = R P0 + w t, written out per axis (a BLAS product of an (N, 3) array is slow
    # when the BLAS threads compete for the CPUs)
    x1, y1, z1 = (
        p0[0] * T[k, 0] + p0[1] * T[k, 1] + p0[2] * T[k, 2] + w * T[k, 3] for k in range(3)
    )
    with np.errstate(divide="ignore", invalid="ignore"):
        xn, yn = x1 / z1, y1 / z1
    ok = (
        (z1 > 0)
        & (xn >= r.x_range[0])
        & (xn <= r.x_range[1])
        & (yn >= r.y_range[0])
        & (yn <= r.y_range[1])
    )
    p1 = np.full((idx.size, 2), np.nan)
    p1[ok] = model.project(np.stack([x1[ok], y1[ok], z1[ok]], axis=1))
    u1, v1 = p1[:, 0], p1[:, 1]
    with np.errstate(invalid="ignore"):
        ok &= (u1 >= -0.5) & (u1 < W - 0.5) & (v1 >= -0.5) & (v1 < H - 0.5)
    d1 = np.asarray(depth1, np.float64)
    with np.errstate(divide="ignore"):
        inv1 = np.where(np.isfinite(d1) & (d1 > 0), 1.0 / d1, 0.0)
    sel = np.flatnonzero(ok)
    # the farthest surface on the 3x3 pixels around p1's nearest pixel
    i1 = np.clip(np.rint(u1[sel]).astype(np.intp), 0, W - 1)
    j1 = np.clip(np.rint(v1[sel]).astype(np.intp), 0, H - 1)
    inv_far = _farthest(inv1)[j1, i1]
    # behind all nine surfaces around p1 (a point at infinity: behind any surface)
    occluded = np.where(w[sel] > 0, z1[sel] * inv_far > 1.0 + OCCLUSION_TOLERANCE, inv_far > 0)
    ok[sel[occluded]] = False
    out = np.full((H * W, 2), np.nan)
    good = idx[ok]
    out[good, 0] = u1[ok] - (good % W)
    out[good, 1] = v1[ok] - (good // W)
    return out.reshape(H, W, 2)


class _Open(NamedTuple):
    """A flow map whose interval is open: its start, depth and camera pose there."""

    t0: int
    t1: int
    depth0: F32
    T_w_c0: F64
    ids0: NDArray[np.integer] | None = None
    """The object each pixel sees at ``t0`` (needed only in a scene whose objects move)."""


class FlowTruth:
    """The event camera's flow maps, made as the run reaches the end of each interval.

    Args:
        model: the lens model; rays: its output pixels' rays (:func:`displacement_flow`).
        pose: ``t_ns -> T_world_cam`` (4, 4) of the optical frame.
        writer: the PNG / timestamps writer.
        interval_ns: ``flow_interval``; end_ns: the run's last instant (None: not known
            yet, closed loop: every map starts, and those the run ends before are dropped).
        sky_valid: ``flow_sky: valid``.
    """

    def __init__(
        self,
        model: CameraModel,
        rays: tuple[F64, F64],
        pose: Callable[[int], F64],
        writer: FlowPngWriter,
        interval_ns: int,
        end_ns: int | None,
        *,
        sky_valid: bool,
        scene: Scene | None = None,
    ) -> None:
        self.model = model
        self.rays = _rays(*rays)
        self.pose = pose
        self.writer = writer
        self.interval_ns = int(interval_ns)
        self.end_ns = end_ns
        self.sky_valid = sky_valid
        self.scene = scene
        """The scene whose own motion the maps follow (None or static: a static world)."""
        self.open: deque[_Open] = deque()

    def step(
        self,
        t: int,
        depth: NDArray[np.floating] | None,
        *,
        start: bool,
        submit: Callable[..., object],
        ids: NDArray[np.integer] | None = None,
    ) -> None:
        """Instant ``t`` (in time order) with its depth (None: not a ground-truth or
        interval-end instant) and the object each pixel sees (``ids``; only a scene whose
        objects move needs them). ``start``: a map may start at ``t`` (a ground-truth
        instant after the first event). Finished maps go to ``submit(fn, *args)`` (the
        camera's file writer thread)."""
        if depth is None:
            return
        T_w_c = None
        while self.open and self.open[0].t1 <= t:
            m = self.open.popleft()
            if m.t1 < t:  # (cannot happen: every end is a forced render instant)
                msg = f"flow map from {m.t0} ns: its end {m.t1} ns was not rendered"
                raise RuntimeError(msg)
            if T_w_c is None:
                T_w_c = self.pose(t)
            submit(self._write, m, np.array(depth, np.float32, copy=True), T_w_c)
        if start and (self.end_ns is None or t + self.interval_ns <= self.end_ns):
            T0 = self.pose(t) if T_w_c is None else T_w_c
            d0 = np.array(depth, np.float32, copy=True)
            self.open.append(_Open(t, t + self.interval_ns, d0, T0, ids))

    def _carry(self, m: _Open) -> Callable[[F64, NDArray[np.intp]], F64] | None:
        """The scene's own motion over map ``m``'s interval (:func:`displacement_flow`'s
        ``carry``): None for a static scene."""
        if self.scene is None or self.scene.is_static:
            return None
        view = self.scene.at(m.t0 * 1e-9)
        ids = np.asarray(require_ids(view, m.ids0, "the DSEC flow maps")).ravel()
        R, c = m.T_w_c0[:3, :3], m.T_w_c0[:3, 3]
        t1 = m.t1 * 1e-9

        def carry(P0: F64, pixels: NDArray[np.intp]) -> F64:
            moved = view.carry(P0 @ R.T + c, ids[pixels], t1)
            out: F64 = (moved - c) @ R
            return out

        return carry

    def _write(self, m: _Open, depth1: F32, T_w_c1: F64) -> None:
        T_c1_c0 = np.linalg.inv(T_w_c1) @ m.T_w_c0
        disp = displacement_flow(
            self.model,
            self.rays,
            m.depth0,
            depth1,
            T_c1_c0,
            sky_valid=self.sky_valid,
            carry=self._carry(m),
        )
        self.writer.write(m.t0, m.t1, disp)
