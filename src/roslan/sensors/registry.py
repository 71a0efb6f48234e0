"""Sensor types by name. Adding a sensor = its module + one :class:`SensorSpec` line here.

Each spec names the config ``type``, the module holding its config and sensor classes,
its render cost and the files it writes. Modules are imported on first use so heavy
back-ends (OpenGL, Embree) load only when a config uses them.
"""

from __future__ import annotations

import builtins
import importlib
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from typing import Any, Literal

from roslan.config.closed_loop import ClosedLoopConfig
from roslan.sensors.base import SensorConfig
from roslan.sensors.measurements import MEASUREMENTS, OBSERVERS, Observer

__all__ = [
    "SENSOR_TYPES",
    "SensorSpec",
    "config_class",
    "config_class_for",
    "render_cost",
    "sensor_class",
    "sensor_spec",
]


@dataclass(frozen=True)
class SensorSpec:
    """One sensor type.

    Attributes:
        type: the config's ``type`` key.
        module: dotted module holding the config and sensor classes.
        config: name of the config class (a :class:`SensorConfig`) in ``module``.
        sensor: name of the sensor class in ``module``.
        render_cost: rough relative cost of rendering / ray casting it, used to balance
            sensors over worker processes; 0: it does not render (runs in the main process).
        outputs: the dataset files it writes into OUTDIR.
        backend: what it measures the scene with: ``opengl`` (rasterized images),
            ``embree`` (ray casting; the scene's BVH is built before the run starts) or
            ``none`` (no scene needed).
        measurement: its step output, the class (in :mod:`roslan.sensors.measurements`)
            of what it taps (``ImuSamples``...); ``""``: it taps nothing.
        observation: its observation in the closed-loop environment: a factory of
            :data:`roslan.sensors.measurements.OBSERVERS` (``"imu"``...) or a dotted
            ``module.function`` path of the same signature; ``""``: not observed.
    """

    type: str
    module: str
    config: str
    sensor: str
    render_cost: float
    outputs: str
    backend: Literal["opengl", "embree", "none"] = "none"
    measurement: str = ""
    observation: str = ""

    def measurement_class(self) -> builtins.type[Any] | None:
        """The class of its step output (None: it taps nothing)."""
        return MEASUREMENTS[self.measurement] if self.measurement else None

    def observer(
        self, config: SensorConfig, loop: ClosedLoopConfig, first: bool
    ) -> Observer | None:
        """Its entry of the environment's observation (None: not observed); ``first``:
        the first sensor of this type in the config."""
        if not self.observation:
            return None
        if "." in self.observation:
            mod, _, fn = self.observation.rpartition(".")
            make = getattr(importlib.import_module(mod), fn)
        else:
            make = OBSERVERS[self.observation]
        out: Observer | None = make(config, loop, first)
        return out

    def config_class(self) -> builtins.type[SensorConfig]:
        module = importlib.import_module(self.module)
        cls: builtins.type[SensorConfig] = getattr(module, self.config)
        return cls

    def sensor_class(self) -> Any:
        return getattr(importlib.import_module(self.module), self.sensor)


_B = "roslan.sensors.beams"
_C = "roslan.sensors.cameras"
_SPECS = (
    SensorSpec(
        "lidar",
        f"{_B}.lidar",
        "LidarConfig",
        "Lidar",
        1.0,
        "lidar/<name>/NNNNNN.npz, lidar/<name>/timestamps.txt",
        backend="embree",
        measurement="CloudScan",
        observation="lidar",
    ),
    SensorSpec(
        "solid_state_lidar",
        f"{_B}.solid_state",
        "SolidStateLidarConfig",
        "SolidStateLidar",
        1.0,
        "lidar/<name>/NNNNNN.npz, lidar/<name>/timestamps.txt",
        backend="embree",
        measurement="CloudScan",
        observation="solid_state",
    ),
    SensorSpec(
        "laser",
        f"{_B}.laser",
        "LaserConfig",
        "Laser",
        0.0,
        "laser_<name>.txt",
        backend="embree",
        measurement="LaserScan",
        observation="laser",
    ),
    SensorSpec(
        "sonar",
        f"{_B}.range",
        "SonarConfig",
        "Sonar",
        0.0,
        "range_<name>.txt",
        backend="embree",
        measurement="RangeSamples",
        observation="range",
    ),
    SensorSpec(
        "altimeter",
        f"{_B}.range",
        "AltimeterConfig",
        "Altimeter",
        0.0,
        "range_<name>.txt",
        backend="embree",
        measurement="RangeSamples",
        observation="range",
    ),
    SensorSpec(
        "imu",
        "roslan.sensors.imu",
        "ImuConfig",
        "Imu",
        0.0,
        "imu.txt + calib/imu.yaml (later IMUs: imu_<name>.txt, calib/imu_<name>.yaml)",
        measurement="ImuSamples",
        observation="imu",
    ),
    SensorSpec(
        "camera",
        f"{_C}.frame",
        "CameraConfig",
        "Camera",
        2.0,
        "images.txt + images/ (or <name>/...), calib.txt, calib/<name>.yaml",
        backend="opengl",
        measurement="Frame",
        observation="camera",
    ),
    SensorSpec(
        "depth_camera",
        f"{_C}.depth",
        "DepthCameraConfig",
        "DepthCamera",
        2.0,
        "depth/<name>/NNNNNNNN.png, depth_<name>.txt, calib/<name>.yaml",
        backend="opengl",
        measurement="Frame",
        observation="depth",
    ),
    SensorSpec(
        "stereo_camera",
        f"{_C}.frame",
        "StereoCameraConfig",
        "StereoCamera",
        3.0,
        "per eye: images.txt + images/ (or <name>_left/..., <name>_right/...), calib.txt, "
        "calib/<name>_left.yaml, calib/<name>_right.yaml",
        backend="opengl",
        measurement="Frame",
        observation="stereo",
    ),
    SensorSpec(
        "event_camera",
        f"{_C}.event",
        "EventCameraConfig",
        "EventCamera",
        4.0,
        "events.txt, events.h5, images/ (or <name>/...), calib.txt, calib/<name>.yaml",
        backend="opengl",
        measurement="EventSamples",
        observation="events",
    ),
)

SENSOR_TYPES: dict[str, SensorSpec] = {s.type: s for s in _SPECS}
"""Every sensor type: config ``type`` -> :class:`SensorSpec`."""


def sensor_spec(type_name: str) -> SensorSpec:
    """The spec of ``type_name``; ValueError (with the allowed types) if unknown."""
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
    return sensor_spec(type_name).config_class()


def config_class_for(data: Mapping[str, Any]) -> type[SensorConfig] | None:
    """The config class of the sensor mapping ``data`` (by its ``type``), or None."""
    kind = data.get("type")
    return config_class(kind) if isinstance(kind, str) and kind in SENSOR_TYPES else None


@cache
def sensor_class(type_name: str) -> Any:
    return sensor_spec(type_name).sensor_class()


def render_cost(type_name: str) -> float:
    """Relative render cost of a sensor type (0: it does not render, or an unknown type);
    sensors of cost > 0 run in worker processes when workers are enabled."""
    spec = SENSOR_TYPES.get(type_name)
    return spec.render_cost if spec is not None else 0.0
