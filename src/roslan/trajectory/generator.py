"""The tau-theory landing trajectory: closed form, vectorized, sampled at any instants."""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from roslan.frames import euler_zyx_kinematics, rpy_to_matrix, rpy_to_quat_xyzw
from roslan.trajectory.base import GAPS, State, Trajectory, check_duration
from roslan.trajectory.config import Flapping, TrajectoryConfig
from roslan.trajectory.instant import InstantEvaluator
from roslan.trajectory.tau import Terminal, classify, exponent, powers

__all__ = ["TauTrajectory", "TrajectoryWarning", "add_flapping", "fill_pose", "table_times"]

F64 = NDArray[np.float64]

CHUNK = 16384
"""Instants evaluated per block inside :meth:`TauTrajectory.state` (keeps temporaries in cache)."""


def add_flapping(f: Flapping, z0: float, tc: F64, gaps: F64, rates: F64, accels: F64) -> None:
    """Superimpose flapping on (N, 6) gaps, rates and accels at instants ``tc`` (s), in place:
    heave (on z) and pitch oscillation, faded by the envelope e = z / z0 of the height gap
    (its value before the heave is added), so the oscillation stops at touchdown. Shared by
    the closed-form landing and the closed-loop vehicle (:mod:`roslan.env.dynamics`)."""
    w = 2.0 * math.pi * f.frequency
    ph = w * tc + f.phase
    sn, cs = np.sin(ph), np.cos(ph)
    # envelope e = z/z0 (before the heave is added) fades the oscillation out at touchdown
    e, de, dde = gaps[:, 2] / z0, rates[:, 2] / z0, accels[:, 2] / z0
    osc = e * sn
    dosc = de * sn + e * w * cs
    ddosc = dde * sn + 2.0 * w * de * cs - (w * w) * osc
    for col, amp in ((2, f.heave), (4, f.pitch)):
        if amp > 0:
            gaps[:, col] += amp * osc
            rates[:, col] += amp * dosc
            accels[:, col] += amp * ddosc


def fill_pose(
    gaps: tuple[F64, F64, F64],
    goal: tuple[F64, F64, F64],
    linear: tuple[F64, F64, F64],
    angular: tuple[F64, F64, F64, F64],
) -> None:
    """base_link's world pose and twist from the 18 components in F, in place.

    Args:
        gaps: (n, 6) gaps, rates and accels in F.
        goal: R_world_goal transposed (3, 3, C-contiguous), p_world_goal (3,),
            q_world_goal (4,).
        linear: (n, 3) position, velocity, acceleration out (world).
        angular: (n, 4) quat_xyzw, (n, 3, 3) R_world_body, (n, 3) omega_body and
            alpha_body out.
    """
    g, r, ac = gaps
    RT, p_goal, q_goal = goal
    position, velocity, acceleration = linear
    np.dot(g[:, :3], RT, out=position)
    position += p_goal
    np.dot(r[:, :3], RT, out=velocity)
    np.dot(ac[:, :3], RT, out=acceleration)
    euler_zyx_kinematics(g[:, 3:], r[:, 3:], ac[:, 3:], q_goal, out=angular)


def table_times(T: float, hold: float, dt: float) -> F64:
    """Instants of the exported table (s): every ``dt`` from 0 up to ``T``, exactly ``T``,
    then every ``dt`` after ``T`` through the hold, ending exactly at ``T + hold``."""
    duration = T + hold
    tol = 1e-9 * max(1.0, T)
    n = math.floor(T / dt + 1e-9)
    before = np.arange(n + 1, dtype=np.float64) * dt
    before = before[before < T - tol]  # a grid point within tol of T becomes T
    parts = [before, np.array([T])]
    if hold > 0.0:
        m = math.floor(hold / dt + 1e-9)
        after = T + np.arange(1, m + 1, dtype=np.float64) * dt
        after = after[after < duration - tol]
        parts += [after, np.array([duration])]
    return np.concatenate(parts)


class TrajectoryWarning(UserWarning):
    """Valid parameters whose landing is physically hard (unbounded deceleration...)."""


