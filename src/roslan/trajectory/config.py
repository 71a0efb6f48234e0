"""The ``trajectory:`` config block (the contract of docs/design.md §1 and the README)."""

from __future__ import annotations

import math
from typing import Annotated, Any

from pydantic import (
    Field,
    SerializerFunctionWrapHandler,
    field_validator,
    model_serializer,
    model_validator,
)

from roslan.config.base import Angle, Angles3, FiniteFloat, Pose, StrictModel, Vec3
from roslan.config.units import RADIANS
from roslan.limits import MAX_DURATION_S, MAX_FLAP_HZ, MIN_SAMPLE_DT_S
from roslan.trajectory.vibration_config import VibrationConfig

__all__ = ["Approach", "Flapping", "Initial", "Kappa", "TrajectoryConfig"]

PositiveFloat = Annotated[FiniteFloat, Field(gt=0)]
NonNegativeFloat = Annotated[FiniteFloat, Field(ge=0)]


Ratio = Annotated[FiniteFloat, Field(ge=1e-3)]


class Kappa(StrictModel):
    """Tau-coupling ratios of the five coupled gaps (tau_g = kappa * tau_z); each >= 0.001."""

    x: Ratio = 0.4
    y: Ratio = 0.6
    roll: Ratio = 0.5
    pitch: Ratio = 0.5
    yaw: Ratio = 0.5


class Initial(StrictModel):
    """Initial state in the goal frame F, relative to the goal."""

    position: Vec3 | None = None
    rpy: Angles3 = (0.0, 0.0, 0.0)
    descent_rate: PositiveFloat | None = None

    @field_validator("position")
    @classmethod
    def _height_positive(
        cls, v: tuple[float, float, float] | None
    ) -> tuple[float, float, float] | None:
        if v is not None and not v[2] > 0:
            msg = f"z = position[2] (height above the goal) = {v[2]} must be > 0"
            raise ValueError(msg)
        return v


class Approach(StrictModel):
    """Landing spec of the paper's dataset: the start lies ``distance`` metres from the goal,
    seen from it at elevation ``angle`` (rad), the robot flying towards it along ``heading``
    (rad, measured in F from +x towards +y), with initial speed ``speed`` (m/s, full 3-D)."""

    distance: PositiveFloat
    angle: Annotated[FiniteFloat, Field(gt=0, le=math.pi / 2)]
    heading: Angle = 0.0
    speed: PositiveFloat


class Flapping(StrictModel):
    """Flapping perturbation: heave (m) on height and pitch (rad) oscillation at ``frequency``
    (Hz), scaled by the remaining height fraction z(t)/z0 so it fades out at touchdown."""

    frequency: Annotated[FiniteFloat, Field(ge=0, le=MAX_FLAP_HZ)] = 0.0
    heave: NonNegativeFloat = 0.0
    pitch: Annotated[NonNegativeFloat, RADIANS] = 0.0
    phase: Angle = 0.0

    @property
    def enabled(self) -> bool:
        return self.frequency > 0 and (self.heave > 0 or self.pitch > 0)


