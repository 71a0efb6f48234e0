"""Adaptive sampling of the rendered signal (ESIM) and the exact motion field.

ESIM chooses the next render instant so that no pixel changes too much in between:

* ``brightness``: ``dt = lambda / max|dL/dt|`` (log intensity per second, estimated from
  the last two samples);
* ``optical_flow``: ``dt = lambda / max|flow|`` (px/s), with the flow computed exactly
  from the rendered depth and the camera twist of the closed-form trajectory.

``dt`` is clamped to ``[1/max_rate, 1/min_rate]`` and never steps over a forced instant
(APS frames, ground-truth flow/depth) or the end of the trajectory.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import NDArray

from roslan.events.jit import kernel
from roslan.trajectory.base import Trajectory

__all__ = ["AdaptiveSampler", "camera_twist", "max_flow_speed", "motion_field", "pixel_rays"]

F64 = NDArray[np.float64]
Strategy = Literal["brightness", "optical_flow", "fixed"]


def pixel_rays(K: NDArray[np.floating], width: int, height: int) -> tuple[F64, F64]:
    """Normalised image coordinates ``x = (u - cx)/fx``, ``y = (v - cy)/fy`` of every pixel
    centre of a pinhole image, each (H, W) float64 (OpenCV convention, row 0 on top)."""
    K = np.asarray(K, dtype=np.float64)
    u = (np.arange(width, dtype=np.float64) - K[0, 2]) / K[0, 0]
    v = (np.arange(height, dtype=np.float64) - K[1, 2]) / K[1, 1]
    x, y = np.meshgrid(u, v)
    return x, y


def motion_field(
    depth: NDArray[np.floating],
    K: NDArray[np.floating],
    v_cam: NDArray[np.floating],
    w_cam: NDArray[np.floating],
    rays: tuple[F64, F64] | None = None,
) -> NDArray[np.float32]:
    """Exact image motion (Longuet-Higgins & Prazdny).

    Args:
        depth: (H, W) z-depth along the optical axis, m (``inf``: infinitely far).
        K: (3, 3) pinhole intrinsics.
        v_cam: (3,) linear velocity of the camera, m/s, in its optical frame (a static
            scene); or (H, W, 3) its velocity relative to each pixel's surface point (a
            scene whose objects move: ``sensors.cameras.scene_motion.relative_velocity``).
        w_cam: (3,) angular velocity of the camera, rad/s, in its optical frame.
        rays: optional cached :func:`pixel_rays`.
    Returns:
        (H, W, 2) float32 flow (du/dt, dv/dt) in px/s.
    """
    d = np.asarray(depth, dtype=np.float64)
    H, W = d.shape
    x, y = rays if rays is not None else pixel_rays(K, W, H)
    va = np.asarray(v_cam, dtype=np.float64)
    if va.ndim == 1:
        vx, vy, vz = (float(a) for a in va)
    else:  # per pixel
        vx, vy, vz = va[..., 0], va[..., 1], va[..., 2]  # type: ignore[assignment]
    wx, wy, wz = (float(a) for a in w_cam)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_z = np.where(np.isfinite(d) & (d > 0), 1.0 / d, 0.0)
    # a point moves in the camera frame as dP/dt = -v - w x P (v: relative to the point)
    dx = (-vx + x * vz) * inv_z + x * y * wx - (1.0 + x * x) * wy + y * wz
    dy = (-vy + y * vz) * inv_z + (1.0 + y * y) * wx - x * y * wy - x * wz
    out = np.empty((H, W, 2), dtype=np.float32)
    out[..., 0] = K[0, 0] * dx
    out[..., 1] = K[1, 1] * dy
    return out


@kernel
def _max_flow_speed(d, xr, yc, fx, fy, vx, vy, vz, wx, wy, wz):  # type: ignore[no-untyped-def]
    # motion_field's float64 operations in the same order, its float32 rounding, then the
    # float32 hypot of np.hypot on float32 (computed in double: exact before rounding).
    # A pinhole ray's x depends on the column only, y on the row only: the products of one
    # of them alone are made once per column / row (the same products, the same sums).
    # float32(sqrt(q)) never decreases with q: the largest q gives the largest speed, so
    # the one sqrt is taken at the end. The maximum is kept per column (no dependence from
    # one pixel to the next: the row loop vectorizes), then over the columns; a NaN q is
    # never kept (``q > a`` is false), as in one running maximum.
    H, W = d.shape
    c1 = np.empty(W)
    c2 = np.empty(W)
    c3 = np.empty(W)
    acc = np.zeros(W)
    for j in range(W):
        a = xr[j]
        c1[j] = -vx + a * vz
        c2[j] = (1.0 + a * a) * wy
        c3[j] = a * wz
    for i in range(H):
        b = yc[i]
        r1 = -vy + b * vz
        r2 = (1.0 + b * b) * wx
        r3 = b * wz
        for j in range(W):
            z = np.float64(d[i, j])
            inv_z = 1.0 / z if (np.isfinite(z) and z > 0.0) else 0.0
            ab = xr[j] * b
            dx = c1[j] * inv_z + ab * wx - c2[j] + r3
            dy = r1 * inv_z + r2 - ab * wy - c3[j]
            u = np.float64(np.float32(fx * dx))
            v = np.float64(np.float32(fy * dy))
            q = u * u + v * v
            a = acc[j]
            acc[j] = q if q > a else a
    best = 0.0
    for j in range(W):
        if acc[j] > best:
            best = acc[j]
    return np.float32(np.sqrt(best))


def max_flow_speed(
    depth: NDArray[np.floating],
    K: NDArray[np.floating],
    v_cam: NDArray[np.floating],
    w_cam: NDArray[np.floating],
    rays: tuple[F64, F64] | None = None,
) -> float:
    """``max |flow|`` over the image, px/s: what the ``optical_flow`` sampling needs, in one
    pass without the (H, W, 2) field of :func:`motion_field` (same arguments, same value;
    ``rays``, when given, are :func:`pixel_rays` of ``K``: only their first row and column
    are read; a per-pixel ``v_cam`` (H, W, 3) is taken through :func:`motion_field`)."""
    if np.ndim(v_cam) > 1:
        f = motion_field(depth, K, v_cam, w_cam, rays)
        return float(np.max(np.hypot(f[..., 0], f[..., 1]))) if f.size else 0.0
    d = np.asarray(depth)
    H, W = d.shape
    x, y = rays if rays is not None else pixel_rays(K, W, H)
    K = np.asarray(K, dtype=np.float64)
    vx, vy, vz = (float(a) for a in v_cam)
    wx, wy, wz = (float(a) for a in w_cam)
    return float(
        _max_flow_speed(
            d,
            np.ascontiguousarray(x[0]),
            np.ascontiguousarray(y[:, 0]),
            float(K[0, 0]),
            float(K[1, 1]),
            vx,
            vy,
            vz,
            wx,
            wy,
            wz,
        )
    )


def camera_twist(
    trajectory: Trajectory, t_ns: int, T_body_cam: NDArray[np.floating]
) -> tuple[F64, F64, F64]:
    """Pose and twist of a camera rigidly mounted on base_link.

    Args:
        trajectory: the closed-form landing.
        t_ns: trajectory time, ns.
        T_body_cam: (4, 4) pose of the camera *optical* frame in base_link.
    Returns:
        ``T_world_cam`` (4, 4), ``v_cam`` (3,) m/s and ``w_cam`` (3,) rad/s, both in the
        optical frame (velocity of the optical centre relative to the world).
    """
    p_wb, v_wb, R_wb, w_b = trajectory.pose_twist_ns(t_ns)
    Tbc = np.asarray(T_body_cam, dtype=np.float64)
    R_bc, p_bc = Tbc[:3, :3], Tbc[:3, 3]
    T_wb = np.eye(4)
    T_wb[:3, :3] = R_wb
    T_wb[:3, 3] = p_wb
    T_wc = T_wb @ Tbc
    # w_b x p_bc written out: np.cross's products and differences, without its overhead
    (a0, a1, a2), (b0, b1, b2) = w_b.tolist(), p_bc.tolist()
    cross = np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])
    v_w = v_wb + R_wb @ cross
    R_wc = T_wc[:3, :3]
    return T_wc, R_wc.T @ v_w, R_bc.T @ w_b


class AdaptiveSampler:
    """Chooses the render instants (integer ns).

    Args:
        strategy: ``brightness``, ``optical_flow`` or ``fixed`` (always ``1/max_rate``).
        lam: ESIM's lambda (log units for brightness, px for optical flow).
        min_rate, max_rate: bounds on the sampling rate, Hz.
        end_ns: last instant (the trajectory's end, always sampled).
        forced_ns: sorted instants that must be sampled exactly.
    """

    def __init__(
        self,
        strategy: Strategy,
        lam: float,
        min_rate: float,
        max_rate: float,
        end_ns: int,
        forced_ns: NDArray[np.int64] | None = None,
    ) -> None:
        self.strategy = strategy
        self.lam = float(lam)
        self.min_dt_ns = max(1, round(1e9 / max_rate))
        self.max_dt_ns = max(self.min_dt_ns, round(1e9 / min_rate))
        self.end_ns = int(end_ns)
        f = np.zeros(0, np.int64) if forced_ns is None else np.asarray(forced_ns, np.int64)
        self.forced = np.unique(f[(f > 0) & (f <= self.end_ns)])

    def step_ns(self, max_rate_of_change: float) -> int:
        """``lambda / max_rate_of_change`` clamped to the rate bounds (ns)."""
        if self.strategy == "fixed":
            return self.min_dt_ns
        r = float(max_rate_of_change)
        if not np.isfinite(r):
            return self.min_dt_ns
        if r <= 0.0:
            return self.max_dt_ns
        dt = round(self.lam / r * 1e9)
        return int(min(max(dt, self.min_dt_ns), self.max_dt_ns))

    def next_ns(self, t_ns: int, max_rate_of_change: float) -> int | None:
        """The instant after ``t_ns`` (None when ``t_ns`` is the end)."""
        if t_ns >= self.end_ns:
            return None
        nxt = t_ns + self.step_ns(max_rate_of_change)
        i = int(np.searchsorted(self.forced, t_ns, side="right"))
        if i < self.forced.shape[0]:
            nxt = min(nxt, int(self.forced[i]))
        return min(nxt, self.end_ns)
