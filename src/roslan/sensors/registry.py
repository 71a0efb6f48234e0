"""Sensor types by name. Adding a sensor = one line here + its module.

Each entry maps the config ``type`` to ``(module, config class, sensor class)``;
modules are imported on first use so heavy back-ends (OpenGL, Embree) load only
when a config uses them. Config modules themselves must stay light to import.
"""

from __future__ import annotations

import importlib
from functools import cache
from typing import Any

from roslan.sensors.base import SensorConfig

__all__ = ["SENSOR_TYPES", "config_class", "sensor_class"]

SENSOR_TYPES: dict[str, tuple[str, str, str]] = {
    # type: (module, config class, sensor class)
    "lidar": ("roslan.sensors.lidar", "LidarConfig", "Lidar"),
    "solid_state_lidar": (
        "roslan.sensors.solid_state_lidar",
        "SolidStateLidarConfig",
        "SolidStateLidar",
    ),
    "laser": ("roslan.sensors.laser", "LaserConfig", "Laser"),
    "sonar": ("roslan.sensors.range", "SonarConfig", "Sonar"),
    "altimeter": ("roslan.sensors.range", "AltimeterConfig", "Altimeter"),
    "imu": ("roslan.sensors.imu", "ImuConfig", "Imu"),
    "camera": ("roslan.sensors.camera", "CameraConfig", "Camera"),
    "depth_camera": ("roslan.sensors.camera", "DepthCameraConfig", "DepthCamera"),
    "stereo_camera": ("roslan.sensors.camera", "StereoCameraConfig", "StereoCamera"),
    "event_camera": ("roslan.sensors.event_camera", "EventCameraConfig", "EventCamera"),
}


def _entry(type_name: str) -> tuple[str, str, str]:
    try:
        return SENSOR_TYPES[type_name]
    except KeyError:
        import difflib

        allowed = ", ".join(sorted(SENSOR_TYPES))
        close = difflib.get_close_matches(type_name, list(SENSOR_TYPES), n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        msg = f"unknown sensor type {type_name!r}{hint}; allowed: {allowed}"
        raise ValueError(msg) from None


@cache
def config_class(type_name: str) -> type[SensorConfig]:
    module, cfg, _ = _entry(type_name)
    cls: type[SensorConfig] = getattr(importlib.import_module(module), cfg)
    return cls


@cache
def sensor_class(type_name: str) -> Any:
    module, _, sensor = _entry(type_name)
    return getattr(importlib.import_module(module), sensor)
