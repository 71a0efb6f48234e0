"""Every row's own exposure window, exact for the known motion.

A frame with exposure ``E`` and readout ``R`` on an ``H``-row sensor exposes row ``r``
over ``[t_r, t_r + E]``, ``t_r = t_start + r * R / H`` (:mod:`.shutter`). Rendering the
scene at enough instants to cover every row's window costs a render per instant; instead
the frame takes ``exposure_samples`` renders (colour or luminance, and depth; at
:data:`RENDER_SAMPLES` MSAA samples per pixel) spread evenly over the middles of the
rows' windows (``t_r + E / 2``; a global shutter: one, at the stamp) and forms every row
from them by the exact per-pixel motion:

* row ``r`` is the mean of ``N_r`` sub-samples at ``t_rj = t_r + (j + 1/2) E / N_r`` (the
  midpoint rule over its own window; ``E = 0``: one, at ``t_r``), ``N_r`` chosen so that
  consecutive sub-samples of any pixel lie at most :data:`ROW_STEP_PX` apart in the image
  (the box blur of the render's piecewise-linear bilinear image, within the midpoint
  rule's error at the pixel lines it crosses), at most :data:`MAX_SUBSAMPLES`;
* sub-sample ``t`` of output pixel ``p`` (its ray ``d``, through the lens, in the optical
  frame at ``t``) is read from the row's render, the one nearest in time to the middle of
  its window (pose ``T_k``; rows are banded between the renders as the readout goes): with
  ``(R, c) = T_k^-1 T(t)`` (the closed-form trajectory's poses, not a linearized twist),
  the surface point is ``R d lambda + c`` in the render's frame, its depth ``lambda`` in
  the camera at ``t`` from the render's depth at the point's own pixel (two fixed-point
  steps from the rotation-only pixel): rotation is exact whatever the depth, and
  translation exact on every surface but within a pixel or two of a depth edge
  (disocclusions: the nearer-in-time render's pixel);
* the pixel value is the render's bilinear sample there.

Each render is a band of the virtual view that holds the rows its sub-samples reach
(rotation-only extent plus :data:`PARALLAX_MARGIN` rows for the translation; beyond it the
band's edge row is read). The image stamp is unchanged: the middle of the middle row's
exposure.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from roslan.events.jit import kernel
from roslan.render import FrameRenderer
from roslan.sensors.cameras.model import RenderPlan
from roslan.sensors.cameras.shutter import ShutterPlan, band_rows, shutter_plan

__all__ = [
    "MAX_SUBSAMPLES",
    "PARALLAX_MARGIN",
    "RENDER_SAMPLES",
    "ROW_STEP_PX",
    "RowFrame",
    "RowShot",
    "band_K",
    "band_layout",
    "output_rays",
    "plan_row_frame",
    "relative_poses",
    "render_row_frame",
]

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

ROW_STEP_PX = 0.25
"""Largest image distance (px) between consecutive sub-samples of a pixel's motion. The
midpoint rule over a row's window sums bilinear samples of the render; the bilinear image
is piecewise linear with a kink at every pixel line the path crosses, and each kink's
sub-interval leaves a residual of fine detail that a finer step shrinks. Measured
(bench_shutter_accuracy.py, untuned landing, 15 frames, band 120-179: the floor's texture
at a grazing angle, most of its energy near the Nyquist frequency): gradient energy
against the 64-render reference 1.096x at 1 px, 1.053x at 0.5 px, 1.036x at 0.25 px."""
MAX_SUBSAMPLES = 64
"""Most sub-samples of one row's exposure window."""
PARALLAX_MARGIN = 8
"""Band rows added above and below the rotation-only extent of a render's sub-samples."""
RENDER_SAMPLES = 4
"""MSAA samples per pixel of the renders the rows are formed from (``supersampling`` > 1
ignores them). A geometric edge moving across the image during the exposure is
anti-aliased along its motion (the many renders of a reference average its one-sample
staircase over sub-pixel positions); a warp of one 1-sample render keeps the staircase
(measured, docs/guide/cameras.md: 75-90 % of the squared error against a 64-render
reference within 2 px of geometric edges), a warp of a 4x MSAA render does not."""
_COLS = 16  # column step of the extent and motion-length estimates


