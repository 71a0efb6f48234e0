"""The top-level simulation config (``roslan simulate CONFIG``)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Annotated, Any, Literal

from pydantic import (
    BeforeValidator,
    Field,
    SerializationInfo,
    SerializeAsAny,
    SerializerFunctionWrapHandler,
    ValidationInfo,
    field_validator,
    model_serializer,
    model_validator,
)

from roslan.config.base import FiniteFloat, ModelFor, StrictModel
from roslan.config.closed_loop import ClosedLoopConfig
from roslan.limits import MAX_RATE_HZ, MAX_SEED
from roslan.sensors.base import LabelsKey, SensorConfig
from roslan.sensors.registry import SENSOR_TYPES, config_class, config_class_for
from roslan.trajectory.base import DEFAULT_GROUND_TRUTH_RATE
from roslan.trajectory.config import TrajectoryConfig
from roslan.vehicle import VehicleConfig

__all__ = ["DEFAULT_START_TIME_NS", "OutputConfig", "SimConfig"]

DEFAULT_START_TIME_NS = 1_700_000_000_000_000_000
"""Default absolute stamp of trajectory time 0: 2023-11-14T22:13:20Z (ROS treats 0 as
"no time", so stamps start at a fixed, documented, non-zero epoch)."""

BagFormat = Literal["ros1", "ros2"]


class OutputConfig(StrictModel):
    """``output:`` block."""

    start_time: Annotated[int, Field(gt=0, le=2**63 - 1)] = DEFAULT_START_TIME_NS
    """Absolute stamp (ns since the Unix epoch) of trajectory time 0; a float in
    seconds is accepted too."""
    formats: tuple[BagFormat, ...] = ("ros1", "ros2")
    compression: Literal["none", "lz4", "bz2"] = "lz4"
    """ROS 1 bag chunk compression (what ``rosbag`` reads: none, lz4, bz2)."""
    ros2_compression: Literal["zstd", "lz4", "none"] = "zstd"
    """ROS 2 bag (MCAP) chunk compression; a separate key because the formats support
    different codecs (ROS 1 has no zstd, MCAP no bz2)."""
    ground_truth_rate: Annotated[FiniteFloat, Field(gt=0, le=MAX_RATE_HZ)] = (
        DEFAULT_GROUND_TRUTH_RATE
    )
    """Hz of the ground-truth topics and of groundtruth.txt (same instants)."""
    workers: Literal["auto"] | Annotated[int, Field(ge=0, strict=True)] = "auto"
    """Worker processes for render-heavy sensors: ``auto`` (one per such sensor, at most
    the CPUs; none on one CPU), ``0`` (all in the main process) or N; outputs are the same."""
    labels: Annotated[bool, Field(strict=True)] = False
    """True: write ground-truth labels (classes.json, instances.json and every sensor's
    label outputs, docs/guide/labels.md); the scene must have classes. A sensor opts out
    with its own ``labels: false``. Left out of run.json when false (the default), so
    runs without labels stay byte-identical."""

    @model_serializer(mode="wrap")
    def _drop_default_labels(self, handler: SerializerFunctionWrapHandler) -> Any:
        data = handler(self)
        if isinstance(data, dict) and data.get("labels") is False:
            data.pop("labels")
        return data

    @field_validator("start_time", mode="before")
    @classmethod
    def _seconds_to_ns(cls, v: Any) -> Any:
        if isinstance(v, float):
            if not math.isfinite(v) or not 0 < v < 9.2e9:
                msg = "must be a positive stamp below 2**63 ns (9.2e9 s as seconds)"
                raise ValueError(msg)
            return round(v * 1e9)
        return v

    @field_validator("formats")
    @classmethod
    def _nonempty(cls, v: tuple[str, ...]) -> tuple[str, ...]:
        if not v:
            msg = "give at least one of 'ros1', 'ros2'"
            raise ValueError(msg)
        if len(set(v)) != len(v):
            msg = "formats must not repeat"
            raise ValueError(msg)
        return v


def _sensor(value: Any, info: ValidationInfo) -> SensorConfig:
    """Dispatch one ``sensors[i]`` mapping to its type's config model."""
    if isinstance(value, SensorConfig):
        return value
    if not isinstance(value, Mapping):
        msg = "each sensor must be a mapping with at least 'type' and 'name'"
        raise ValueError(msg)
    if "type" not in value:
        msg = f"missing 'type'; allowed: {', '.join(sorted(SENSOR_TYPES))}"
        raise ValueError(msg)
    cls = config_class(str(value["type"]))
    return cls.model_validate(value, context=info.context)


class SimConfig(StrictModel):
    """Everything a simulation needs; validated once when the YAML is read."""

    trajectory: TrajectoryConfig = TrajectoryConfig()
    scene: str | None = None
    """A built-in scene name (``warehouse``, ``refinery``, ``empty``) or a scene YAML path."""
    sensors: list[
        Annotated[
            SerializeAsAny[SensorConfig], BeforeValidator(_sensor), ModelFor(config_class_for)
        ]
    ] = Field(default_factory=list)
    seed: Annotated[int, Field(ge=0, le=MAX_SEED)] = 0
    vehicle: VehicleConfig = VehicleConfig()
    """Body shape and contact points in base_link (:mod:`roslan.vehicle`)."""
    output: OutputConfig = OutputConfig()
    closed_loop: ClosedLoopConfig | None = None
    """How ``roslan fly`` and :class:`roslan.env.LandingEnv` fly (``simulate`` ignores it);
    left out of the dump when absent, so simulate's run.json is unchanged."""

    @model_serializer(mode="wrap")
    def _drop_absent_closed_loop(
        self, handler: SerializerFunctionWrapHandler, info: SerializationInfo
    ) -> Any:
        data = handler(self)
        if isinstance(data, dict) and data.get("closed_loop") is None:
            data.pop("closed_loop", None)
        return data

    @model_validator(mode="after")
    def _run_labels(self) -> SimConfig:
        # each labelling sensor knows whether the run writes labels (also in workers)
        for s in self.sensors:
            if isinstance(s, LabelsKey):
                s._run_labels = self.output.labels
        return self

    @model_validator(mode="after")
    def _unique(self) -> SimConfig:
        for key in ("name", "topic"):
            seen: set[str] = set()
            for i, s in enumerate(self.sensors):
                value = getattr(s, key)
                if value in seen:
                    msg = (
                        f"sensors[{i}].{key} = {value!r}: duplicate; "
                        f"every sensor {key} must be unique"
                    )
                    raise ValueError(msg)
                seen.add(value)
        return self
