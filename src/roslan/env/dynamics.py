"""The closed-loop vehicle: a rigid body flown by commanded acceleration and body rates.

Model (docs/design.md §7). The state lives in the goal frame F, like the closed-form
landing's: the position gaps ``x, y, z`` of base_link (m) and the ZYX Euler gaps ``roll,
pitch, yaw`` relative to F (rad), with their rates. Each control step holds one command:

* a world-frame linear acceleration ``a_cmd`` of base_link (m/s^2; the flyer's wings
  supply it, gravity included, so the IMU's specific force is ``a - g``), reached through a
  first-order lag ``tau_a``: ``da/dt = (a_cmd - a) / tau_a``;
* body rates ``omega_cmd`` (rad/s, base_link), turned at the step's start into the Euler
  rates that give them at that attitude, reached through a first-order lag ``tau_r``.

Attitude is commanded, not derived from the acceleration: a flapping flyer points its
forces with its wings, and tau theory closes the roll, pitch and yaw gaps on their own.
With a piecewise-constant command the lagged state has a closed form inside each step
(:func:`_evaluate`), so sensors may sample the vehicle at any instant up to the horizon.
Flapping is superimposed exactly as on the closed-form landing
(:func:`roslan.trajectory.generator.add_flapping`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from roslan.config.closed_loop import Dynamics
from roslan.frames import body_rates_to_euler_rates, rpy_to_matrix, rpy_to_quat_xyzw
from roslan.trajectory.base import GAPS, HorizonError, State, Trajectory
from roslan.trajectory.config import TrajectoryConfig
from roslan.trajectory.generator import TauTrajectory, add_flapping, fill_pose, table_times

__all__ = [
    "DynamicsTrajectory",
    "MeanState",
]

F64 = NDArray[np.float64]

MAX_PITCH = 1.4
"""|pitch gap| (rad) beyond which the Euler-rate map is too close to its singularity."""


@dataclass(frozen=True)
class MeanState:
    """The vehicle's state without flapping, in F, at one instant (the controller's view).

    Attributes:
        t: trajectory time, s.
        gaps, rates, accels: (6,) in :data:`~roslan.trajectory.base.GAPS` order (m, rad;
            m/s, rad/s; m/s^2, rad/s^2).
    """

    t: float
    gaps: F64
    rates: F64
    accels: F64


def _lag(u: F64, tau: float) -> tuple[F64, F64, F64]:
    """Response of a first-order lag to a unit step after ``u`` s: ``E = exp(-u/tau)`` and
    its integrals ``tau (1 - E)`` and ``tau (u - tau (1 - E))``; (0, 0, 0) for tau = 0."""
    if tau <= 0.0:
        z = np.zeros_like(u)
        return z, z.copy(), z.copy()
    E = np.exp(-u / tau)
    i1 = tau * (1.0 - E)
    return E, i1, tau * (u - i1)


def _evaluate(u: F64, start: F64, cmd: F64, lags: tuple[float, float]) -> tuple[F64, F64, F64]:
    """Closed form inside steps: (n, 6) gaps, rates, accels after ``u`` (n,) s of steps
    whose start states ``start`` are (n, 15) (gaps, rates, linear acceleration) and whose
    commands ``cmd`` are (n, 6) (acceleration in F, Euler rates)."""
    g0, r0, a0 = start[:, :6], start[:, 6:12], start[:, 12:15]
    uc = u[:, None]
    gaps = np.empty((u.shape[0], 6))
    rates = np.empty_like(gaps)
    accels = np.empty_like(gaps)
    # linear: da/dt = (c - a) / tau_a
    E, i1, i2 = (x[:, None] for x in _lag(u, lags[0]))
    c, d = cmd[:, :3], a0 - cmd[:, :3]
    accels[:, :3] = c + d * E
    rates[:, :3] = r0[:, :3] + c * uc + d * i1
    gaps[:, :3] = g0[:, :3] + r0[:, :3] * uc + 0.5 * c * uc * uc + d * i2
    # angular: d(rate)/dt = (c - rate) / tau_r
    E, i1, _ = (x[:, None] for x in _lag(u, lags[1]))
    c, d = cmd[:, 3:], r0[:, 3:] - cmd[:, 3:]
    rates[:, 3:] = c + d * E
    gaps[:, 3:] = g0[:, 3:] + c * uc + d * i1
    accels[:, 3:] = -d * E / lags[1] if lags[1] > 0.0 else 0.0
    return gaps, rates, accels


class DynamicsTrajectory(Trajectory):
    """base_link's path in closed loop: grows one control step per :meth:`step`.

    Readable (``state``...) on ``[0, horizon_ns]``; reading later raises
    :class:`~roslan.trajectory.base.HorizonError` until :meth:`finish`, after which the
    vehicle rests at its touchdown pose for ``config.hold`` seconds, like a closed-form
    landing. ``T`` and ``duration`` are meaningful once ``finished``.

    Args:
        config: the ``trajectory:`` block with base_link's goal
            (:func:`roslan.vehicle.base_link_trajectory`); its start state is the closed-form
            landing's at t = 0 (``initial`` or ``approach``; gaps and rates, without
            flapping); its flapping is superimposed. The start's linear acceleration is
            the closed form's, each world component limited to +-``max_acceleration``
            (:attr:`start_limited`).
        dynamics: actuator bounds and lags (the bounds are the environment's to apply).
        step_ns: control period, integer ns.
    """

    def __init__(self, config: TrajectoryConfig, dynamics: Dynamics, step_ns: int) -> None:
        self.config = config
        self.dynamics = dynamics
        self.step_ns = int(step_ns)
        smooth = config.model_copy(update={"flapping": type(config.flapping)()})
        ref = TauTrajectory(smooth, warn=False)
        self.reference_T = float(ref.T)
        """Touchdown time of the closed-form landing from the same start, s."""
        s0 = ref.state([0.0])
        self.z0 = float(ref.initial_gaps[2])
        self.R_world_goal: F64 = rpy_to_matrix(np.asarray(config.goal.rpy))
        self.p_world_goal: F64 = np.asarray(config.goal.position, dtype=np.float64)
        self._q_world_goal: F64 = rpy_to_quat_xyzw(np.asarray(config.goal.rpy))
        self._RT = np.ascontiguousarray(self.R_world_goal.T)
        self._flap = config.flapping if config.flapping.enabled else None
        self._lags = (float(dynamics.acceleration_lag), float(dynamics.body_rate_lag))
        first = np.concatenate([s0.gaps[0], s0.rates[0], s0.accels[0, :3]])
        # the actuator's acceleration stays within its command range, at the start too
        self.start_acceleration: F64 = self.R_world_goal @ s0.accels[0, :3]
        """The closed form's acceleration at t = 0 in the world (m/s^2), before limiting."""
        bound = float(dynamics.max_acceleration)
        self.start_limited = bool(np.any(np.abs(self.start_acceleration) > bound))
        """True when the start's acceleration was limited to +-``max_acceleration``."""
        if self.start_limited:
            first[12:15] = self._RT @ np.clip(self.start_acceleration, -bound, bound)
        # step start states (n + 1, 15) and commands (n, 6), in buffers grown by doubling
        self._n = 0
        self._start_buf = np.zeros((64, 15))
        self._cmd_buf = np.zeros((64, 6))
        self._start_buf[0] = first
        self._horizon_ns = 0
        self._end_ns: int | None = None
        self.hold = float(config.hold)
        self.T = math.inf
        self.duration = math.inf

    # ------------------------------------------------------------------ growing
    @property
    def horizon_ns(self) -> int:
        """Latest readable instant (ns); the end of the run once finished."""
        return self.duration_ns if self._end_ns is not None else self._horizon_ns

    @property
    def finished(self) -> bool:
        return self._end_ns is not None

    @property
    def steps(self) -> int:
        """Control steps flown."""
        return self._n

    def mean_state(self) -> MeanState:
        """The state (no flapping) at the horizon: what a state-feedback controller reads."""
        start = self._start_buf[self._n]
        return MeanState(
            t=self._horizon_ns * 1e-9,
            gaps=start[:6].copy(),
            rates=start[6:12].copy(),
            accels=np.concatenate([start[12:15], np.zeros(3)]),
        )

    def step(self, accel_world: ArrayLike, body_rates: ArrayLike) -> None:
        """Fly one control step holding a command (already checked and bounded).

        Args:
            accel_world: (3,) commanded acceleration of base_link in the world, m/s^2.
            body_rates: (3,) commanded body rates (roll, pitch, yaw), rad/s.
        """
        if self._end_ns is not None:
            msg = "the closed-loop trajectory is finished; no more steps"
            raise HorizonError(msg)
        start = self._start_buf[self._n].copy()
        a_goal = self.R_world_goal.T @ np.asarray(accel_world, dtype=np.float64)
        e_rates = body_rates_to_euler_rates(start[3:6], np.asarray(body_rates, dtype=float))
        cmd = np.concatenate([a_goal, e_rates])
        n = self._n
        if n + 1 >= self._cmd_buf.shape[0]:
            self._start_buf = np.concatenate([self._start_buf, np.zeros_like(self._start_buf)])
            self._cmd_buf = np.concatenate([self._cmd_buf, np.zeros_like(self._cmd_buf)])
        self._cmd_buf[n] = cmd
        u = np.array([self.step_ns * 1e-9])
        g, r, a = _evaluate(u, start[None, :], cmd[None, :], self._lags)
        self._start_buf[n + 1] = np.concatenate([g[0], r[0], a[0, :3]])
        self._n = n + 1
        self._horizon_ns += self.step_ns

    def finish(self, end_ns: int) -> None:
        """End the motion at ``end_ns`` (touchdown or the episode's end, <= the horizon):
        the vehicle then rests there for ``hold`` s; everything up to ``duration`` is
        readable."""
        if not 0 <= end_ns <= self._horizon_ns:
            msg = f"finish at {end_ns} ns: outside [0, horizon {self._horizon_ns} ns]"
            raise HorizonError(msg)
        self._end_ns = int(end_ns)
        self.T = end_ns * 1e-9
        self.duration = self.T + self.hold

    @property
    def duration_ns(self) -> int:
        if self._end_ns is None:
            return self._horizon_ns
        return self._end_ns + round(self.hold * 1e9)

    @property
    def touchdown_ns(self) -> int:
        return self._end_ns if self._end_ns is not None else self._horizon_ns

    # ------------------------------------------------------------------ sampling
    def _mean(self, tt: F64) -> tuple[F64, F64, F64]:
        """(n, 6) gaps, rates, accels without flapping at instants tt (s) in [0, horizon]."""
        starts, cmds = self._start_buf[: self._n + 1], self._cmd_buf[: self._n]
        t0 = np.arange(starts.shape[0]) * (self.step_ns * 1e-9)
        k = np.clip(np.searchsorted(t0, tt, side="right") - 1, 0, None)
        last = cmds.shape[0]
        inside = k < last
        gaps = starts[k, :6].copy()
        rates = starts[k, 6:12].copy()
        accels = np.zeros((tt.shape[0], 6))
        accels[:, :3] = starts[k, 12:15]
        if inside.any():
            ki = k[inside]
            u = np.clip(tt[inside] - t0[ki], 0.0, None)
            g, r, a = _evaluate(u, starts[ki], cmds[ki], self._lags)
            gaps[inside], rates[inside], accels[inside] = g, r, a
        return gaps, rates, accels

    def _check(self, tt: F64) -> None:
        if self._end_ns is not None or tt.size == 0:
            return
        late = float(tt.max())
        if late * 1e9 > self._horizon_ns + 0.5:
            msg = (
                f"closed-loop trajectory read at t = {late:.9f} s, past its horizon "
                f"{self._horizon_ns * 1e-9:.9f} s (a sensor looked ahead)"
            )
            raise HorizonError(msg)

    def gaps_at(self, t: ArrayLike) -> tuple[F64, F64, F64, F64]:
        """The 18 components in F (flapping included): (t, gaps, rates, accels)."""
        tt = np.atleast_1d(np.asarray(t, dtype=np.float64)).ravel()
        self._check(tt)
        tc = np.clip(tt, 0.0, None if self._end_ns is None else self.T)
        gaps, rates, accels = self._mean(tc)
        if self._flap is not None:
            add_flapping(self._flap, self.z0, tc, gaps, rates, accels)
        before = tt < 0.0
        rest = tt > self.T
        rates[before | rest] = 0.0
        accels[before | rest] = 0.0
        return tt, gaps, rates, accels

    def state(self, t: ArrayLike) -> State:
        """Full state at instants ``t`` (s), shape (N,)."""
        tt, gaps, rates, accels = self.gaps_at(t)
        n = tt.shape[0]
        position, velocity, acceleration = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
        R = np.empty((n, 3, 3))
        quat, omega, alpha = np.empty((n, 4)), np.empty((n, 3)), np.empty((n, 3))
        fill_pose(
            (gaps, rates, accels),
            (self._RT, self.p_world_goal, self._q_world_goal),
            (position, velocity, acceleration),
            (quat, R, omega, alpha),
        )
        return State(
            tt, gaps, rates, accels, position, velocity, acceleration, R, quat, omega, alpha
        )

    def table_times(self) -> F64:
        """Every ``sample_dt`` up to the touchdown, the touchdown, then through the hold."""
        T = self.T if self._end_ns is not None else self._horizon_ns * 1e-9
        return table_times(T, self.hold, self.config.sample_dt)

    def warnings(self) -> list[str]:
        return []

    def summary(self) -> dict[str, Any]:
        """JSON-ready: touchdown time, duration, goal, start gaps, the dynamics model."""
        T = self.T if self._end_ns is not None else self._horizon_ns * 1e-9
        return {
            "T": T,
            "touchdown_time": T,
            "duration": T + self.hold,
            "goal": self.config.goal.model_dump(mode="json"),
            "closed_loop": True,
            "control_rate": 1e9 / self.step_ns,
            "steps": self.steps,
            "dynamics": self.dynamics.model_dump(mode="json"),
            "initial_gaps": dict(zip(GAPS, self._start_buf[0, :6].tolist(), strict=True)),
            "reference_touchdown_time": self.reference_T,
            "flapping": self._flap is not None,
            "warnings": [],
        }
