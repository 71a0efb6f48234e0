"""Camera calibration files: reading ROS ``camera_info`` YAML (camera_calibration_parsers
keys) and Kalibr camchain YAML (``camN`` entries) into a :class:`CameraModel`, and the
:class:`CalibCamera` entries a camera-like sensor contributes to the run's calibration
files."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from roslan.config.base import load_yaml
from roslan.errors import ConfigError, SensorError
from roslan.sensors.cameras.model import CameraModel

__all__ = ["CalibCamera", "load_calibration"]

F64 = NDArray[np.float64]


def load_calibration(
    path: str | Path, *, camera: str | None = None, name: str | None = None
) -> CameraModel:
    """A :class:`CameraModel` from a ROS camera_info YAML or a Kalibr camchain YAML.

    Args:
        path: the YAML file.
        camera: Kalibr entry to use (``cam0``...); default the first (``cam0``).
        name: camera name to use instead of the file's.
    Raises:
        SensorError: missing/malformed file or values, naming the file and the key.
    """
    p = Path(path)
    try:
        data = load_yaml(p)
    except ConfigError as err:
        raise SensorError(str(err)) from None
    src = str(p)
    if not isinstance(data, dict):
        msg = (
            f"{src}: expected a ROS camera_info YAML or a Kalibr camchain YAML (a mapping), "
            f"got {type(data).__name__}"
        )
        raise SensorError(msg)
    if "camera_matrix" in data or "image_width" in data:
        if camera is not None:
            msg = (
                f"{src}: calibration_camera = {camera!r}: "
                "only Kalibr camchain files have several cameras"
            )
            raise SensorError(msg)
        return _from_camera_info(data, src, name)
    cams = sorted(k for k in data if isinstance(k, str) and k.startswith("cam"))
    if cams:
        key = camera or ("cam0" if "cam0" in data else cams[0])
        if key not in data:
            msg = (
                f"{src}: calibration_camera = {key!r}: no such camera in the file; "
                f"it has {', '.join(cams)}"
            )
            raise SensorError(msg)
        return _from_kalibr(data[key], src, key, name)
    msg = (
        f"{src}: neither a ROS camera_info YAML (keys image_width, image_height, camera_matrix, "
        "distortion_model, distortion_coefficients) nor a Kalibr camchain (keys cam0, cam1, ...)"
    )
    raise SensorError(msg)


def _need(d: dict[str, Any], key: str, src: str, prefix: str = "") -> Any:
    if not isinstance(d, dict) or key not in d:
        msg = f"{src}: {prefix}{key}: missing key"
        raise SensorError(msg)
    return d[key]


def _matrix(d: dict[str, Any], key: str, src: str, shape: tuple[int, int]) -> F64:
    m = _need(d, key, src)
    data = _need(m, "data", src, f"{key}.") if isinstance(m, dict) else m
    try:
        a = np.asarray(data, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        msg = f"{src}: {key}.data = {data!r}: must be a list of numbers"
        raise SensorError(msg) from None
    if a.size != shape[0] * shape[1]:
        n = shape[0] * shape[1]
        msg = f"{src}: {key}.data: needs {n} numbers ({shape[0]}x{shape[1]}), got {a.size}"
        raise SensorError(msg)
    return a.reshape(shape)


def _from_camera_info(d: dict[str, Any], src: str, name: str | None) -> CameraModel:
    w = _need(d, "image_width", src)
    h = _need(d, "image_height", src)
    if not isinstance(w, int) or not isinstance(h, int) or w < 1 or h < 1:
        msg = f"{src}: image_width, image_height = {w!r}, {h!r}: must be positive integers"
        raise SensorError(msg)
    K = _matrix(d, "camera_matrix", src, (3, 3))
    if K[0, 1] != 0 or K[1, 0] != 0 or K[2, 0] != 0 or K[2, 1] != 0 or K[2, 2] != 1:
        msg = f"{src}: camera_matrix.data = {K.ravel().tolist()}: must be [fx 0 cx 0 fy cy 0 0 1]"
        raise SensorError(msg)
    model = _need(d, "distortion_model", src)
    dist = d.get("distortion_coefficients", {"data": []})
    coeffs = dist.get("data", []) if isinstance(dist, dict) else dist
    keys = {
        "fx": "camera_matrix.data[0] (fx)",
        "fy": "camera_matrix.data[4] (fy)",
        "cx": "camera_matrix.data[2] (cx)",
        "cy": "camera_matrix.data[5] (cy)",
        "distortion_coeffs": "distortion_coefficients.data",
        "resolution": "image_width/image_height",
    }
    return CameraModel.create(
        w,
        h,
        K[0, 0],
        K[1, 1],
        K[0, 2],
        K[1, 2],
        model,
        coeffs,
        name=name or str(d.get("camera_name") or "camera"),
        source=src,
        keys=keys,
    )


def _from_kalibr(d: Any, src: str, cam: str, name: str | None) -> CameraModel:
    if not isinstance(d, dict):
        msg = f"{src}: {cam}: must be a mapping (camera_model, intrinsics, ...)"
        raise SensorError(msg)
    cm = d.get("camera_model", "pinhole")
    if cm != "pinhole":
        msg = f"{src}: {cam}.camera_model = {cm!r}: only 'pinhole' is supported"
        raise SensorError(msg)
    intr = _need(d, "intrinsics", src, f"{cam}.")
    res = _need(d, "resolution", src, f"{cam}.")
    if not isinstance(intr, list) or len(intr) != 4:
        msg = f"{src}: {cam}.intrinsics = {intr!r}: must be [fu, fv, pu, pv]"
        raise SensorError(msg)
    if not isinstance(res, list) or len(res) != 2:
        msg = f"{src}: {cam}.resolution = {res!r}: must be [width, height]"
        raise SensorError(msg)
    keys = {
        "fx": f"{cam}.intrinsics[0] (fu)",
        "fy": f"{cam}.intrinsics[1] (fv)",
        "cx": f"{cam}.intrinsics[2] (pu)",
        "cy": f"{cam}.intrinsics[3] (pv)",
        "distortion_model": f"{cam}.distortion_model",
        "distortion_coeffs": f"{cam}.distortion_coeffs",
        "resolution": f"{cam}.resolution",
    }
    return CameraModel.create(
        res[0],
        res[1],
        intr[0],
        intr[1],
        intr[2],
        intr[3],
        d.get("distortion_model", "none"),
        d.get("distortion_coeffs", []),
        name=name or cam,
        source=src,
        keys=keys,
    )


@dataclass(frozen=True, eq=False)
class CalibCamera:
    """One camera entry of the calibration files.

    Attributes:
        name: file stem of ``calib/<name>.yaml``.
        model: its intrinsics.
        T_base_optical: (4, 4) pose of its optical frame in base_link.
        rostopic: image topic written into the camchain.
        Tx: ROS CameraInfo ``P[0, 3]`` (``-fx * baseline`` for a right stereo camera).
    """

    name: str
    model: CameraModel
    T_base_optical: F64
    rostopic: str = ""
    Tx: float = 0.0
