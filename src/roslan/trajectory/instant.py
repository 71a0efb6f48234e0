"""The tau landing's pose and twist at ONE instant, cheaply and to the last bit.

:meth:`TauTrajectory.state` is vectorized for many instants; at a single instant (the
event camera asks once per adaptive sampling step) its ~150 NumPy calls on 1-element
arrays cost ~0.7 ms. :class:`InstantEvaluator` performs the same floating-point
operations, in the same order, on Python floats: ``+ - * /`` and ``sqrt`` are IEEE
correctly rounded either way, and every other operation whose result could depend on the
implementation (``pow``, ``sin``, ``cos`` through NumPy's SIMD loops; the 3x3 products
through BLAS) is still made by the same NumPy call on an array of the same layout. So
the results equal :meth:`TauTrajectory.state_ns`'s bit for bit (tests/trajectory check).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray

from roslan.frames import quaternion_matrix_entries, reference_yaw, zyx_quaternion
from roslan.trajectory.tau import _EPS, S_FLOOR

if TYPE_CHECKING:
    from roslan.trajectory.config import Flapping

__all__ = ["InstantEvaluator", "TauLanding"]

F64 = NDArray[np.float64]


class TauLanding(Protocol):
    """What the evaluator reads of a :class:`~roslan.trajectory.generator.TauTrajectory`
    (which imports this module): the landing's constants."""

    @property
    def T(self) -> float: ...

    @property
    def initial_gaps(self) -> F64: ...

    @property
    def exponents(self) -> F64: ...

    @property
    def R_world_goal(self) -> F64: ...

    @property
    def p_world_goal(self) -> F64: ...

    @property
    def _q_world_goal(self) -> F64: ...

    @property
    def _flap(self) -> Flapping | None: ...


def _pow(s: float, e: float) -> float:
    """:func:`roslan.trajectory.tau.safe_pow` of one value (NumPy's ``power`` kept)."""
    if e == 0.0:
        return 1.0
    if e == 1.0:
        return s
    if e == 2.0:
        return s * s
    if e == 0.5:
        return math.sqrt(s)  # IEEE correctly rounded, as np.sqrt
    if e > 0.0:
        return float(np.power(np.array([s]), e)[0])
    return float(np.power(np.array([max(s, S_FLOOR)]), e)[0])


def _powers(s: float, n: float) -> tuple[float, float, float]:
    """:func:`roslan.trajectory.tau.powers` of one value."""
    if n >= 2.0:
        p2 = _pow(s, n - 2.0)
        p1 = p2 * s
        return p1 * s, p1, p2
    p1 = _pow(s, n - 1.0)
    p2 = 0.0 if abs(n - 1.0) <= _EPS else _pow(s, n - 2.0)
    return p1 * s, p1, p2


class InstantEvaluator:
    """``position, velocity, R_world_body, omega_body`` of a :class:`TauTrajectory` at one
    instant, equal to its :meth:`~TauTrajectory.state_ns` (see the module docstring)."""

    def __init__(self, traj: TauLanding) -> None:
        self.T = float(traj.T)
        self.g0 = [float(g) for g in traj.initial_gaps]
        self.e = [float(e) for e in traj.exponents]
        self.RT = np.ascontiguousarray(traj.R_world_goal.T)
        self.p_goal = traj.p_world_goal
        self.flap = traj._flap
        self.yaw_offset, self.q_ref = reference_yaw(traj._q_world_goal)

    def _gaps(self, tt: float) -> tuple[list[float], list[float]]:
        """``TauTrajectory._gaps_into`` at one instant: the gaps and rates (no accels)."""
        T = self.T
        s = min(max(1.0 - tt / T, 0.0), 1.0)
        gaps, rates = [0.0] * 6, [0.0] * 6
        cache: dict[float, tuple[float, float, float]] = {}
        for i in range(6):
            g0 = self.g0[i]
            if g0 == 0.0:
                continue
            e = self.e[i]
            if e not in cache:
                cache[e] = _powers(s, e)
            p0, p1, _ = cache[e]
            gaps[i] = p0 * g0
            rates[i] = p1 * (-g0 * e / T)
        f = self.flap
        if f is not None:
            w = 2.0 * math.pi * f.frequency
            ph = np.array([w * max(tt, 0.0) + f.phase])
            sn, cs = float(np.sin(ph)[0]), float(np.cos(ph)[0])
            z0 = self.g0[2]
            e_, de = gaps[2] / z0, rates[2] / z0
            osc = e_ * sn
            dosc = de * sn + e_ * w * cs
            for col, amp in ((2, f.heave), (4, f.pitch)):
                if amp > 0:
                    gaps[col] += amp * osc
                    rates[col] += amp * dosc
        if tt > T:
            gaps, rates = [0.0] * 6, [0.0] * 6
        if tt < 0.0:
            rates = [0.0] * 6
        return gaps, rates

    def pose_twist_ns(self, t_ns: int) -> tuple[F64, F64, F64, F64]:
        """(3,) position, (3,) velocity, (3, 3) R_world_body, (3,) omega_body at ``t_ns``."""
        tt = float(np.float64(np.int64(t_ns)) * 1e-9)
        g, r = self._gaps(tt)
        position = np.dot(np.array([g[:3]]), self.RT)[0]
        position += self.p_goal
        velocity = np.dot(np.array([r[:3]]), self.RT)[0]
        # roslan.frames.euler_zyx_kinematics, one instant
        half = [0.5 * g[3], 0.5 * g[4], 0.5 * g[5]]
        if self.yaw_offset != 0.0:
            half[2] += 0.5 * self.yaw_offset
        ha = np.array(half)
        chr_, chp, chy = np.cos(ha).tolist()
        shr, shp, shy = np.sin(ha).tolist()
        qx, qy, qz, qw = zyx_quaternion(chr_, chp, chy, shr, shp, shy, self.q_ref)
        R = np.array(quaternion_matrix_entries(qx, qy, qz, qw)).reshape(3, 3)
        sr, cr = 2.0 * shr * chr_, chr_ * chr_ - shr * shr
        sp, cp = 2.0 * shp * chp, chp * chp - shp * shp
        dr, dp, dy = r[3], r[4], r[5]
        srcp, crcp = sr * cp, cr * cp
        omega = np.array([dr - dy * sp, dp * cr + dy * srcp, dy * crcp - dp * sr])
        return position, velocity, R, omega