def output_rays(plan: RenderPlan, width: int, height: int) -> tuple[F32, F32]:
    """``(x, y)`` (H, W) of every output pixel's ray ``(x, y, 1)`` in the optical frame:
    the virtual pinhole's coordinates of the pixel through the lens maps (exact inverse
    of the distortion; pinhole: the pixel itself) over ``K``."""
    if plan.identity:
        u, v = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    else:
        u, v = plan.mapx.astype(np.float64), plan.mapy.astype(np.float64)
    K = plan.K
    y = (v - K[1, 2]) / K[1, 1]
    x = (u - K[0, 2] - K[0, 1] * y) / K[0, 0]
    return x.astype(np.float32), y.astype(np.float32)


@numba.njit(inline="always")
def _rot(P, e, x, y):  # type: ignore[no-untyped-def]
    """``R d`` of the ray ``d = (x, y, 1)`` for instant ``e`` (``P[e]``: ``R`` row-major,
    then ``c``: the camera at that instant in the render's frame)."""
    return (
        P[e, 0] * x + P[e, 1] * y + P[e, 2],
        P[e, 3] * x + P[e, 4] * y + P[e, 5],
        P[e, 6] * x + P[e, 7] * y + P[e, 8],
    )


@numba.njit(inline="always")
def _depth(x, y, P, e, zs, b0, h, W, fx, s, cx, fy, cy):  # type: ignore[no-untyped-def]
    """The render's depth (``zs[b0:b0 + h]``: z in its frame) at the rotation-only pixel of
    the ray ``(x, y, 1)`` at instant ``e`` (``cy`` relative to the band)."""
    ax, ay, az = _rot(P, e, x, y)
    if az <= 1e-9:
        return np.inf
    iz = 1.0 / az
    iu = min(max(int((fx * ax + s * ay) * iz + cx + 0.5), 0), W - 1)
    iv = min(max(int(fy * ay * iz + cy + 0.5), 0), h - 1)
    return zs[b0 + iv, iu]


@numba.njit(inline="always")
def _point(x, y, P, e, z, fx, s, fy):  # type: ignore[no-untyped-def]
    """``(nx, ny, D)``: the band pixel ``(nx / D + cx, ny / D + cy)`` of the ray
    ``(x, y, 1)`` at instant ``e`` that meets the surface at the render's depth ``z``: the
    point ``R d lambda + c``, ``lambda`` (its depth at ``e``) from
    ``z = (R d lambda + c)_z``; multiplied through by ``z - c_z`` (one division later)."""
    ax, ay, az = _rot(P, e, x, y)
    den = z - P[e, 11]
    if z < np.inf and den > 1e-9:
        bx = ax * den + P[e, 9] * az
        by = ay * den + P[e, 10] * az
        return fx * bx + s * by, fy * by, az * z
    return fx * ax + s * ay, fy * ay, az


