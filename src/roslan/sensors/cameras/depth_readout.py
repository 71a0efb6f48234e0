"""A rolling-shutter depth frame, every row at its own instant (the depth camera's readout).

Row ``r`` of an ``H``-row depth camera with readout ``R`` is read at
``t_r = t_start + r * R / H`` (:mod:`.shutter`; the stamp is the middle row's instant).
The frame takes ``readout_samples`` depth renders spread over the readout
(:func:`~.row_exposure.plan_row_frame` with no exposure: every row served by the render
nearest its instant, each render a band of the virtual view) and forms every output pixel
from its row's render along the exact motion, as :mod:`.row_exposure` forms a frame
camera's rows:

* the output pixel's ray ``d = (x, y, 1)`` (through the lens, :func:`~.row_exposure.output_rays`)
  at ``t_r``, in the render's frame with ``(R, c) = T_k^-1 T(t_r)`` (the closed-form
  poses), meets the surface at ``R d lambda + c``; the render's depth ``z`` there gives
  ``lambda = (z - c_z) / (R d)_z``, the z-depth at ``t_r``;
* ``z`` is read at the point's own pixel of the render (three fixed-point steps from the
  rotation-only pixel ``R d``): rotation is exact whatever the depth, translation exact on
  every surface but within a pixel or two of a depth edge (a disocclusion: the surface
  the render saw there);
* **no smeared edges.** Inverse depth is affine in the image on a plane, so the render's
  ``1 / z`` is read bilinearly where its four taps are affine (a plane's depth at a
  sub-pixel point, exactly) and from the nearest tap where they are not (silhouettes,
  creases, nothing hit: :func:`~.depth._non_affine`'s test): every output depth is that of
  a surface the render saw, never a blend of a near and a far one (no "flying pixels"),
  and the depth itself is moved (``lambda`` from ``z``), not only resampled.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from roslan.events.jit import kernel
from roslan.render import FrameRenderer
from roslan.sensors.cameras.row_exposure import (
    RowShot,
    band_K,
    band_layout,
    plan_row_frame,
    relative_poses,
)

__all__ = ["FIXED_POINT_STEPS", "render_depth_rows"]

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]

FIXED_POINT_STEPS = 3
"""Steps from the rotation-only pixel to the depth at the surface point's own pixel."""


@kernel
def _inverse_at(inv, flag, b0, h, W, px, py):  # type: ignore[no-untyped-def]  # pragma: no cover - numba
    """The render's inverse depth (``inv[b0:b0 + h]``; 0: nothing hit) at band pixel
    ``(px, py)``: bilinear where the four taps are affine (``flag`` 0), else the nearest."""
    px = min(max(px, 0.0), W - 1.0)
    py = min(max(py, 0.0), h - 1.0)
    x0 = max(min(int(px), W - 2), 0)
    y0 = max(min(int(py), h - 2), 0)
    x1 = min(x0 + 1, W - 1)
    y1 = min(y0 + 1, h - 1)
    fu = px - x0
    fv = py - y0
    i0, i1 = b0 + y0, b0 + y1
    if flag[i0, x0] + flag[i0, x1] + flag[i1, x0] + flag[i1, x1] > 0.0:
        return inv[i1 if fv >= 0.5 else i0, x1 if fu >= 0.5 else x0]
    t = inv[i0, x0] + fu * (inv[i0, x1] - inv[i0, x0])
    b = inv[i1, x0] + fu * (inv[i1, x1] - inv[i1, x0])
    return t + fv * (b - t)


@kernel
def _depth_rows(inv, flag, base, a0, hgt, Kv, rx, ry, R, c, ks, steps, out):  # type: ignore[no-untyped-def]  # pragma: no cover - numba
    """``out[r, u]``: the z-depth at row ``r``'s instant along output pixel ``(r, u)``'s
    ray (``R[r], c[r]``: the camera then in its render's frame; ``inf``: nothing hit)."""
    H, W = out.shape
    Wr = inv.shape[1]  # the render's width (the virtual view's, not the output's)
    fx, s, fy = Kv[0], Kv[1], Kv[3]
    for r in range(H):
        k = ks[r]
        b0, h = base[k], hgt[k]
        cx, cy = Kv[2], Kv[4] - a0[k]
        R00, R01, R02 = R[r, 0, 0], R[r, 0, 1], R[r, 0, 2]
        R10, R11, R12 = R[r, 1, 0], R[r, 1, 1], R[r, 1, 2]
        R20, R21, R22 = R[r, 2, 0], R[r, 2, 1], R[r, 2, 2]
        c0, c1, c2 = c[r, 0], c[r, 1], c[r, 2]
        for u in range(W):
            x, y = np.float64(rx[r, u]), np.float64(ry[r, u])
            ax = R00 * x + R01 * y + R02
            ay = R10 * x + R11 * y + R12
            az = R20 * x + R21 * y + R22
            out[r, u] = np.inf
            if az <= 1e-9:
                continue
            iz = _inverse_at(inv, flag, b0, h, Wr, (fx * ax + s * ay) / az + cx, fy * ay / az + cy)
            for _ in range(steps):  # the depth at the surface point's own pixel
                if iz <= 0.0:
                    break
                lam = (1.0 / iz - c2) / az
                if lam <= 1e-9:
                    break
                X, Y, Z = ax * lam + c0, ay * lam + c1, az * lam + c2
                iz = _inverse_at(inv, flag, b0, h, Wr, (fx * X + s * Y) / Z + cx, fy * Y / Z + cy)
            if iz > 0.0:
                lam = (1.0 / iz - c2) / az
                if lam > 1e-9:
                    out[r, u] = lam


def render_depth_rows(
    renderer: FrameRenderer,
    shot: RowShot,
    near: float,
    flags: Callable[[F32], F32],
    supersampling: int = 1,
) -> Callable[[F32], F32]:
    """The rolling-shutter depth frame ``shot`` (``exposure`` 0): its depth renders now
    (this thread; each of the scene at its own instant), and a call that forms every row
    from them into an (H, W) float32 z-depth array (``inf``: nothing hit) on any thread.
    ``flags(inv)``: 1.0 where inverse depth ``inv`` is not affine around a pixel."""
    plan, rays = shot.plan, shot.rays
    rf, T_k = plan_row_frame(shot)
    total, base, a0, hgt = band_layout(rf)
    inv = np.empty((total, plan.width), np.float32)
    for k, a, b in rf.bands:
        z = renderer.render(
            T_k[k],
            band_K(plan, a),
            plan.width,
            b - a,
            color=False,
            depth=True,
            near=near,
            supersampling=supersampling,
            t=float(rf.shutter.instants_ns[k]) * 1e-9,
        ).depth
        assert z is not None
        with np.errstate(divide="ignore"):
            np.reciprocal(z, out=inv[int(base[k]) : int(base[k]) + b - a])
    Kv = np.array([plan.K[0, 0], plan.K[0, 1], plan.K[0, 2], plan.K[1, 1], plan.K[1, 2]])
    R, c = relative_poses(T_k[rf.serve], shot.poses(np.round(rf.row_start_ns).astype(np.int64)))

    def compose(out: F32) -> F32:
        flag = np.empty_like(inv)
        for k, _a, _b in rf.bands:  # (each band's own test: its edge rows are its own)
            sl = slice(int(base[k]), int(base[k] + hgt[k]))
            flag[sl] = flags(inv[sl])
        _depth_rows(
            inv, flag, base, a0, hgt, Kv, rays[0], rays[1], R, c, rf.serve, FIXED_POINT_STEPS, out
        )
        return out

    return compose
