"""Packaged landing policies, each a ``roslan fly --policy NAME``.

A policy is reset with a :class:`PolicyContext` at the start of each episode, then maps
each step's observation and info to an action (6,): the world-frame acceleration command
(m/s^2) and the body-rate command (rad/s) of :class:`roslan.env.LandingEnv`.

* ``tau-state`` (an oracle by design): tau-dot guidance on every gap with tau coupling,
  from the true state (``info["state"]``): the closed-form landing's own controller.
* ``constant-descent`` (an oracle by design): a naive baseline, from the true state.
* ``tau-events``: from the observation and the context only (event camera, IMU, the start
  estimate; :mod:`roslan.env.tau_events`), landed with constant tau-dot.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray

from roslan.errors import ConfigError
from roslan.frames import euler_rates_to_body_rates
from roslan.trajectory.tau import exponent

if TYPE_CHECKING:
    from roslan.config.sim import SimConfig

__all__ = [
    "POLICIES",
    "ConstantDescentPolicy",
    "Policy",
    "PolicyContext",
    "TauStatePolicy",
    "make_policy",
]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class PolicyContext:
    """What a policy may know before the first step (:mod:`roslan.env.knowledge`).

    Attributes:
        config: the validated config, nominal: the vehicle (sensors, calibration, body,
            feet) and the trajectory block as written (``k``, ``kappa``, the nominal
            ``initial``; not the start drawn by ``closed_loop.start_spread``).
        control_dt: control period, s.
        R_world_goal: (3, 3) orientation of the goal frame F in the world.
        max_acceleration, max_body_rate: the action bounds (m/s^2, rad/s).
        start_estimate: the navigation filter's start state
            (:class:`~roslan.env.knowledge.StartEstimate`; None: not told).
        goal_position: (3,) the goal in the world (where the contact point lands), m.
        base_link_goal: (3,) base_link's position at touchdown on the goal, world, m.
    """

    config: SimConfig
    control_dt: float
    R_world_goal: F64
    max_acceleration: float
    max_body_rate: float
    start_estimate: Any = None  # roslan.env.knowledge.StartEstimate (no import: no cycle)
    goal_position: F64 | None = None
    base_link_goal: F64 | None = None


class Policy(Protocol):
    """A landing controller."""

    def reset(self, context: PolicyContext) -> None:
        """Start an episode."""
        ...

    def act(self, observation: Mapping[str, Any], info: Mapping[str, Any]) -> F64:
        """(6,) action: world acceleration (m/s^2), body rates (rad/s)."""
        ...


def _guide(G: float, e: float, t_rem: float, u: float) -> tuple[float, float, float, float]:
    """Tau guide ``G (t_rem - u) ** e`` and its first three time derivatives at ``u``."""
    r = max(t_rem - u, 0.0)
    p0 = G * r**e
    p1 = -e * G * r ** (e - 1.0) if r > 0.0 or e > 1.0 else 0.0
    p2 = e * (e - 1.0) * G * r ** (e - 2.0) if r > 0.0 or e > 2.0 else 0.0
    p3 = -e * (e - 1.0) * (e - 2.0) * G * r ** (e - 3.0) if r > 0.0 or e > 3.0 else 0.0
    return p0, p1, p2, p3


class TauStatePolicy:
    """Tau-dot guidance on all six gaps from the true state (the closed form's controller).

    The height gap closes with constant tau-dot ``k``: the time left is
    ``t_rem = -z / (k dz/dt)``, and the height command is the mean acceleration of the
    constant-tau-dot guide through the current state over the next step. Every other gap g
    is tau-coupled to it (tau_g = kappa_g tau_z): its guide is ``G (t_rem - u) ** e`` with
    ``e = 1 / (k kappa_g)`` and ``G`` fixed at the first step, tracked by state feedback
    (gap, rate and, with an actuator lag, acceleration; poles at -8 rad/s). With zero lag,
    on the guide, the command is the guide's mean acceleration (rate) over the step, so the
    landing is the closed form's.
    """

    OMEGA = 8.0
    """Bandwidth of the tracking loops, rad/s."""

    def __init__(self) -> None:
        self._ctx: PolicyContext | None = None
        self._exp = np.ones(6)
        self._k = 0.5
        self._lags = (0.0, 0.0)
        self._G: F64 | None = None

    def reset(self, context: PolicyContext) -> None:
        self._ctx = context
        tr = context.config.trajectory
        kap = tr.kappa
        self._k = float(tr.k)
        self._exp = np.array(
            [exponent(self._k * c) for c in (kap.x, kap.y, 1.0, kap.roll, kap.pitch, kap.yaw)]
        )
        cl = context.config.closed_loop
        dyn = None if cl is None else cl.dynamics
        self._lags = (0.0, 0.0) if dyn is None else (dyn.acceleration_lag, dyn.body_rate_lag)
        self._G = None

    def act(self, observation: Mapping[str, Any], info: Mapping[str, Any]) -> F64:
        del observation
        assert self._ctx is not None, "reset() first"
        dt = self._ctx.control_dt
        st = info["state"]
        g = np.asarray(st["gaps"], dtype=np.float64)
        v = np.asarray(st["rates"], dtype=np.float64)
        a = np.asarray(st.get("accels", np.zeros(6)), dtype=np.float64)
        z, vz = float(g[2]), float(v[2])
        # time left on the height gap's constant-tau-dot guide (a climbing or hovering
        # vehicle gets the guide that starts now at 0.5 m/s)
        t_rem = -z / (self._k * vz) if vz < -1e-6 else z / (self._k * 0.5)
        t_rem = max(t_rem, 1e-6)
        if self._G is None:
            self._G = g / t_rem**self._exp
        G = self._G.copy()
        G[2] = z / t_rem ** self._exp[2]  # the height guide passes through the state
        w = self.OMEGA
        tau_a, tau_r = self._lags
        acc = np.empty(3)
        for i in range(3):
            p0, v0, a0, j0 = _guide(float(G[i]), float(self._exp[i]), t_rem, 0.0)
            v1 = _guide(float(G[i]), float(self._exp[i]), t_rem, dt)[1]
            mean_a = (v1 - v0) / dt
            if tau_a > 0.0:
                k1, k2, k3 = w**3 * tau_a, 3.0 * w * w * tau_a, 3.0 * w * tau_a - 1.0
                acc[i] = (
                    mean_a + tau_a * j0 + k1 * (p0 - g[i]) + k2 * (v0 - v[i]) + k3 * (a0 - a[i])
                )
            else:
                acc[i] = (v1 - v[i]) / dt + w * w * (p0 - g[i])
        e_rates = np.empty(3)
        for i in range(3, 6):
            p0, v0, a0, _ = _guide(float(G[i]), float(self._exp[i]), t_rem, 0.0)
            p1 = _guide(float(G[i]), float(self._exp[i]), t_rem, dt)[0]
            if tau_r > 0.0:
                k1, k2 = w * w * tau_r, 2.0 * w * tau_r - 1.0
                e_rates[i - 3] = (p1 - p0) / dt + tau_r * a0 + k1 * (p0 - g[i]) + k2 * (v0 - v[i])
            else:
                e_rates[i - 3] = (p1 - g[i]) / dt
        out = np.empty(6)
        out[:3] = self._ctx.R_world_goal @ acc
        out[3:] = euler_rates_to_body_rates(g[3:], e_rates)
        return out


class ConstantDescentPolicy:
    """Naive baseline: descend at a constant ``speed`` (m/s) while a PD law centres the
    vehicle over the goal (time constant ``horizontal_time``, s) and levels its attitude
    gaps; no braking at all before contact."""

    def __init__(self, speed: float = 0.6, horizontal_time: float = 1.0) -> None:
        self.speed = float(speed)
        self.horizontal_time = float(horizontal_time)
        self._ctx: PolicyContext | None = None

    def reset(self, context: PolicyContext) -> None:
        self._ctx = context

    def act(self, observation: Mapping[str, Any], info: Mapping[str, Any]) -> F64:
        del observation
        assert self._ctx is not None, "reset() first"
        st = info["state"]
        g = np.asarray(st["gaps"], dtype=np.float64)
        v = np.asarray(st["rates"], dtype=np.float64)
        tc = self.horizontal_time
        # critically damped PD on x, y; first-order speed tracking on z
        acc = np.empty(3)
        acc[:2] = -g[:2] / (tc * tc) - 2.0 * v[:2] / tc
        acc[2] = (-self.speed - v[2]) / (0.5 * tc)
        e_rates = -g[3:] / tc
        out = np.empty(6)
        out[:3] = self._ctx.R_world_goal @ acc
        out[3:] = euler_rates_to_body_rates(g[3:], e_rates)
        return out


POLICIES: dict[str, str] = {
    "tau-state": "roslan.env.policies:TauStatePolicy",
    "constant-descent": "roslan.env.policies:ConstantDescentPolicy",
    "tau-events": "roslan.env.tau_events:TauEventsPolicy",
}
"""``--policy`` names and the classes behind them (``module:Class``, imported on use)."""


def make_policy(name: str) -> Policy:
    """A new policy by its ``--policy`` name.

    Raises:
        ConfigError: unknown name (the message lists the allowed ones).
    """
    if name not in POLICIES:
        msg = f"--policy {name!r}: unknown policy; allowed: {', '.join(sorted(POLICIES))}"
        raise ConfigError(msg)
    module, cls = POLICIES[name].split(":")
    policy: Policy = getattr(importlib.import_module(module), cls)()
    return policy
