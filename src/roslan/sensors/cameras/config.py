"""The intrinsics keys every camera-like sensor config (frame, depth, stereo, event
camera) inherits: inline pinhole + distortion keys or a calibration file."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, ValidationInfo, field_validator, model_validator

from roslan.config.base import FiniteFloat, StrictModel
from roslan.errors import SensorError
from roslan.sensors.cameras.calibration import CalibCamera, load_calibration
from roslan.sensors.cameras.model import (
    DEFAULT_HFOV_DEG,
    DEFAULT_RESOLUTION,
    T_LINK_OPTICAL,
    CameraModel,
)

__all__ = ["CameraIntrinsics", "intrinsics_model"]

F64 = NDArray[np.float64]


class CameraIntrinsics(StrictModel):
    """Intrinsics keys of every camera-like sensor config.

    Either inline (``resolution``, ``fx``, ``fy``, ``cx``, ``cy``,
    ``distortion_model``, ``distortion_coeffs``; defaults: 640x480, 90 deg horizontal
    field of view, centred principal point, no distortion) or ``calibration``: a ROS
    camera_info YAML or Kalibr camchain YAML (``calibration_camera`` picks ``camN``),
    relative paths resolved against the config file's folder.
    """

    resolution: (
        tuple[Annotated[int, Field(ge=1, le=65536)], Annotated[int, Field(ge=1, le=65536)]] | None
    ) = None
    fx: FiniteFloat | None = None
    fy: FiniteFloat | None = None
    cx: FiniteFloat | None = None
    cy: FiniteFloat | None = None
    distortion_model: str = "none"
    distortion_coeffs: tuple[FiniteFloat, ...] = ()
    calibration: Path | None = None
    calibration_camera: str | None = None
    near_clip: Annotated[FiniteFloat, Field(ge=1e-4, le=1.0)] = 0.01
    """Near clipping distance of the renderer (m): surfaces closer to the optical centre
    are not drawn. The clearance check refuses a run in which scene geometry comes
    closer than this to any corner of the near-clipping rectangle."""

    supersampling: Annotated[int, Field(ge=1, le=8)] = 1
    """N > 1: the reference image formation, N x N samples per pixel on a regular grid,
    box-filtered (textures filtered over each sample's own footprint), converging to
    the area average of the true image as N grows; N^2 times the render cost. 1
    (default): one sample per pixel, the edge filter and the shader's anisotropic
    texture filter (docs/design.md, "Image formation")."""

    @field_validator("calibration", mode="after")
    @classmethod
    def _resolve(cls, v: Path | None, info: ValidationInfo) -> Path | None:
        if v is None or v.is_absolute():
            return v
        base = (info.context or {}).get("base_dir")
        return (Path(base) / v) if base is not None else v

    @model_validator(mode="after")
    def _check_intrinsics(self) -> CameraIntrinsics:
        if self.calibration is not None:
            inline = [k for k in ("fx", "fy", "cx", "cy") if getattr(self, k) is not None]
            if inline or self.distortion_coeffs or self.distortion_model != "none":
                keys = inline + (["distortion_model/distortion_coeffs"] if len(inline) < 4 else [])
                msg = (
                    f"calibration = {self.calibration}: give either a calibration file "
                    f"or inline {', '.join(keys)}, not both"
                )
                raise ValueError(msg)
        self.calibration_cameras()  # builds (validates) the models: SensorError -> ValueError
        return self

    def camera_model(self) -> CameraModel:
        """The validated :class:`CameraModel` of this config."""
        name = str(getattr(self, "name", "camera"))
        return intrinsics_model(self, name=name, source=self._source())

    def _source(self) -> str:
        name = getattr(self, "name", None)
        return f"sensor {name!r}" if name else "camera"

    def calibration_cameras(self) -> list[CalibCamera]:
        """The cameras this sensor contributes to calib/ and camchain.yaml (override for stereo)."""
        try:
            model = self.camera_model()
        except SensorError as err:
            raise ValueError(str(err)) from None
        return [
            CalibCamera(
                name=str(getattr(self, "name", "camera")),
                model=model,
                T_base_optical=self.T_base_optical(),
                rostopic=f"{getattr(self, 'topic', '')}/image_raw",
            )
        ]

    def T_base_optical(self) -> F64:
        """(4, 4) ``T_base_link_optical`` of the (first) camera."""
        pose = getattr(self, "pose", None)
        T = pose.matrix() if pose is not None else np.eye(4)
        return np.asarray(T @ T_LINK_OPTICAL, dtype=np.float64)


def intrinsics_model(
    cfg: CameraIntrinsics, *, name: str = "camera", source: str = "config"
) -> CameraModel:
    """From a :class:`CameraIntrinsics` config (inline keys or its calibration file)."""
    if cfg.calibration is not None:
        model = load_calibration(cfg.calibration, camera=cfg.calibration_camera, name=name)
        if cfg.resolution is not None and tuple(cfg.resolution) != (model.width, model.height):
            msg = (
                f"{source}: resolution = {list(cfg.resolution)}: differs from the calibration "
                f"file {cfg.calibration} ({model.width}x{model.height}); omit it or match it"
            )
            raise SensorError(msg)
        return model
    w, h = cfg.resolution or DEFAULT_RESOLUTION
    f_default = 0.5 * w / math.tan(math.radians(DEFAULT_HFOV_DEG) / 2.0)
    fx = cfg.fx if cfg.fx is not None else (cfg.fy if cfg.fy is not None else f_default)
    fy = cfg.fy if cfg.fy is not None else fx
    cx = cfg.cx if cfg.cx is not None else (w - 1) / 2.0
    cy = cfg.cy if cfg.cy is not None else (h - 1) / 2.0
    return CameraModel.create(
        w,
        h,
        fx,
        fy,
        cx,
        cy,
        cfg.distortion_model,
        cfg.distortion_coeffs,
        name=name,
        source=source,
    )