class TauTrajectory(Trajectory):
    """A validated tau-theory landing, evaluated in closed form.

    ``Trajectory(config).state(t)`` gives the full :class:`State` at any instants
    ``t`` (s); before 0 it is clamped to the start, after touchdown ``T`` the robot
    rests at the goal for ``config.hold`` seconds.
    """

    def __init__(self, config: TrajectoryConfig, *, warn: bool = True) -> None:
        self.config = config
        c = config
        if c.approach is not None:
            a = c.approach
            horiz = a.distance * math.cos(a.angle)
            x0 = -horiz * math.cos(a.heading)
            y0 = -horiz * math.sin(a.heading)
            z0 = a.distance * math.sin(a.angle)
            # |v0| = vz0 * sqrt(1 + (x0/(kx z0))^2 + (y0/(ky z0))^2)   (docs/design.md §1)
            denom = math.sqrt(1.0 + (x0 / (c.kappa.x * z0)) ** 2 + (y0 / (c.kappa.y * z0)) ** 2)
            v0 = a.speed / denom
        else:
            assert c.initial.position is not None
            assert c.initial.descent_rate is not None
            x0, y0, z0 = c.initial.position
            v0 = c.initial.descent_rate
        roll0, pitch0, yaw0 = c.initial.rpy
        self.initial_gaps: F64 = np.array([x0, y0, z0, roll0, pitch0, yaw0], dtype=np.float64)
        self.descent_rate = float(v0)
        self.k = float(c.k)
        self.T = z0 / (self.k * v0)
        """Touchdown time, s."""
        self.tau0 = -self.T * self.k
        """tau of the height gap at t = 0 (s, negative by the paper's convention)."""
        self.kappas: F64 = np.array(
            [c.kappa.x, c.kappa.y, 1.0, c.kappa.roll, c.kappa.pitch, c.kappa.yaw]
        )
        self.exponents: F64 = np.array([exponent(self.k * kap) for kap in self.kappas])
        self.terminal: dict[str, Terminal] = {
            g: classify(self.k * kap, float(g0))
            for g, kap, g0 in zip(GAPS, self.kappas, self.initial_gaps, strict=True)
        }
        self.hold = float(c.hold)
        self.duration = self.T + self.hold
        """Touchdown time plus hold, s."""
        check_duration(self.duration, float(c.sample_dt), self.T)
        self.R_world_goal: F64 = rpy_to_matrix(np.asarray(c.goal.rpy))
        self.p_world_goal: F64 = np.asarray(c.goal.position, dtype=np.float64)
        self._q_world_goal: F64 = rpy_to_quat_xyzw(np.asarray(c.goal.rpy))
        flap = c.flapping
        self._flap = flap if flap.enabled else None
        self._instant: InstantEvaluator | None = None
        if warn:
            for message in self.warnings():
                warnings.warn(message, TrajectoryWarning, stacklevel=2)

    # ------------------------------------------------------------------ reports
    def warnings(self) -> list[str]:
        """Human-readable notes on hard terminal behaviour (empty for a soft landing)."""
        out = []
        for g, term in self.terminal.items():
            kap = self.kappas[GAPS.index(g)]
            what = "k" if g == "z" else f"k*kappa.{g}"
            val = self.k * kap
            if term is Terminal.UNBOUNDED_DECELERATION:
                out.append(
                    f"{g} gap: {what} = {val:.4g} in (0.5, 1): its rate reaches 0 but the "
                    "required deceleration grows without bound near touchdown"
                )
            elif term is Terminal.NONZERO_RATE:
                out.append(
                    f"{g} gap: {what} = {val:.4g}: the gap closes at a non-zero rate "
                    "(contact with speed on this axis)"
                )
        return out

    def summary(self) -> dict[str, Any]:
        """Touchdown time, tau0, parameters, terminal behaviour, peaks (JSON-ready).

        Peaks are taken over 20001 instants on [0, T]. ``peak_deceleration`` is the
        largest braking component of the acceleration along the velocity (m/s^2); it is
        None when a gap's deceleration grows without bound (see ``terminal``).
        """
        t = np.linspace(0.0, self.T, 20001)
        st = self.state(t)
        speed = np.linalg.norm(st.velocity, axis=1)
        # deceleration along the direction of motion (positive when braking)
        along = -np.sum(st.acceleration * st.velocity, axis=1) / np.where(speed > 0, speed, 1.0)
        unbounded = any(
            term is Terminal.UNBOUNDED_DECELERATION
            for g, term in self.terminal.items()
            if g in ("x", "y", "z")
        )
        kappa = dict(
            zip(
                ("x", "y", "roll", "pitch", "yaw"),
                self.kappas[[0, 1, 3, 4, 5]].tolist(),
                strict=True,
            )
        )
        return {
            "T": self.T,
            "touchdown_time": self.T,
            "duration": self.duration,
            "goal": self.config.goal.model_dump(mode="json"),
            "tau0": self.tau0,
            "k": self.k,
            "kappa": kappa,
            "initial_gaps": dict(zip(GAPS, self.initial_gaps.tolist(), strict=True)),
            "descent_rate": self.descent_rate,
            "initial_speed": float(speed[0]),
            "terminal": {g: term.value for g, term in self.terminal.items()},
            "peak_speed": float(speed.max()),
            "peak_deceleration": None if unbounded else float(max(along.max(), 0.0)),
            "peak_acceleration_norm": (
                None if unbounded else float(np.linalg.norm(st.acceleration, axis=1).max())
            ),
            "flapping": self._flap is not None,
            "warnings": self.warnings(),
        }

    # ------------------------------------------------------------------ sampling
    def table_times(self) -> F64:
        """Instants of the exported table (s): every ``sample_dt`` from 0 up to T, exactly T,
        then every ``sample_dt`` after T through the hold, ending exactly at T + hold."""
        return table_times(self.T, self.hold, self.config.sample_dt)

    def gaps_at(self, t: ArrayLike) -> tuple[F64, F64, F64, F64]:
        """The 18 components in F: (t, gaps, rates, accels), each (N,) / (N, 6)."""
        tt = np.atleast_1d(np.asarray(t, dtype=np.float64)).ravel()
        n = tt.shape[0]
        gaps = np.empty((n, 6))
        rates = np.empty((n, 6))
        accels = np.empty((n, 6))
        for a in range(0, n, CHUNK):
            sl = slice(a, a + CHUNK)
            self._gaps_into(tt[sl], gaps[sl], rates[sl], accels[sl])
        return tt, gaps, rates, accels

    def _gaps_into(self, tt: F64, gaps: F64, rates: F64, accels: F64) -> None:
        """Fill (n, 6) gaps, rates, accels at the instants tt (n,) in place."""
        T = self.T
        # s = 1 - t/T in [0, 1]; s = 0 exactly at t = T
        s = 1.0 - tt / T
        np.clip(s, 0.0, 1.0, out=s)
        # one power per distinct exponent (gaps with equal kappa share it)
        cache: dict[float, tuple[F64, F64, F64]] = {}
        for i in range(6):
            g0 = float(self.initial_gaps[i])
            if g0 == 0.0:
                gaps[:, i] = 0.0
                rates[:, i] = 0.0
                accels[:, i] = 0.0
                continue
            e = float(self.exponents[i])
            if e not in cache:
                cache[e] = powers(s, e)
            p0, p1, p2 = cache[e]
            np.multiply(p0, g0, out=gaps[:, i])
            np.multiply(p1, -g0 * e / T, out=rates[:, i])
            np.multiply(p2, g0 * e * (e - 1.0) / (T * T), out=accels[:, i])
        if self._flap is not None:
            self._add_flapping(np.clip(tt, 0.0, None), gaps, rates, accels)
        # at rest before the start (t < 0 clamps to the start) and after touchdown
        after = tt > T
        if after.any():
            gaps[after] = 0.0
            rates[after] = 0.0
            accels[after] = 0.0
        before = tt < 0.0
        if before.any():
            rates[before] = 0.0
            accels[before] = 0.0

    def _add_flapping(self, tc: F64, gaps: F64, rates: F64, accels: F64) -> None:
        """Superimpose heave (on z) and pitch oscillation, faded by e = z/z0 (in place)."""
        assert self._flap is not None
        add_flapping(self._flap, float(self.initial_gaps[2]), tc, gaps, rates, accels)

    def pose_twist_ns(self, t_ns: int) -> tuple[F64, F64, F64, F64]:
        """(3,) position, (3,) velocity, (3, 3) R_world_body and (3,) omega_body at one
        instant: :meth:`state_ns`'s values, bit for bit, ~20x cheaper
        (:class:`~roslan.trajectory.instant.InstantEvaluator`)."""
        if self._instant is None:
            self._instant = InstantEvaluator(self)
        return self._instant.pose_twist_ns(t_ns)

    def state(self, t: ArrayLike) -> State:
        """Full state at instants ``t`` (s), shape (N,).

        Evaluated in blocks of :data:`CHUNK` instants written straight into the result
        arrays, so the temporaries stay in cache whatever N is.
        """
        tt = np.atleast_1d(np.asarray(t, dtype=np.float64)).ravel()
        n = tt.shape[0]
        gaps, rates, accels = np.empty((n, 6)), np.empty((n, 6)), np.empty((n, 6))
        position, velocity, acceleration = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
        R_world_body = np.empty((n, 3, 3))
        quat, omega, alpha = np.empty((n, 4)), np.empty((n, 3)), np.empty((n, 3))
        RT = np.ascontiguousarray(self.R_world_goal.T)
        for a in range(0, n, CHUNK):
            sl = slice(a, a + CHUNK)
            g, r, ac = gaps[sl], rates[sl], accels[sl]
            self._gaps_into(tt[sl], g, r, ac)
            fill_pose(
                (g, r, ac),
                (RT, self.p_world_goal, self._q_world_goal),
                (position[sl], velocity[sl], acceleration[sl]),
                (quat[sl], R_world_body[sl], omega[sl], alpha[sl]),
            )
        return State(
            t=tt,
            gaps=gaps,
            rates=rates,
            accels=accels,
            position=position,
            velocity=velocity,
            acceleration=acceleration,
            R_world_body=R_world_body,
            quat_xyzw=quat,
            omega_body=omega,
            alpha_body=alpha,
        )
