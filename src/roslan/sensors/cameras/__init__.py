"""Camera-like sensors: frame, stereo, depth and event cameras on the shared OpenGL
renderer, with their lens model (:mod:`.model`), calibration files (:mod:`.calibration`),
config intrinsics keys (:mod:`.config`) and 8-bit encoding (:mod:`.encoding`)."""

from __future__ import annotations

from roslan.sensors.cameras.calibration import (
    CalibCamera,
    load_calibration,
)
from roslan.sensors.cameras.config import (
    CameraIntrinsics,
    intrinsics_model,
)
from roslan.sensors.cameras.depth import (
    DepthCamera,
    DepthCameraConfig,
)
from roslan.sensors.cameras.encoding import (
    encode_image,
    encode_linear,
    srgb_curve,
    srgb_lut,
)
from roslan.sensors.cameras.event import EventCamera
from roslan.sensors.cameras.event_config import SENSOR_PRESETS, EventCameraConfig, SensorPreset
from roslan.sensors.cameras.frame import (
    Camera,
    CameraConfig,
    StereoCamera,
    StereoCameraConfig,
)
from roslan.sensors.cameras.model import (
    DEFAULT_HFOV_DEG,
    DEFAULT_RESOLUTION,
    DISTORTION_MODELS,
    RENDER_PIXELS_PER_OUTPUT,
    T_LINK_OPTICAL,
    CameraModel,
    RenderPlan,
    auto_render_scale,
)

__all__ = [
    "DEFAULT_HFOV_DEG",
    "DEFAULT_RESOLUTION",
    "DISTORTION_MODELS",
    "RENDER_PIXELS_PER_OUTPUT",
    "SENSOR_PRESETS",
    "T_LINK_OPTICAL",
    "CalibCamera",
    "Camera",
    "CameraConfig",
    "CameraIntrinsics",
    "CameraModel",
    "DepthCamera",
    "DepthCameraConfig",
    "EventCamera",
    "EventCameraConfig",
    "RenderPlan",
    "SensorPreset",
    "StereoCamera",
    "StereoCameraConfig",
    "auto_render_scale",
    "encode_image",
    "encode_linear",
    "intrinsics_model",
    "load_calibration",
    "srgb_curve",
    "srgb_lut",
]
