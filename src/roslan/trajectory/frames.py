"""The rotation helpers under their trajectory-side name: they live in
:mod:`roslan.frames`, below the config models that use them (``Pose.matrix``), since
importing any module of this package first runs the package's ``__init__``, which
imports those config models back."""

from __future__ import annotations

from roslan.frames import (
    OPTICAL_FROM_BODY,
    euler_rates_to_body_acceleration,
    euler_rates_to_body_rates,
    euler_zyx_kinematics,
    matrix_to_quat_xyzw,
    matrix_to_rpy,
    quat_multiply,
    quat_xyzw_to_matrix,
    quaternion_matrix_entries,
    reference_yaw,
    rotation_log,
    rpy_to_matrix,
    rpy_to_quat_xyzw,
    zyx_quaternion,
)

__all__ = [
    "OPTICAL_FROM_BODY",
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
