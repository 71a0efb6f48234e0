"""Rotations and frame conventions (docs/design.md §2), for every layer: below the config
models that use them (``Pose.matrix``) and the trajectories.

Conventions used everywhere in roslan:

* Euler angles are ``rpy = (roll, pitch, yaw)`` with ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``
  (ZYX intrinsic, REP 103), mapping child-frame vectors into the parent frame.
* Quaternions are ``quat_xyzw`` (the ROS message order), unit norm, ``w >= 0``.
* Names carry the direction: ``R_world_body`` maps body vectors to world.

All functions are vectorized over a leading axis of N samples.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "R_LINK_OPTICAL",
    "T_LINK_OPTICAL",
    "body_rates_to_euler_rates",
    "euler_rates_to_body_acceleration",
    "euler_rates_to_body_rates",
    "euler_zyx_kinematics",
    "matrix_to_quat_xyzw",
    "matrix_to_rpy",
    "quat_multiply",
    "quat_xyzw_to_matrix",
    "quaternion_matrix_entries",
    "reference_yaw",
    "rotation_log",
    "rpy_to_matrix",
    "rpy_to_quat_xyzw",
    "zyx_quaternion",
]

F64 = NDArray[np.float64]

R_LINK_OPTICAL: F64 = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
"""The orientation of a camera's optical frame (z forward, x right, y down) in its link
frame (x forward, y left, z up): maps optical-frame vectors into the link frame (its
transpose maps link vectors into the optical frame)."""

T_LINK_OPTICAL: F64 = np.eye(4)
T_LINK_OPTICAL[:3, :3] = R_LINK_OPTICAL
"""The pose (4, 4) of a camera's optical frame in its link frame: :data:`R_LINK_OPTICAL`,
no offset."""


def rpy_to_matrix(rpy: ArrayLike) -> F64:
    """Rotation matrices from roll/pitch/yaw.

    Args:
        rpy: (..., 3) radians.
    Returns:
        (..., 3, 3) ``Rz(yaw) @ Ry(pitch) @ Rx(roll)``.
    """
    a = np.asarray(rpy, dtype=np.float64)
    if a.shape[-1] != 3:
        msg = f"rpy must have shape (..., 3), got {a.shape}"
        raise ValueError(msg)
    cr, sr = np.cos(a[..., 0]), np.sin(a[..., 0])
    cp, sp = np.cos(a[..., 1]), np.sin(a[..., 1])
    cy, sy = np.cos(a[..., 2]), np.sin(a[..., 2])
    R = np.empty((*a.shape[:-1], 3, 3))
    R[..., 0, 0] = cy * cp
    R[..., 0, 1] = cy * sp * sr - sy * cr
    R[..., 0, 2] = cy * sp * cr + sy * sr
    R[..., 1, 0] = sy * cp
    R[..., 1, 1] = sy * sp * sr + cy * cr
    R[..., 1, 2] = sy * sp * cr - cy * sr
    R[..., 2, 0] = -sp
    R[..., 2, 1] = cp * sr
    R[..., 2, 2] = cp * cr
    return R


def matrix_to_rpy(R: ArrayLike) -> F64:
    """Inverse of :func:`rpy_to_matrix` for pitch in (-pi/2, pi/2). (..., 3, 3) -> (..., 3)."""
    m = np.asarray(R, dtype=np.float64)
    roll = np.arctan2(m[..., 2, 1], m[..., 2, 2])
    pitch = np.arcsin(np.clip(-m[..., 2, 0], -1.0, 1.0))
    yaw = np.arctan2(m[..., 1, 0], m[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


def matrix_to_quat_xyzw(R: ArrayLike) -> F64:
    """Unit quaternions (x, y, z, w) with w >= 0 from rotation matrices (..., 3, 3)."""
    m = np.asarray(R, dtype=np.float64)
    shape = m.shape[:-2]
    m = m.reshape(-1, 3, 3)
    tr = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    # Robust branch-free variant: four candidate solutions, pick the best conditioned.
    cand = np.stack(
        [
            1.0 + tr,
            1.0 + m[:, 0, 0] - m[:, 1, 1] - m[:, 2, 2],
            1.0 - m[:, 0, 0] + m[:, 1, 1] - m[:, 2, 2],
            1.0 - m[:, 0, 0] - m[:, 1, 1] + m[:, 2, 2],
        ],
        axis=1,
    )
    best = np.argmax(cand, axis=1)
    q = np.empty((m.shape[0], 4))  # x, y, z, w
    idx = np.arange(m.shape[0])
    s = np.sqrt(np.maximum(cand[idx, best], 1e-300)) * 2.0  # s = 4 * |component|
    b0, b1, b2, b3 = (best == 0), (best == 1), (best == 2), (best == 3)
    q[b0, 3] = 0.25 * s[b0]
    q[b0, 0] = (m[b0, 2, 1] - m[b0, 1, 2]) / s[b0]
    q[b0, 1] = (m[b0, 0, 2] - m[b0, 2, 0]) / s[b0]
    q[b0, 2] = (m[b0, 1, 0] - m[b0, 0, 1]) / s[b0]
    q[b1, 0] = 0.25 * s[b1]
    q[b1, 3] = (m[b1, 2, 1] - m[b1, 1, 2]) / s[b1]
    q[b1, 1] = (m[b1, 0, 1] + m[b1, 1, 0]) / s[b1]
    q[b1, 2] = (m[b1, 0, 2] + m[b1, 2, 0]) / s[b1]
    q[b2, 1] = 0.25 * s[b2]
    q[b2, 3] = (m[b2, 0, 2] - m[b2, 2, 0]) / s[b2]
    q[b2, 0] = (m[b2, 0, 1] + m[b2, 1, 0]) / s[b2]
    q[b2, 2] = (m[b2, 1, 2] + m[b2, 2, 1]) / s[b2]
    q[b3, 2] = 0.25 * s[b3]
    q[b3, 3] = (m[b3, 1, 0] - m[b3, 0, 1]) / s[b3]
    q[b3, 0] = (m[b3, 0, 2] + m[b3, 2, 0]) / s[b3]
    q[b3, 1] = (m[b3, 1, 2] + m[b3, 2, 1]) / s[b3]
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[q[:, 3] < 0] *= -1.0
    return q.reshape((*shape, 4))


def quat_xyzw_to_matrix(q: ArrayLike) -> F64:
    """Rotation matrices (..., 3, 3) from quaternions (..., 4) in x, y, z, w order."""
    a = np.asarray(q, dtype=np.float64)
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    x, y, z, w = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    R = np.empty((*a.shape[:-1], 3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - z * w)
    R[..., 0, 2] = 2 * (x * z + y * w)
    R[..., 1, 0] = 2 * (x * y + z * w)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - x * w)
    R[..., 2, 0] = 2 * (x * z - y * w)
    R[..., 2, 1] = 2 * (y * z + x * w)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def rotation_log(R: ArrayLike) -> F64:
    """Log map SO(3) -> rotation vectors (..., 3): axis * angle, angle in [0, pi].

    Computed through the quaternion (``angle = 2 atan2(|v|, w)``), which stays accurate
    near 0 and near pi, where the trace formula loses the axis.
    """
    q = matrix_to_quat_xyzw(R)
    v = q[..., :3]
    norm = np.linalg.norm(v, axis=-1)
    angle = 2.0 * np.arctan2(norm, q[..., 3])
    small = norm < 1e-12
    # angle / norm -> 2 / w as the angle -> 0 (w -> 1)
    scale = np.where(small, 2.0, angle / np.where(small, 1.0, norm))
    return v * scale[..., None]


def euler_rates_to_body_rates(rpy: ArrayLike, rpy_dot: ArrayLike) -> F64:
    """Body angular velocity (rad/s, body frame) from ZYX Euler angles and their rates.

    ``w = [dr - dy sin p, dp cos r + dy sin r cos p, -dp sin r + dy cos r cos p]``.
    Shapes: (N, 3), (N, 3) -> (N, 3).
    """
    a = np.asarray(rpy, dtype=np.float64)
    d = np.asarray(rpy_dot, dtype=np.float64)
    r, p = a[..., 0], a[..., 1]
    dr, dp, dy = d[..., 0], d[..., 1], d[..., 2]
    sr, cr, sp, cp = np.sin(r), np.cos(r), np.sin(p), np.cos(p)
    return np.stack(
        [dr - dy * sp, dp * cr + dy * sr * cp, -dp * sr + dy * cr * cp],
        axis=-1,
    )


def body_rates_to_euler_rates(rpy: ArrayLike, omega: ArrayLike) -> F64:
    """ZYX Euler-angle rates giving body angular velocity ``omega`` (rad/s, body frame)
    at Euler angles ``rpy``: the inverse of :func:`euler_rates_to_body_rates` (singular at
    ``cos(pitch) = 0``). Shapes: (N, 3), (N, 3) -> (N, 3)."""
    a = np.asarray(rpy, dtype=np.float64)
    w = np.asarray(omega, dtype=np.float64)
    r, p = a[..., 0], a[..., 1]
    wx, wy, wz = w[..., 0], w[..., 1], w[..., 2]
    sr, cr, sp, cp = np.sin(r), np.cos(r), np.sin(p), np.cos(p)
    dy = (wy * sr + wz * cr) / cp
    return np.stack([wx + dy * sp, wy * cr - wz * sr, dy], axis=-1)


def euler_rates_to_body_acceleration(
    rpy: ArrayLike, rpy_dot: ArrayLike, rpy_ddot: ArrayLike
) -> F64:
    """Body angular acceleration (rad/s^2, body frame): exact time derivative of
    :func:`euler_rates_to_body_rates` (the body frame derivative equals the inertial one
    for angular velocity). Shapes: 3 x (N, 3) -> (N, 3)."""
    a = np.asarray(rpy, dtype=np.float64)
    d = np.asarray(rpy_dot, dtype=np.float64)
    dd = np.asarray(rpy_ddot, dtype=np.float64)
    r, p = a[..., 0], a[..., 1]
    dr, dp, dy = d[..., 0], d[..., 1], d[..., 2]
    ddr, ddp, ddy = dd[..., 0], dd[..., 1], dd[..., 2]
    sr, cr, sp, cp = np.sin(r), np.cos(r), np.sin(p), np.cos(p)
    ax = ddr - ddy * sp - dy * cp * dp
    ay = ddp * cr - dp * sr * dr + ddy * sr * cp + dy * (cr * dr * cp - sr * sp * dp)
    az = -ddp * sr - dp * cr * dr + ddy * cr * cp + dy * (-sr * dr * cp - cr * sp * dp)
    return np.stack([ax, ay, az], axis=-1)


def rpy_to_quat_xyzw(rpy: ArrayLike) -> F64:
    """Quaternions (..., 4) x, y, z, w of ``Rz(yaw) Ry(pitch) Rx(roll)``, sign fixed to w >= 0."""
    a = np.asarray(rpy, dtype=np.float64)
    hr, hp, hy = a[..., 0] / 2, a[..., 1] / 2, a[..., 2] / 2
    cr, sr, cp, sp, cy, sy = np.cos(hr), np.sin(hr), np.cos(hp), np.sin(hp), np.cos(hy), np.sin(hy)
    q = np.stack(
        [
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy,
        ],
        axis=-1,
    )
    return np.where(q[..., 3:4] < 0, -q, q)


def quat_multiply(a: ArrayLike, b: ArrayLike) -> F64:
    """Hamilton product ``a ⊗ b`` of (..., 4) x, y, z, w quaternions (rotation b, then a)."""
    p = np.asarray(a, dtype=np.float64)
    q = np.asarray(b, dtype=np.float64)
    x1, y1, z1, w1 = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    x2, y2, z2, w2 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        ],
        axis=-1,
    )


def reference_yaw(
    q_parent_ref: ArrayLike | None,
) -> tuple[float, tuple[float, float, float, float] | None]:
    """``(yaw_offset, q_ref)`` of a constant reference orientation (x, y, z, w) for
    :func:`euler_zyx_kinematics`: a pure yaw of the reference frame just adds to the
    (outermost) yaw angle (``q_ref`` None); otherwise the quaternion is kept."""
    if q_parent_ref is None:
        return 0.0, None
    q = np.asarray(q_parent_ref, dtype=np.float64)
    if abs(q[0]) < 1e-15 and abs(q[1]) < 1e-15:
        return 2.0 * math.atan2(float(q[2]), float(q[3])), None
    return 0.0, (float(q[0]), float(q[1]), float(q[2]), float(q[3]))


def zyx_quaternion(
    chr_: Any, chp: Any, chy: Any, shr: Any, shp: Any, shy: Any,
    q_ref: tuple[float, float, float, float] | None = None,
) -> tuple[Any, Any, Any, Any]:  # fmt: skip
    """x, y, z, w of Rz(y) Ry(p) Rx(r) from the cosines and sines of the half angles
    (floats or arrays alike: the same operations in the same order, so one instant on
    floats equals the vectorized result bit for bit), premultiplied by ``q_ref``."""
    a, b = chr_ * chp, shr * shp
    c, d = shr * chp, chr_ * shp
    qx = c * chy - d * shy
    qy = d * chy + c * shy
    qz = a * shy - b * chy
    qw = a * chy + b * shy
    if q_ref is not None:
        x1, y1, z1, w1 = q_ref
        qx, qy, qz, qw = (
            w1 * qx + x1 * qw + y1 * qz - z1 * qy,
            w1 * qy - x1 * qz + y1 * qw + z1 * qx,
            w1 * qz + x1 * qy - y1 * qx + z1 * qw,
            w1 * qw - x1 * qx - y1 * qy - z1 * qz,
        )
    return qx, qy, qz, qw


def quaternion_matrix_entries(qx: Any, qy: Any, qz: Any, qw: Any) -> tuple[Any, ...]:
    """The 9 entries, row by row, of the rotation matrix of a unit quaternion (floats or
    arrays alike, as :func:`zyx_quaternion`)."""
    tx, ty, tz = 2.0 * qx, 2.0 * qy, 2.0 * qz
    xx, yy, zz = tx * qx, ty * qy, tz * qz
    xy, xz, yz = tx * qy, tx * qz, ty * qz
    wx, wy, wz = tx * qw, ty * qw, tz * qw
    return (
        1.0 - (yy + zz), xy - wz, xz + wy,
        xy + wz, 1.0 - (xx + zz), yz - wx,
        xz - wy, yz + wx, 1.0 - (xx + yy),
    )  # fmt: skip


def euler_zyx_kinematics(
    rpy: F64,
    rpy_dot: F64,
    rpy_ddot: F64,
    q_parent_ref: ArrayLike | None = None,
    *,
    out: tuple[F64, F64, F64, F64] | None = None,
) -> tuple[F64, F64, F64, F64]:
    """Orientation, angular velocity and angular acceleration from ZYX Euler angles.

    The fused, fast path of :func:`rpy_to_quat_xyzw`, :func:`quat_xyzw_to_matrix`,
    :func:`euler_rates_to_body_rates` and :func:`euler_rates_to_body_acceleration`:
    six trig calls in all (half angles; full-angle sines and cosines follow from them).

    Args:
        rpy, rpy_dot, rpy_ddot: (N, 3) Euler angles of ``body`` relative to a reference
            frame ``ref`` (rad) and their first and second time derivatives.
        q_parent_ref: optional constant (4,) x, y, z, w orientation of ``ref`` in a
            parent frame; the returned orientation is then that of body in the parent.
        out: optional preallocated (quat, R, omega, alpha) arrays of the result shapes.
    Returns:
        quat_xyzw (N, 4) (w >= 0), R_parent_body (N, 3, 3), omega_body (N, 3) rad/s,
        alpha_body (N, 3) rad/s^2 (both in the body frame).
    """
    n = rpy.shape[0]
    half = 0.5 * rpy.T  # (3, N), rows contiguous after the copy below
    half = np.ascontiguousarray(half)
    yaw_offset, q_ref = reference_yaw(q_parent_ref)
    if yaw_offset != 0.0:
        half[2] += 0.5 * yaw_offset
    cos_h = np.cos(half)
    sin_h = np.sin(half)
    chr_, chp, chy = cos_h
    shr, shp, shy = sin_h
    qx, qy, qz, qw = zyx_quaternion(chr_, chp, chy, shr, shp, shy, q_ref)
    if out is None:
        quat, R = np.empty((n, 4)), np.empty((n, 3, 3))
        omega, alpha = np.empty((n, 3)), np.empty((n, 3))
    else:
        quat, R, omega, alpha = out
    sign = np.where(qw < 0.0, -1.0, 1.0)
    np.multiply(qx, sign, out=quat[:, 0])
    np.multiply(qy, sign, out=quat[:, 1])
    np.multiply(qz, sign, out=quat[:, 2])
    np.multiply(qw, sign, out=quat[:, 3])
    for k, entry in enumerate(quaternion_matrix_entries(qx, qy, qz, qw)):
        R[:, k // 3, k % 3] = entry
    # full-angle trig of roll and pitch from the half angles
    sr, cr = 2.0 * shr * chr_, chr_ * chr_ - shr * shr
    sp, cp = 2.0 * shp * chp, chp * chp - shp * shp
    d1 = np.ascontiguousarray(rpy_dot.T)
    d2 = np.ascontiguousarray(rpy_ddot.T)
    dr, dp, dy = d1
    ddr, ddp, ddy = d2
    srcp, crcp = sr * cp, cr * cp
    dysp = dy * sp
    dpsr, dpcr = dp * sr, dp * cr
    drdy = dr * dy
    omega[:, 0] = dr - dysp
    omega[:, 1] = dpcr + dy * srcp
    omega[:, 2] = dy * crcp - dpsr
    alpha[:, 0] = ddr - ddy * sp - dy * cp * dp
    alpha[:, 1] = ddp * cr - dpsr * dr + ddy * srcp + drdy * crcp - dysp * dpsr
    alpha[:, 2] = ddy * crcp - ddp * sr - dpcr * dr - drdy * srcp - dysp * dpcr
    return quat, R, omega, alpha
