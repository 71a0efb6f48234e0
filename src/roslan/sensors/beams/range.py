"""Single-reading range sensors, ray cast: ``type: sonar`` and ``type: altimeter``.

Both publish sensor_msgs/Range. The beam is a cone of rays around ``axis`` (a unit
vector in the frame given by ``pose``; for the default identity pose that is
base_link): concentric rings at ``i / rings`` of the half angle (``6 i`` rays on ring
``i``, the last ring on the cone's edge) around the central ray. The reading is the
minimum distance over the rays, as Gazebo's range plugin reports it, so a sonar
sees the nearest surface anywhere in its cone, not only on its axis.

The message frame (``frame_id``) has its x axis along the beam (sensor_msgs/Range
convention): the static transform base_link -> frame is ``pose`` followed by the
shortest rotation taking x onto ``axis``.

Readings follow REP 117: +inf when nothing is within ``max_range`` (or the reading
dropped out), -inf for a surface closer than ``min_range``; otherwise the true
minimum plus Gaussian noise, clipped to [min_range, max_range].

Dataset file: ``range_<name>.txt`` with lines ``t range`` (s since the trajectory
start, 9 decimals; m; ``inf`` / ``-inf`` as above).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import IO, TYPE_CHECKING, Annotated, Any, ClassVar, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, model_validator

from roslan.config.base import FiniteFloat, Vec3
from roslan.io.text import write_columns
from roslan.sensors.base import (
    LabelsKey,
    Message,
    SensorConfig,
    SimContext,
    StaticTransform,
    TopicName,
    TopicSpec,
    paced,
    sample_times_ns,
)
from roslan.sensors.beams.rays import rays_in_world
from roslan.sensors.measurements import RangeSamples

if TYPE_CHECKING:
    from roslan.render.base import BeamCaster

__all__ = [
    "Altimeter",
    "AltimeterConfig",
    "RangeSensor",
    "Sonar",
    "SonarConfig",
    "align_x_to",
    "cone_directions",
]

RANGE = "sensor_msgs/msg/Range"
ULTRASOUND = 0
INFRARED = 1

PositiveFloat = Annotated[FiniteFloat, Field(gt=0)]
NonNegative = Annotated[FiniteFloat, Field(ge=0)]


def align_x_to(axis: NDArray[np.float64]) -> NDArray[np.float64]:
    """(3, 3) shortest-arc rotation taking +x onto the unit vector ``axis``."""
    a = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    x = np.array([1.0, 0.0, 0.0])
    c = float(a @ x)
    if c < -1.0 + 1e-12:  # opposite: half a turn about z
        return np.diag([-1.0, -1.0, 1.0])
    v = np.cross(x, a)
    K = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    R: NDArray[np.float64] = np.eye(3) + K + K @ K / (1.0 + c)
    return R


def cone_directions(half_angle: float, rings: int) -> NDArray[np.float64]:
    """(1 + 3 rings (rings + 1), 3) unit rays of a cone around +x.

    Ring ``i`` (1..rings) lies at ``half_angle * i / rings`` from the axis with ``6 i``
    rays evenly spaced in azimuth (a hexagonal-like fill of the cone's solid angle).
    """
    dirs = [np.array([[1.0, 0.0, 0.0]])]
    for i in range(1, rings + 1):
        th = half_angle * i / rings
        phi = 2.0 * math.pi * np.arange(6 * i) / (6 * i)
        dirs.append(
            np.stack(
                [
                    np.full(phi.shape, math.cos(th)),
                    math.sin(th) * np.cos(phi),
                    math.sin(th) * np.sin(phi),
                ],
                axis=1,
            )
        )
    return np.concatenate(dirs)


class _RangeConfig(SensorConfig, LabelsKey):
    """Keys shared by sonar and altimeter (defaults set by each type)."""

    axis: Vec3
    field_of_view: Annotated[FiniteFloat, Field(ge=0, lt=math.pi)]
    rings: Annotated[int, Field(ge=0, le=64)]
    min_range: NonNegative
    max_range: PositiveFloat
    noise_sigma: NonNegative
    dropout: Annotated[FiniteFloat, Field(ge=0, lt=1)] = 0.0

    @model_validator(mode="after")
    def _check_range(self) -> _RangeConfig:
        if not self.min_range < self.max_range:
            msg = f"min_range = {self.min_range} m must be less than max_range = {self.max_range} m"
            raise ValueError(msg)
        if float(np.linalg.norm(self.axis)) < 1e-9:
            msg = f"axis = {list(self.axis)}: must be a non-zero vector (the beam direction)"
            raise ValueError(msg)
        return self


class SonarConfig(_RangeConfig):
    """``type: sonar``: ultrasound cone (HC-SR04-like defaults: 30 deg, 0.02-4 m)."""

    type: Literal["sonar"]
    rate: PositiveFloat = 20.0
    topic: TopicName = "/sonar"
    axis: Vec3 = (1.0, 0.0, 0.0)
    field_of_view: Annotated[FiniteFloat, Field(ge=0, lt=math.pi)] = math.radians(30.0)
    rings: Annotated[int, Field(ge=0, le=64)] = 8
    min_range: NonNegative = 0.02
    max_range: PositiveFloat = 4.0
    noise_sigma: NonNegative = 0.01


class AltimeterConfig(_RangeConfig):
    """``type: altimeter``: narrow infrared/laser beam, default straight down
    (TFmini-like defaults: 2 deg, 0.1-12 m)."""

    type: Literal["altimeter"]
    rate: PositiveFloat = 50.0
    topic: TopicName = "/altimeter"
    axis: Vec3 = (0.0, 0.0, -1.0)
    field_of_view: Annotated[FiniteFloat, Field(ge=0, lt=math.pi)] = math.radians(2.0)
    rings: Annotated[int, Field(ge=0, le=64)] = 0
    min_range: NonNegative = 0.1
    max_range: PositiveFloat = 12.0
    noise_sigma: NonNegative = 0.02


class RangeSensor:
    """A cone of rays reporting its minimum range (see module docstring)."""

    radiation_type: ClassVar[int] = ULTRASOUND

    def __init__(self, config: _RangeConfig) -> None:
        self.config = config
        T = config.pose.matrix()
        T[:3, :3] = T[:3, :3] @ align_x_to(np.asarray(config.axis, dtype=np.float64))
        self.T_body_sensor = T  # x along the beam
        self.directions = cone_directions(0.5 * config.field_of_view, config.rings)
        self._fh: IO[str] | None = None

    def topics(self) -> list[TopicSpec]:
        return [TopicSpec(self.config.topic, RANGE)]

    def static_transforms(self) -> list[StaticTransform]:
        return [StaticTransform("base_link", self.config.frame, self.T_body_sensor)]

    def read(
        self, trajectory: Any, caster: BeamCaster, t_ns: NDArray[np.int64], rng: np.random.Generator
    ) -> NDArray[np.float64]:
        """(N,) readings at trajectory instants ``t_ns`` (REP 117 +-inf conventions), with
        ``N`` noise and dropout draws from ``rng``."""
        n_t = t_ns.shape[0]
        noise: NDArray[np.float64] = np.asarray(rng.standard_normal(n_t))
        keep: NDArray[np.bool_] = np.asarray(rng.random(n_t) >= self.config.dropout)
        return self.readings(trajectory, caster, t_ns, noise, keep)

    def readings(
        self,
        trajectory: Any,
        caster: BeamCaster,
        t_ns: NDArray[np.int64],
        noise: NDArray[np.float64],
        keep: NDArray[np.bool_],
    ) -> NDArray[np.float64]:
        """(N,) readings at ``t_ns`` given each reading's standard-normal ``noise`` draw and
        whether it survives dropout (``keep``)."""
        c = self.config
        n_t = t_ns.shape[0]
        if n_t == 0:
            return np.zeros(0)
        n_r = self.directions.shape[0]
        d = np.broadcast_to(self.directions, (n_t, n_r, 3))
        t = t_ns.astype(np.float64) * 1e-9
        # one knot per reading (all rays of a reading leave at the same instant)
        origins, dirs = rays_in_world(
            trajectory, self.T_body_sensor, t, np.zeros(n_r), d, mode="exact"
        )
        hits = caster.cast(
            origins.reshape(-1, 3), dirs.reshape(-1, 3), c.max_range, t=np.repeat(t, n_r)
        )
        true: NDArray[np.float64] = hits.distance.astype(np.float64).reshape(n_t, n_r).min(axis=1)
        out = np.full(n_t, np.inf)
        hit = np.isfinite(true) & keep
        close = hit & (true < c.min_range)
        ok = hit & ~close
        out[ok] = np.clip(true[ok] + c.noise_sigma * noise[ok], c.min_range, c.max_range)
        out[close] = -np.inf
        return out

    def messages(self, ctx: SimContext) -> Iterator[Message]:
        c = self.config
        rate = c.rate
        grid = ctx.clock.grid(lambda end: sample_times_ns(rate, end))
        caster = ctx.raycaster()
        rng = ctx.rng(c.name)
        if ctx.files is not None:  # (no file sink: a run that records nothing)
            self._fh = ctx.files.path(f"range_{c.name}.txt").open(
                "w", encoding="utf-8", newline="\n"
            )
        chunk = max(1, round(c.rate))  # one second of readings per batch of draws
        # A batch's noise and dropout draws are made whole when its first reading comes, so
        # a reading's draws do not depend on where the horizon or the run's end cuts its
        # batch: every reading is sent as soon as the horizon reaches it (closed loop) and is
        # the one-shot run's.
        noise: NDArray[np.float64] = np.zeros(0)
        keep: NDArray[np.bool_] = np.zeros(0, bool)
        i0 = 0
        last = [-1]
        for item in paced(grid, chunk, lambda: last[0] + 1):
            if isinstance(item, Message):
                yield item  # wait for the horizon
                continue
            j0, t = item
            at = j0 % chunk
            if at == 0:
                noise = np.asarray(rng.standard_normal(chunk))
                keep = np.asarray(rng.random(chunk) >= c.dropout)
            span = slice(at, at + t.size)
            r = self.readings(ctx.trajectory, caster, t, noise[span], keep[span])
            if self._fh is not None:
                write_columns(self._fh, t, r, fmt="%.6f", allow_nonfinite=True)
            ctx.clock.tap(c.name, RangeSamples(t, r))
            last[0] = int(t[-1])
            for k, (tk, rk) in enumerate(zip(t.tolist(), r.tolist(), strict=True)):
                yield Message(tk, c.topic, RANGE, self._builder(ctx.stamp(tk), rk, i0 + k))
            i0 += t.size

    def _builder(self, stamp: int, value: float, seq: int) -> Any:
        c = self.config

        def build(store: Any) -> Any:
            return store.new(
                RANGE,
                header=store.header(stamp, c.frame, seq),
                radiation_type=self.radiation_type,
                field_of_view=float(c.field_of_view),
                min_range=float(c.min_range),
                max_range=float(c.max_range),
                range=value,
            )

        return build

    def close(self, ctx: SimContext) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None


class Sonar(RangeSensor):
    """``type: sonar`` (sensor_msgs/Range ULTRASOUND)."""

    radiation_type: ClassVar[int] = ULTRASOUND

    def __init__(self, config: SonarConfig) -> None:
        super().__init__(config)


class Altimeter(RangeSensor):
    """``type: altimeter`` (sensor_msgs/Range INFRARED)."""

    radiation_type: ClassVar[int] = INFRARED

    def __init__(self, config: AltimeterConfig) -> None:
        super().__init__(config)