@kernel
def _integrate(  # type: ignore[no-untyped-def]  # pragma: no cover - numba
    imgs, zs, base, a0, hgt, Kv, rx, ry, R, c, ks, step, nmax, out
):
    """``out[r, u]`` (``C`` = 1 or 3 channels): the mean of the render's bilinear samples
    at ``n`` points evenly spread in time over row ``r``'s window (midpoint rule), ``n`` =
    1 + the pixel's motion length over ``step``, at most ``nmax``. The points: the
    quadratic through the exact points (:func:`_point`) of the window's start, middle and
    end (``R[3r:3r + 3]``) on the surface seen at the middle's point (two fixed-point
    steps from its rotation-only pixel, :func:`_depth`); one point, the start, where
    ``nmax`` is 1."""
    H, Wo, C = out.shape
    W = imgs.shape[1]  # the render's width (the virtual view's, not the output's)
    three = nmax > 1
    fx, s, cx, fy = Kv[0], Kv[1], Kv[2], Kv[3]
    P = np.empty((3, 12))
    for r in range(H):
        k = ks[r]
        b0, h = base[k], hgt[k]
        cy = Kv[4] - a0[k]
        hmax = h - 1.0
        for e in range(3 if three else 1):
            m = 3 * r + e
            for i in range(3):
                for j in range(3):
                    P[e, 3 * i + j] = R[m, i, j]
                P[e, 9 + i] = c[m, i]
        for u in range(Wo):
            out[r, u] = 0.0
            x, y = np.float64(rx[r, u]), np.float64(ry[r, u])
            em = 1 if three else 0
            z = _depth(x, y, P, em, zs, b0, h, W, fx, s, cx, fy, cy)
            if z < np.inf:  # a second fixed-point step: the depth at the point's own pixel
                nx, ny, dm = _point(x, y, P, em, z, fx, s, fy)
                if dm > 1e-9:
                    iu = min(max(int(nx / dm + cx + 0.5), 0), W - 1)
                    iv = min(max(int(ny / dm + cy + 0.5), 0), h - 1)
                    z = zs[b0 + iv, iu]
            n0x, n0y, d0 = _point(x, y, P, 0, z, fx, s, fy)
            if three:
                n1x, n1y, d1 = _point(x, y, P, 1, z, fx, s, fy)
                n2x, n2y, d2 = _point(x, y, P, 2, z, fx, s, fy)
                if d0 <= 1e-9 or d1 <= 1e-9 or d2 <= 1e-9:
                    continue
                inv = 1.0 / (d0 * d1 * d2)  # one division for the three
                i0, i1, i2 = d1 * d2 * inv, d0 * d2 * inv, d0 * d1 * inv
                q0x, q0y = n0x * i0 + cx, n0y * i0 + cy
                q1x, q1y = n1x * i1 + cx, n1y * i1 + cy
                q2x, q2y = n2x * i2 + cx, n2y * i2 + cy
                ux, uy, vx, vy = q1x - q0x, q1y - q0y, q2x - q1x, q2y - q1y
                length = math.sqrt(ux * ux + uy * uy) + math.sqrt(vx * vx + vy * vy)
                n = min(int(length / step) + 1, nmax)  # 1 + floor: at most step apart
            else:
                if d0 <= 1e-9:
                    continue
                q0x, q0y = n0x / d0 + cx, n0y / d0 + cy
                q1x, q1y, q2x, q2y = q0x, q0y, q0x, q0y
                n = 1
            # Lagrange quadratic through s = 0, 1/2, 1: q(s) = q0 + s (b + s a)
            bx = -3.0 * q0x + 4.0 * q1x - q2x
            by = -3.0 * q0y + 4.0 * q1y - q2y
            ax = 2.0 * q0x - 4.0 * q1x + 2.0 * q2x
            ay = 2.0 * q0y - 4.0 * q1y + 2.0 * q2y
            w = 1.0 / n
            acc0 = acc1 = acc2 = 0.0
            for j in range(n):
                sj = (j + 0.5) * w if three else 0.0
                px = min(max(q0x + sj * (bx + sj * ax), 0.0), W - 1.0)
                py = min(max(q0y + sj * (by + sj * ay), 0.0), hmax)
                x0 = min(int(px), W - 2)
                y0 = min(int(py), h - 2)
                fu = px - x0
                fv = py - y0
                i0 = b0 + y0
                t = imgs[i0, x0, 0] + fu * (imgs[i0, x0 + 1, 0] - imgs[i0, x0, 0])
                b = imgs[i0 + 1, x0, 0] + fu * (imgs[i0 + 1, x0 + 1, 0] - imgs[i0 + 1, x0, 0])
                acc0 += t + fv * (b - t)
                if C == 3:
                    t = imgs[i0, x0, 1] + fu * (imgs[i0, x0 + 1, 1] - imgs[i0, x0, 1])
                    b = imgs[i0 + 1, x0, 1] + fu * (imgs[i0 + 1, x0 + 1, 1] - imgs[i0 + 1, x0, 1])
                    acc1 += t + fv * (b - t)
                    t = imgs[i0, x0, 2] + fu * (imgs[i0, x0 + 1, 2] - imgs[i0, x0, 2])
                    b = imgs[i0 + 1, x0, 2] + fu * (imgs[i0 + 1, x0 + 1, 2] - imgs[i0 + 1, x0, 2])
                    acc2 += t + fv * (b - t)
            out[r, u, 0] = acc0 * w
            if C == 3:
                out[r, u, 1] = acc1 * w
                out[r, u, 2] = acc2 * w


@dataclass(frozen=True)
class RowFrame:
    """The renders of one frame for :func:`render_row_frame` and where they lie.

    Attributes:
        shutter: the frame's :class:`~.shutter.ShutterPlan` (render instants).
        row_start_ns: (H,) float start of every row's exposure window (ns).
        exposure_ns: the exposure ``E`` (ns).
        bands: ``(k, a, b)`` of every render drawn: rows ``[a, b)`` of the virtual view.
        serve: (H,) the render of every row: the one nearest its window's middle.
    """

    shutter: ShutterPlan
    row_start_ns: F64
    exposure_ns: float
    bands: list[tuple[int, int, int]]
    serve: I64


