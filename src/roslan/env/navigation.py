"""The ``tau-events`` policy's navigation: the height gap from the event camera's tau, the
horizontal gaps from the marker's bearing, both on the IMU's dead reckoning.

:class:`VerticalEstimator`: the IMU's dead reckoning from the start estimate (position
``p``, velocity ``v``: the world's vertical axis) is wrong by the start estimate's
errors and the accelerometer's bias ``b``: the true height gap and vertical velocity are
``h(t) = p(t) - c0 - dv t - b t^2 / 2`` and ``vz(t) = v(t) - dv - b t`` with three
unknowns ``theta = (c0, dv, b)`` (``c0``: the touchdown level in the dead-reckoned frame).
The event camera measures the divergence ``D = -1 / tau_cam = -vz / h_cam`` (``h_cam``: the
camera's height, ``h + o(t)`` from the vehicle's geometry), so every estimate gives one
equation **linear** in theta::

    D (p + o) + v = D c0 + (D t + 1) dv + (D t^2 / 2 + t) b

solved by weighted least squares with the start estimate and the IMU's turn-on bias as
Gaussian priors (a Kalman filter of a constant state). The scale of the height is
observable because the vehicle accelerates (its braking): with a constant velocity the
divergence fixes only ``vz / h`` (de Croon, "Monocular distance estimation with optical
flow maneuvers and efference copies: a stability-based strategy", Bioinspiration &
Biomimetics 11, 2016, on the same point). An estimate whose residual exceeds
``GATE`` standard deviations is rejected once the solution has settled.

:class:`HorizontalFilter`: a Kalman filter per goal-frame axis of the gap, its rate and
the accelerometer's bias (with the tilt error's share of it), driven by the IMU's
velocity increments and corrected by the marker's position from its bearing
(:mod:`roslan.env.marker_bearing`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

__all__ = ["HorizontalFilter", "VerticalEstimator"]

F64 = NDArray[np.float64]


class VerticalEstimator:
    """Height gap and vertical velocity from divergence and dead reckoning (module
    docstring).

    Args:
        z0: the start estimate's height gap, m; ``sigma_z``: its error, m.
        sigma_v: the start estimate's velocity error, m/s.
        sigma_b: the accelerometer's turn-on bias, m/s^2.
        rel_error: relative error of one divergence estimate.
    """

    GATE = 3.0
    """Residuals beyond this many standard deviations are rejected (after ``SETTLE``)."""
    SETTLE = 15
    """Estimates accepted before the gate applies."""
    DIVERGENCE_DEWEIGHT = 5.0
    """The divergence estimates' error counts this many times larger once the marker gave
    a height (:meth:`add_height`)."""

    def __init__(
        self, z0: float, sigma_z: float, sigma_v: float, sigma_b: float, rel_error: float = 0.15
    ) -> None:
        s = np.array([max(sigma_z, 0.02), max(sigma_v, 0.01), max(sigma_b, 0.005)])
        # normal equations: the prior, the divergence's and the marker's heights' apart
        # (the divergence's weigh less once there are heights: :meth:`add_height`)
        self._N0 = np.diag(1.0 / s**2)
        self._r0 = self._N0 @ np.array([-z0, 0.0, 0.0])
        self._Nd, self._rd = np.zeros((3, 3)), np.zeros(3)
        self._Nh, self._rh = np.zeros((3, 3)), np.zeros(3)
        self.theta = np.array([-z0, 0.0, 0.0])
        self.rel_error = float(rel_error)
        self.accepted = 0
        self.rejected = 0
        self.heights = 0

    def add(self, D: float, t: float, p: float, v: float, o: float, extra: float = 0.0) -> bool:
        """One divergence ``D`` (1/s) at time ``t`` (s since the start) with the dead
        reckoning's ``p``, ``v`` there and the camera's height above the height gap
        ``o`` (m); ``extra``: a further error of ``D h_cam`` (m/s; a sliding camera's
        normal error biases ``D`` by about ``1.5 V tilt / h``). Returns whether it was
        accepted."""
        a = np.array([D, D * t + 1.0, 0.5 * D * t * t + t])
        y = D * (p + o) + v
        vz = v - self.theta[1] - self.theta[2] * t
        sigma = self.rel_error * abs(vz) + 0.02 + extra
        if self.accepted >= self.SETTLE and abs(y - a @ self.theta) > self.GATE * sigma:
            self.rejected += 1
            return False
        w = 1.0 / sigma**2
        self._Nd += w * np.outer(a, a)
        self._rd += w * a * y
        self._solve()
        self.accepted += 1
        return True

    def add_height(self, h: float, t: float, p: float, sigma: float) -> bool:
        """A direct measurement ``h`` (m, error ``sigma``) of the height gap at time ``t``
        with the dead reckoning's ``p`` there (the landing marker's apparent size:
        :mod:`roslan.env.marker_bearing`): ``p - h = c0 + dv t + b t^2 / 2``. Not gated
        (the marker's fixes are verified by its geometry); from then on the divergence's
        estimates, past and future, weigh as if their errors were ``DIVERGENCE_DEWEIGHT``
        times larger (their error is a scale error of the whole descent, not independent
        noise)."""
        a = np.array([1.0, t, 0.5 * t * t])
        y = p - h
        w = 1.0 / sigma**2
        self._Nh += w * np.outer(a, a)
        self._rh += w * a * y
        self.heights += 1
        self._solve()
        return True

    def _solve(self) -> None:
        wd = 1.0 / self.DIVERGENCE_DEWEIGHT**2 if self.heights else 1.0
        N = self._N0 + wd * self._Nd + self._Nh
        self.theta = np.linalg.solve(N, self._r0 + wd * self._rd + self._rh)

    def height(self, t: float, p: float) -> float:
        """The height gap at time ``t`` with the dead reckoning's ``p``, m."""
        c0, dv, b = self.theta
        return float(p - c0 - dv * t - 0.5 * b * t * t)

    def velocity(self, t: float, v: float) -> float:
        """The vertical velocity at ``t`` with the dead reckoning's ``v``, m/s."""
        return float(v - self.theta[1] - self.theta[2] * t)


class HorizontalFilter:
    """Kalman filter of the horizontal gaps (module docstring); two independent axes.

    Args:
        x0, v0: (2,) the start estimate's gaps (m) and rates (m/s) in the goal frame.
        sigma_x, sigma_v: their errors; ``sigma_b``: the acceleration bias's (m/s^2).
        accel_noise: m/s^2 of unmodelled acceleration error (process noise).
        heading_sigma: rad, the heading estimate's error (the accelerometer does not
            observe it).
    """

    def __init__(
        self,
        x0: F64,
        v0: F64,
        sigma_x: float,
        sigma_v: float,
        sigma_b: float,
        accel_noise: float = 0.3,
        heading_sigma: float = 0.02,
    ) -> None:
        self.heading_sigma = float(heading_sigma)
        self.s = np.zeros((2, 3))
        self.s[:, 0], self.s[:, 1] = x0, v0
        P = np.diag([max(sigma_x, 0.02) ** 2, max(sigma_v, 0.01) ** 2, max(sigma_b, 0.01) ** 2])
        self.P = np.stack([P, P])
        self.q = float(accel_noise) ** 2
        self.fixes = 0

    def predict(self, dv: F64, dt: float) -> None:
        """Advance ``dt`` s with the IMU's velocity increment ``dv`` (2,) over it (its
        direction uncertain by ``heading_sigma``: a heading error turns a velocity change
        into a sideways error)."""
        if dt <= 0.0:
            return
        turn = (self.heading_sigma * float(np.hypot(dv[0], dv[1]))) ** 2
        F = np.array([[1.0, dt, -0.5 * dt * dt], [0.0, 1.0, -dt], [0.0, 0.0, 1.0]])
        x = self.s
        x[:, 0] += x[:, 1] * dt + 0.5 * dv * dt - 0.5 * x[:, 2] * dt * dt
        x[:, 1] += dv - x[:, 2] * dt
        Q = self.q * np.array(
            [[dt**3 / 3.0, dt**2 / 2.0, 0.0], [dt**2 / 2.0, dt, 0.0], [0.0, 0.0, 1e-4 * dt]]
        )
        self.P = F @ self.P @ F.T + Q
        self.P[:, 1, 1] += turn

    def correct(self, xy: F64, sigma: float) -> None:
        """A measurement ``xy`` (2,) of the gaps (m) with error ``sigma`` (m)."""
        for i in range(2):
            P = self.P[i]
            k = P[:, 0] / (P[0, 0] + sigma * sigma)
            self.s[i] += k * (xy[i] - self.s[i, 0])
            self.P[i] = P - np.outer(k, P[0])
        self.fixes += 1

    @property
    def gaps(self) -> F64:
        """(2,) the horizontal gaps, m."""
        return np.asarray(self.s[:, 0].copy(), dtype=np.float64)

    @property
    def rates(self) -> F64:
        """(2,) their rates, m/s."""
        return np.asarray(self.s[:, 1].copy(), dtype=np.float64)

    @property
    def sigma(self) -> float:
        """The larger axis's position standard deviation, m."""
        return float(math.sqrt(max(self.P[0, 0, 0], self.P[1, 0, 0])))
