"""A small sensor written the way docs/guide/architecture.md says: one module
(a config model and a class satisfying ``roslan.sensors.base.Sensor``) plus one
``SensorSpec``. tests/sensors/test_sensor_plugin.py registers it and runs it through the pipeline.

A barometer: static pressure of the International Standard Atmosphere at the sensor's
altitude (world z, taken as height above sea level), with white noise, published as
``sensor_msgs/FluidPressure`` and written to ``baro_<name>.txt`` (``t pressure``).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any, ClassVar, Literal

import numpy as np

from roslan.io.text import write_columns
from roslan.sensors.base import (
    Message,
    SensorConfig,
    SimContext,
    StaticTransform,
    TopicSpec,
    sample_times_ns,
)
from roslan.sensors.registry import SensorSpec

P0_PA = 101_325.0
"""ISA sea-level pressure."""


def isa_pressure(height_m: Any) -> Any:
    """ISA troposphere: ``p = P0 (1 - 2.25577e-5 h)^5.25588`` (Pa, h in m)."""
    return P0_PA * (1.0 - 2.25577e-5 * np.asarray(height_m)) ** 5.25588


class BarometerConfig(SensorConfig):
    type: Literal["barometer"] = "barometer"
    noise_pa: float = 0.0
    """Standard deviation of the white noise, Pa."""

    needs_scene: ClassVar[bool] = False


class Barometer:
    def __init__(self, config: BarometerConfig) -> None:
        self.config = config

    def topics(self) -> list[TopicSpec]:
        return [TopicSpec(self.config.topic, "sensor_msgs/msg/FluidPressure")]

    def static_transforms(self) -> list[StaticTransform]:
        return []

    def messages(self, ctx: SimContext) -> Iterator[Message]:
        c = self.config
        t_ns = sample_times_ns(c.rate, ctx.trajectory.duration_ns)
        state = ctx.trajectory.state_ns(t_ns)
        T_mount = c.pose.matrix()
        z = state.position[:, 2] + np.einsum("nj,j->n", state.R_world_body[:, 2, :], T_mount[:3, 3])
        noise = ctx.rng(c.name).normal(0.0, c.noise_pa, len(t_ns)) if c.noise_pa > 0 else 0.0
        pressure = isa_pressure(z) + noise
        if ctx.files is not None:  # None: a run that records no files
            with ctx.files.path(f"baro_{c.name}.txt").open("w", encoding="utf-8") as fh:
                write_columns(fh, t_ns, pressure, fmt="%.3f")  # t in s, 9 decimals, exact
        for t, p in zip(t_ns.tolist(), pressure.tolist(), strict=True):
            yield Message(t, c.topic, "sensor_msgs/msg/FluidPressure", self._build(ctx, t, p))

    def _build(self, ctx: SimContext, t_ns: int, pressure: float) -> Any:
        frame, stamp = self.config.frame, ctx.stamp(t_ns)

        def build(store: Any) -> Any:
            return store.new(
                "sensor_msgs/msg/FluidPressure",
                header=store.header(stamp, frame),
                fluid_pressure=pressure,
                variance=self.config.noise_pa**2,
            )

        return build

    def close(self, ctx: SimContext) -> None:
        pass  # the text file is complete once the stream starts


SPEC = SensorSpec("barometer", __name__, "BarometerConfig", "Barometer", 0.0, "baro_<name>.txt")
"""The one line that registers the sensor (in roslan, it goes into sensors/registry.py)."""