def relative_poses(T_ref: F64, T: F64) -> tuple[F64, F64]:
    """``(R, c)`` of poses ``T`` (N, 4, 4) in the frames ``T_ref`` (N, 4, 4)."""
    Rr = np.transpose(T_ref[:, :3, :3], (0, 2, 1))
    R = Rr @ T[:, :3, :3]
    c = np.einsum("nij,nj->ni", Rr, T[:, :3, 3] - T_ref[:, :3, 3])
    return np.ascontiguousarray(R), np.ascontiguousarray(c)


def _nearest(shutter: ShutterPlan, t_ns: F64) -> I64:
    """Index of the render nearest in time to each of ``t_ns``."""
    tau = shutter.instants_ns.astype(np.float64)
    mids = 0.5 * (tau[1:] + tau[:-1])
    return np.searchsorted(mids, t_ns).astype(np.int64)


@dataclass(frozen=True)
class RowShot:
    """What one frame's row formation is asked for.

    Attributes:
        plan: the eye's virtual view (:class:`~.model.RenderPlan`).
        rays: ``(x, y)`` (H, W) of every output pixel's ray (:func:`output_rays`).
        poses: ``t_ns -> (N, 4, 4)`` optical poses at (N,) int64 instants.
        stamp_ns: the frame's stamp.
        exposure: ``E`` (s; 0: every row at one instant).
        readout: ``R`` (s; 0: a global shutter).
        samples: renders over the rows' window middles.
    """

    plan: RenderPlan
    rays: tuple[F32, F32]
    poses: Callable[[I64], F64]
    stamp_ns: int
    exposure: float
    readout: float
    samples: int


def plan_row_frame(shot: RowShot) -> tuple[RowFrame, F64]:
    """The frame's renders, and their optical poses (n, 4, 4): ``samples`` instants
    spread evenly over the middles of the rows' windows (the readout; a global shutter:
    one, at the stamp), every row served by the nearest; band ``k`` holds the rows that
    the rotation-only points of its rows' windows reach, with :data:`PARALLAX_MARGIN`
    rows more on each side."""
    plan, rays, poses = shot.plan, shot.rays, shot.poses
    stamp_ns, exposure, readout, samples = shot.stamp_ns, shot.exposure, shot.readout, shot.samples
    H, W = rays[0].shape
    # the renders: spread over the rows' window middles (a global shutter: one, the stamp)
    sp = shutter_plan(stamp_ns, 0.0, readout, samples, H)
    span_ns = (readout * (H - 1) / H + exposure) * 1e9
    t_r = (stamp_ns - 0.5 * span_ns) + np.arange(H, dtype=np.float64) * (readout * 1e9 / H)
    e_ns = exposure * 1e9
    T_k = poses(sp.instants_ns)
    n = sp.instants_ns.size
    serve = _nearest(sp, t_r + 0.5 * e_ns)  # every row from the render nearest its middle
    rows = np.unique(np.concatenate([np.arange(0, H, 8), [H - 1]]))
    cols = np.unique(np.concatenate([np.arange(0, W, _COLS), [W - 1]]))
    x = rays[0][np.ix_(rows, cols)].astype(np.float64)
    y = rays[1][np.ix_(rows, cols)].astype(np.float64)
    d = np.stack([x, y, np.ones_like(x)], axis=-1)  # (rows, cols, 3)
    bands = []
    for k in range(n):
        mine = np.flatnonzero(serve == k)
        if mine.size == 0:
            continue
        use = np.isin(rows, mine)
        if not use.any():  # a band narrower than the row subset: its own first and last rows
            rows_k = np.array([mine[0], mine[-1]])
            dk = np.stack([rays[0][rows_k][:, cols], rays[1][rows_k][:, cols]], axis=-1)
            dk = np.concatenate([dk.astype(np.float64), np.ones((2, cols.size, 1))], axis=-1)
        else:
            rows_k = rows[use]
            dk = d[use]
        lo, hi = t_r[rows_k], t_r[rows_k] + e_ns
        T = poses(np.round(np.concatenate([lo, hi])).astype(np.int64))
        Rk, _ = relative_poses(np.broadcast_to(T_k[k], T.shape), T)
        dd = np.concatenate([dk, dk])  # (2 rows, cols, 3)
        a = np.einsum("nij,ncj->nci", Rk, dd)
        az = np.where(a[..., 2] > 1e-9, a[..., 2], np.nan)
        py = plan.K[1, 1] * a[..., 1] / az + plan.K[1, 2]
        ylo, yhi = np.nanmin(py), np.nanmax(py)
        ylo = max(ylo - PARALLAX_MARGIN, 0.0)
        yhi = min(yhi + PARALLAX_MARGIN, plan.height - 1.0)
        if not (np.isfinite(ylo) and np.isfinite(yhi) and yhi >= ylo):  # the whole view
            ylo, yhi = 0.0, plan.height - 1.0
        ra, rb = band_rows(ylo, yhi, plan.height)
        bands.append((k, ra, rb))
    return RowFrame(sp, t_r, e_ns, bands, serve), T_k


