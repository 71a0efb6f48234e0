"""Attitude from the gyro and the accelerometer: a Mahony complementary filter with gyro
bias estimation.

Mahony, Hamel and Pflimlin, "Nonlinear Complementary Filters on the Special Orthogonal
Group", IEEE Transactions on Automatic Control 53(5), 2008 (the "explicit complementary
filter" with bias estimation). The gyro propagates the attitude; the accelerometer's
direction corrects its roll and pitch (yaw is not observable from it) through a
proportional gain ``kp`` and an integral one ``ki`` that estimates the gyro's bias.

The accelerometer measures the specific force ``f = R^T (a - g)``, gravity only when
the body does not accelerate. During a landing it does (braking, centring, flapping), so
the filter compares the measured direction with the one **expected** from the vehicle's
own commanded acceleration ``a`` (which the policy knows: its actions, through the
actuator lag of its configuration), and skips the correction of a sample whose specific
force's magnitude departs from the expected one by more than ``gate`` (m/s^2): the
flapping heave's peaks, a bump; and while the expected horizontal acceleration exceeds
``max_accel`` (the start's hard turn towards the goal).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

__all__ = ["AttitudeFilter", "expm_so3"]

F64 = NDArray[np.float64]


def expm_so3(w: F64) -> F64:
    """Rotation matrix of the rotation vector ``w`` (Rodrigues)."""
    th = math.sqrt(float(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]))
    k = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    if th < 1e-9:
        return np.asarray(np.eye(3) + k, dtype=np.float64)
    out = np.eye(3) + math.sin(th) / th * k + (1.0 - math.cos(th)) / th**2 * (k @ k)
    return np.asarray(out, dtype=np.float64)


class AttitudeFilter:
    """Explicit complementary filter (module docstring) of base_link's attitude.

    Args:
        R0: (3, 3) initial attitude (the start estimate's).
        kp: proportional gain, rad/s per rad of error.
        ki: integral (bias) gain, rad/s^2 per rad.
        gate: m/s^2; samples whose specific force's magnitude departs from the expected
            one by more than this do not correct.
        max_accel: m/s^2; no correction while the expected horizontal acceleration is
            larger (the expected direction then hangs on the yaw, which the accelerometer
            does not observe: a yaw error of 0.05 rad at 10 m/s^2 reads as a 0.05 rad tilt).
        gravity: m/s^2.

    Attributes:
        R: (3, 3) the attitude estimate (world from body).
        bias: (3,) the gyro bias estimate, rad/s (body frame).
        corrected: samples that corrected the attitude so far; ``samples``: all.
    """

    def __init__(
        self,
        R0: F64,
        *,
        kp: float = 2.0,
        ki: float = 0.1,
        gate: float = 7.0,
        max_accel: float = 100.0,
        gravity: float = 9.81,
    ) -> None:
        self.R = np.array(R0, dtype=np.float64)
        self.bias = np.zeros(3)
        self.kp, self.ki, self.gate = float(kp), float(ki), float(gate)
        self.max_accel = float(max_accel)
        self.g_up = np.array([0.0, 0.0, float(gravity)])
        self.corrected = 0
        self.samples = 0

    def update(self, gyro: F64, acc: F64, dt: float, a_world: F64) -> F64:
        """One IMU sample: ``gyro`` (rad/s) and ``acc`` (specific force, m/s^2), both in
        base_link, over ``dt`` s, with the expected acceleration ``a_world`` (m/s^2,
        world). Returns the new attitude."""
        w = gyro - self.bias
        f_exp = self.R.T @ (a_world + self.g_up)
        n_meas = math.sqrt(float(acc @ acc))
        n_exp = math.sqrt(float(f_exp @ f_exp))
        self.samples += 1
        a_h = math.hypot(float(a_world[0]), float(a_world[1]))
        if a_h < self.max_accel and n_meas > 1.0 and abs(n_meas - n_exp) < self.gate:
            e = np.cross(acc / n_meas, f_exp / n_exp)
            w = w + self.kp * e
            self.bias = self.bias - self.ki * e * dt
            self.corrected += 1
        self.R = self.R @ expm_so3(w * dt)
        return self.R
