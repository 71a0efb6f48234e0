"""The ``closed_loop:`` config block: how :class:`roslan.env.LandingEnv` and ``roslan fly``
fly the vehicle (control rate, actuator bounds and lags, observation, reward).

``roslan simulate`` ignores the block; a config without it gets these defaults
(docs/guide/closed-loop.md).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from roslan.config.base import FiniteFloat, StrictModel
from roslan.limits import MAX_DURATION_S

__all__ = [
    "ClosedLoopConfig",
    "Dynamics",
    "ObservationConfig",
    "RewardConfig",
    "StartEstimateConfig",
    "StartSpread",
    "SuccessConfig",
]

NonNegative = Annotated[FiniteFloat, Field(ge=0.0)]
Lag = Annotated[FiniteFloat, Field(ge=0.0, le=10.0)]


class Dynamics(StrictModel):
    """Actuator bounds and first-order lags (docs/design.md §7)."""

    max_acceleration: Annotated[FiniteFloat, Field(gt=0.0, le=1000.0)] = 20.0
    """Bound of each component of the commanded world-frame acceleration, m/s^2."""
    max_body_rate: Annotated[FiniteFloat, Field(gt=0.0, le=100.0)] = 4.0
    """Bound of each commanded body rate (roll, pitch, yaw), rad/s."""
    acceleration_lag: Lag = 0.05
    """Time constant of the acceleration actuator, s (0: the command acts at once)."""
    body_rate_lag: Lag = 0.03
    """Time constant of the body-rate actuator, s (0: the command acts at once)."""


class ObservationConfig(StrictModel):
    """What the environment's observation holds."""

    events: Literal["count", "voxel"] = "count"
    """``count``: (2, H, W) events per polarity (OFF, ON) over the step; ``voxel``:
    (bins, H, W) signed polarity, linearly interpolated over ``voxel_bins`` time bins."""
    voxel_bins: Annotated[int, Field(ge=1, le=64)] = 5
    max_imu_samples: Annotated[int, Field(ge=1, le=100_000)] | None = None
    """Rows of the ``imu`` observation (padded with zeros); default: enough for the IMU
    rate over one control step."""


class RewardConfig(StrictModel):
    """Weights of the reward (docs/guide/closed-loop.md "Reward")."""

    time: NonNegative = 0.1
    """Per second of flight (charged every step)."""
    contact_speed: NonNegative = 2.0
    """Per m/s of speed at contact (vertical plus horizontal)."""
    position: NonNegative = 2.0
    """Per metre of contact-point distance from the goal at contact."""
    heading: NonNegative = 1.0
    """Per radian of heading error at contact."""
    success: NonNegative = 10.0
    """Bonus for a successful landing."""
    collision: NonNegative = 10.0
    """Penalty for a collision (or leaving the scene's bounds)."""


class SuccessConfig(StrictModel):
    """When a touchdown counts as a landing (``success`` in info and episode.json)."""

    max_vertical_speed: Annotated[FiniteFloat, Field(gt=0.0)] = 0.5
    """m/s."""
    max_horizontal_speed: Annotated[FiniteFloat, Field(gt=0.0)] = 1.0
    """m/s."""
    max_position_error: Annotated[FiniteFloat, Field(gt=0.0)] = 0.5
    """Contact point to goal, m."""


Spread3 = tuple[NonNegative, NonNegative, NonNegative]


class StartSpread(StrictModel):
    """``closed_loop.start_spread``: each episode starts at the trajectory's start plus
    offsets drawn uniformly within +-these (from the episode's seed); all zero (the
    default): every episode starts at the trajectory's start."""

    position: Spread3 = (0.0, 0.0, 0.0)
    """x, y, z of the start in the goal frame F, +-m."""
    rpy: Spread3 = (0.0, 0.0, 0.0)
    """Roll, pitch, yaw gaps at the start, +-rad."""
    descent_rate: NonNegative = 0.0
    """Descent rate at the start, +-m/s."""

    def is_zero(self) -> bool:
        """No spread: every episode starts at the trajectory's start."""
        return not (any(self.position) or any(self.rpy) or self.descent_rate)


class StartEstimateConfig(StrictModel):
    """``closed_loop.start_estimate``: the error of the start state a policy is told (its
    onboard navigation filter's estimate when the landing begins): the true start plus
    Gaussian errors drawn per episode (per axis, from the episode's seed on a generator of
    its own). 0 gives the truth. The defaults are a visual-inertial odometry filter's
    typical accuracy (docs/guide/closed-loop.md "What a policy knows")."""

    position_sigma: NonNegative = 0.3
    """Per axis, m (world frame)."""
    velocity_sigma: NonNegative = 0.1
    """Per axis, m/s (world frame)."""
    attitude_sigma: NonNegative = 0.02
    """Per body axis (a small rotation applied to the true attitude), rad."""


class ClosedLoopConfig(StrictModel):
    """``closed_loop:`` block (every key optional)."""

    control_rate: Annotated[FiniteFloat, Field(ge=1.0, le=1000.0)] = 50.0
    """Control steps per second, Hz."""
    time_limit: Annotated[FiniteFloat, Field(gt=0.0, le=MAX_DURATION_S)] | None = None
    """Episode length (s) before ``truncated``; default four times the closed-form landing's
    touchdown time, plus one second."""
    dynamics: Dynamics = Dynamics()
    observation: ObservationConfig = ObservationConfig()
    reward: RewardConfig = RewardConfig()
    success: SuccessConfig = SuccessConfig()
    start_spread: StartSpread = StartSpread()
    start_estimate: StartEstimateConfig = StartEstimateConfig()
    scene_seed: Literal["fixed", "per_episode"] = "fixed"
    """The procedural scene's seed: ``fixed`` (the config's ``seed``: one scene, built at
    the first reset and kept; a reset with a new seed costs no scene) or ``per_episode``
    (the episode's seed: the scene varies too, domain randomisation, and every new seed
    builds its scene again)."""