def band_layout(rf: RowFrame) -> tuple[int, I64, I64, I64]:
    """Where the bands of ``rf`` lie when stacked in one array, in render order: the rows
    in all, and per render ``k`` its first stacked row, its first row of the virtual view
    and its height (0 for a render that serves no row)."""
    n = rf.shutter.instants_ns.size
    base = np.zeros(n, np.int64)
    a0 = np.zeros(n, np.int64)
    hgt = np.zeros(n, np.int64)
    row = 0
    for k, a, b in rf.bands:
        base[k], a0[k], hgt[k] = row, a, b - a
        row += b - a
    return row, base, a0, hgt


def band_K(plan: RenderPlan, first_row: int) -> F64:
    """The virtual view's ``K`` for a band that starts at ``first_row``."""
    K = plan.K.copy()
    K[1, 2] -= first_row
    return K


def render_row_frame(
    renderer: FrameRenderer, shot: RowShot, mono: bool, near: float, supersampling: int = 1
) -> Callable[[F32], F32]:
    """The frame ``shot``: its renders now (this thread; each of the scene at its own
    instant), and a call that forms every row from them into an output array ((H, W)
    luminance or (H, W, 3) linear RGB) on any thread."""
    plan, rays, poses = shot.plan, shot.rays, shot.poses
    H, W = rays[0].shape
    rf, T_k = plan_row_frame(shot)
    C = 1 if mono else 3
    total, base, a0, hgt = band_layout(rf)
    imgs = np.empty((total, plan.width, C), np.float32)
    zs = np.empty((total, plan.width), np.float32)
    for k, a, b in rf.bands:
        row, h = int(base[k]), b - a
        dst = imgs[row : row + h]
        res = renderer.render(
            T_k[k],
            band_K(plan, a),
            plan.width,
            h,
            color=not mono,
            depth=True,
            luminance=mono,
            samples=RENDER_SAMPLES,
            out=dst[..., 0]
            if mono and supersampling == 1
            else (dst if supersampling == 1 else None),
            near=near,
            supersampling=supersampling,
            t=float(rf.shutter.instants_ns[k]) * 1e-9,
        )
        img = res.luminance if mono else res.color
        assert img is not None
        assert res.depth is not None
        if supersampling != 1:
            dst[...] = img.reshape(dst.shape)
        zs[row : row + h] = res.depth
    Kv = np.array([plan.K[0, 0], plan.K[0, 1], plan.K[0, 2], plan.K[1, 1], plan.K[1, 2]])
    t_r, e_ns = rf.row_start_ns, rf.exposure_ns
    # the exact poses of every row's window start, middle and end in its render's frame
    t = (t_r[:, None] + np.array([0.0, 0.5, 1.0])[None, :] * e_ns).reshape(-1)
    R, c = relative_poses(T_k[np.repeat(rf.serve, 3)], poses(np.round(t).astype(np.int64)))
    nmax = MAX_SUBSAMPLES if e_ns > 0.0 else 1

    def compose(out: F32) -> F32:
        view = out.reshape(H, W, C)
        _integrate(
            imgs, zs, base, a0, hgt, Kv, rays[0], rays[1], R, c, rf.serve, _step(), nmax, view
        )
        return out

    return compose


def _step() -> float:
    return ROW_STEP_PX