class TrajectoryConfig(StrictModel):
    """Tau-theory landing: height gap closed with constant tau-dot ``k``, five coupled gaps."""

    k: Annotated[FiniteFloat, Field(ge=1e-3, lt=1.0)] = 0.5
    kappa: Kappa = Kappa()
    initial: Initial = Initial(position=(-8.0, 2.0, 4.6), rpy=(0.05, 0.15, 0.3), descent_rate=2.0)
    approach: Approach | None = None
    goal: Pose = Pose()
    sample_dt: Annotated[FiniteFloat, Field(ge=MIN_SAMPLE_DT_S, le=MAX_DURATION_S)] = 0.1
    hold: Annotated[FiniteFloat, Field(ge=0, le=MAX_DURATION_S)] = 0.0
    flapping: Flapping = Flapping()
    file: str | None = None
    """A pose file to fly instead of a tau landing (TUM ``t x y z qx qy qz qw``, or roslan's
    trajectory.csv), relative to the config file's folder. Its poses are in the frame
    ``goal`` (default: the world; for a trajectory.csv, the goal it was written for, which
    its summary.json records)."""
    smoothing: NonNegativeFloat = 0.0
    """File trajectories: 0 interpolates the poses (quintic spline); > 0 is the smoothing
    spline's penalty (``scipy.interpolate.make_smoothing_spline`` ``lam``) per axis."""
    max_gap: Annotated[FiniteFloat, Field(gt=0, le=MAX_DURATION_S)] = 1.0
    """File trajectories: the longest time (s) allowed between consecutive poses."""
    vibration: VibrationConfig | None = None
    """Body vibration every sensor sees (:mod:`roslan.trajectory.vibration`); none by default."""

    @model_serializer(mode="wrap")
    def _without_absent_vibration(self, handler: SerializerFunctionWrapHandler) -> Any:
        # no `vibration: null` in saved configs: runs without the block stay byte-identical
        data = handler(self)
        if self.vibration is None and isinstance(data, dict):
            data.pop("vibration", None)
        return data

    @field_validator("k", mode="before")  # before the range check: say why k >= 1 fails
    @classmethod
    def _below_one(cls, v: Any) -> Any:
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            return v  # (the field's own checks name the problem)
        if v > 1.0:
            msg = (
                "must satisfy 0 < k < 1: k > 1 makes the height gap close with growing speed "
                "(no landing at all); k <= 0.5 gives a soft touchdown"
            )
            raise ValueError(msg)
        if v == 1.0:
            msg = (
                "k = 1 closes the height gap at constant speed, i.e. the robot hits the goal "
                "without braking (a crash); use 0 < k < 1 (k <= 0.5 for a soft touchdown)"
            )
            raise ValueError(msg)
        return v

    def initial_height(self) -> float:
        """z0 (m): initial height above the goal, from ``initial`` or ``approach``."""
        if self.approach is not None:
            return self.approach.distance * math.sin(self.approach.angle)
        assert self.initial.position is not None
        return float(self.initial.position[2])

    @model_validator(mode="before")
    @classmethod
    def _approach_replaces_default_start(cls, data: Any) -> Any:
        # With an approach block the default initial position/descent rate do not apply;
        # start from an empty `initial` so the resolved (dumped) config says so.
        if isinstance(data, dict) and data.get("approach") is not None and "initial" not in data:
            data = {**data, "initial": {}}
        return data

    @model_validator(mode="after")
    def _check(self) -> TrajectoryConfig:
        if self.file is not None:
            tau = sorted({"k", "kappa", "initial", "approach", "flapping"} & self.model_fields_set)
            fields = type(self).model_fields
            # a saved, resolved config repeats the defaults: only other values clash
            tau_given = [
                k
                for k in tau
                if getattr(self, k) != fields[k].get_default(call_default_factory=True)
            ]
            if tau_given:
                msg = (
                    f"'file' flies the poses of the file; {', '.join(tau_given)} belong to a tau "
                    "landing: remove them (with 'file': goal, smoothing, max_gap, hold, sample_dt)"
                )
                raise ValueError(msg)
            return self
        if self.approach is not None:
            given = self.initial.model_fields_set if "initial" in self.model_fields_set else set()
            # An explicit null (as in a saved, resolved config) does not count as given.
            clash = [
                key
                for key in ("position", "descent_rate")
                if key in given and getattr(self.initial, key) is not None
            ]
            if clash:
                keys = " and ".join(f"initial.{key}" for key in clash)
                msg = f"give either 'approach' or {keys}, not both"
                raise ValueError(msg)
        else:
            missing = [k for k in ("position", "descent_rate") if getattr(self.initial, k) is None]
            if missing:
                keys = " and ".join(f"initial.{key}" for key in missing)
                msg = (
                    f"{keys} missing: give initial.position and initial.descent_rate, "
                    "or an 'approach' block"
                )
                raise ValueError(msg)
        for name in ("x", "y", "roll", "pitch", "yaw"):
            kk = self.k * getattr(self.kappa, name)
            if kk > 1.0 + 1e-12:
                msg = (
                    f"kappa.{name} = {getattr(self.kappa, name)}: k * kappa.{name} = {kk:.4g} > 1 "
                    f"makes the {name} gap close with unbounded rate at touchdown; use "
                    f"kappa.{name} <= 1/k = {1 / self.k:.4g} (<= 0.5/k for bounded acceleration)"
                )
                raise ValueError(msg)
        if self.flapping.heave > 0 and self.flapping.heave >= self.initial_height():
            msg = (
                f"flapping.heave = {self.flapping.heave} m reaches below the goal: it must be "
                f"smaller than the initial height z0 = {self.initial_height():.4g} m"
            )
            raise ValueError(msg)
        return self
