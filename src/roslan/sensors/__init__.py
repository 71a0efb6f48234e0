"""Simulated sensors: the sensor interface (:mod:`.base`), the type registry
(:mod:`.registry`), the IMU, the ground truth, and the camera-like (:mod:`.cameras`) and
ray-cast (:mod:`.beams`) sensor subpackages.

Only the interface and the registry are re-exported here: they are light to import;
sensor modules load when a config uses them (:func:`registry.sensor_class`).
"""

from __future__ import annotations

from roslan.sensors.base import (
    Message,
    Sensor,
    SensorConfig,
    SimContext,
    StaticTransform,
    TopicSpec,
    sample_times_ns,
)
from roslan.sensors.registry import (
    SENSOR_TYPES,
    SensorSpec,
    config_class,
    render_cost,
    sensor_class,
    sensor_spec,
)

__all__ = [
    "SENSOR_TYPES",
    "Message",
    "Sensor",
    "SensorConfig",
    "SensorSpec",
    "SimContext",
    "StaticTransform",
    "TopicSpec",
    "config_class",
    "render_cost",
    "sample_times_ns",
    "sensor_class",
    "sensor_spec",
]
