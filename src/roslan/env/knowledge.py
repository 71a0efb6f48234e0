"""What a policy may know: the start estimate, the goal, and the policy's context.

The information boundary (docs/guide/closed-loop.md "What a policy knows"):

* before the first step: the vehicle's own configuration (sensor mounts, calibration,
  body, feet) and the trajectory block **as written** (the nominal start, ``k``,
  ``kappa``), the goal pose in the world, the action bounds and the control period, and
  the :class:`StartEstimate`: the true start plus an error drawn per episode
  (``closed_loop.start_estimate``), as an onboard navigation filter reports it when the
  landing begins;
* every step: the observation;
* never: the drawn start (``closed_loop.start_spread``), the true state, or anything
  derived from them (``info["state"]`` is for evaluation and for the oracle baselines).

The Gymnasium observation carries the same knowledge for a learning agent: the constant
entries ``start_estimate`` and ``goal`` (:data:`CONSTANT_SHAPES`, :func:`constant_observation`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from roslan.frames import matrix_to_rpy

if TYPE_CHECKING:
    from roslan.config.closed_loop import StartEstimateConfig
    from roslan.env.dynamics import DynamicsTrajectory
    from roslan.env.policies import PolicyContext

__all__ = [
    "CONSTANT_SHAPES",
    "ESTIMATE_STREAM",
    "StartEstimate",
    "constant_observation",
    "draw_start_estimate",
    "policy_context",
]

F64 = NDArray[np.float64]

ESTIMATE_STREAM = 0xE5717
"""The start estimate's generator: ``[seed, ESTIMATE_STREAM]`` (the start spread's and the
sensors' draws do not change with it)."""


@dataclass(frozen=True, eq=False)
class StartEstimate:
    """base_link's state at t = 0 as the vehicle's navigation filter reports it.

    Attributes:
        position: (3,) in the world, m.
        velocity: (3,) in the world, m/s (the flapping body's, as a filter tracks it).
        R_world_body: (3, 3) attitude.
        gaps: (6,) the same position and attitude as gaps to base_link's goal in the goal
            frame F (x, y, z m; roll, pitch, yaw rad), the convention of ``info["state"]``.
        rates: (3,) the velocity in F, m/s.
    """

    position: F64
    velocity: F64
    R_world_body: F64
    gaps: F64
    rates: F64

    def as_observation(self) -> NDArray[np.float32]:
        """(9,) float32: ``gaps[:3]`` (m), ``rates`` (m/s), ``gaps[3:]`` (rad), all in F."""
        return np.concatenate([self.gaps[:3], self.rates, self.gaps[3:]]).astype(np.float32)


def _expm(w: F64) -> F64:
    th = float(np.linalg.norm(w))
    k = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    if th < 1e-12:
        return np.asarray(np.eye(3) + k, dtype=np.float64)
    return np.asarray(
        np.eye(3) + np.sin(th) / th * k + (1.0 - np.cos(th)) / th**2 * (k @ k), dtype=np.float64
    )


def draw_start_estimate(
    traj: DynamicsTrajectory, config: StartEstimateConfig, seed: int
) -> StartEstimate:
    """The start estimate of an episode: the true state of ``traj`` at t = 0 (flapping
    included) plus Gaussian errors of ``config``'s sigmas, drawn from ``seed`` on
    :data:`ESTIMATE_STREAM` (position and velocity per world axis, attitude a rotation of
    per-body-axis angles)."""
    st = traj.state([0.0])
    rng = np.random.default_rng([int(seed), ESTIMATE_STREAM])
    u = rng.standard_normal(9)
    p = st.position[0] + config.position_sigma * u[0:3]
    v = st.velocity[0] + config.velocity_sigma * u[3:6]
    R = st.R_world_body[0] @ _expm(config.attitude_sigma * u[6:9])
    Rwg, pg = traj.R_world_goal, traj.p_world_goal
    gaps = np.concatenate([Rwg.T @ (p - pg), matrix_to_rpy(Rwg.T @ R)])
    return StartEstimate(p, v, R, gaps, Rwg.T @ v)


CONSTANT_SHAPES: dict[str, tuple[int, ...]] = {"start_estimate": (9,), "goal": (6,)}
"""The observation's constant entries and their shapes (:func:`constant_observation`);
:class:`~roslan.env.observe.ObservationBuilder.constant` holds them."""


def constant_observation(estimate: StartEstimate, goal: Any) -> dict[str, NDArray[np.float32]]:
    """``start_estimate`` (:meth:`StartEstimate.as_observation`) and ``goal``: (6,) the
    goal's position (m, where the contact point lands) and roll, pitch, yaw (rad) in the
    world."""
    g = np.array([*goal.position, *goal.rpy], dtype=np.float32)
    return {"start_estimate": estimate.as_observation(), "goal": g}


def policy_context(env: Any) -> PolicyContext:
    """The :class:`~roslan.env.policies.PolicyContext` of ``env``'s episode (a
    :class:`~roslan.env.landing.LandingEnv`, after
    ``reset``): the nominal config (``trajectory.initial`` as written, the episode's
    seed), the control period, the goal, the action bounds and the start estimate."""
    from roslan.env.policies import PolicyContext

    traj = env._traj
    assert traj is not None, "reset() first"
    dyn = env.closed_loop.dynamics
    nominal = env.base_config.model_copy(update={"seed": env.config.seed})
    goal = env.goal
    assert goal is not None, "reset() first"
    return PolicyContext(
        nominal,
        env.dt,
        traj.R_world_goal.copy(),
        dyn.max_acceleration,
        dyn.max_body_rate,
        start_estimate=env.start_estimate,
        goal_position=np.asarray(goal.position, dtype=np.float64),
        base_link_goal=traj.p_world_goal.copy(),
    )
