"""The run's camera calibration files and where each camera's dataset files go.

Event Camera Dataset layout: the OUTDIR root holds one camera's ``images.txt``,
``images/`` and ``calib.txt`` (:func:`root_camera`); every other camera writes the same
files in ``<camera>/`` (:func:`camera_folder`). :func:`write_calibration` writes, once per
run, ``calib/<camera>.yaml`` (ROS camera_info) of every camera, each camera's
``calib.txt`` (not depth cameras) and ``calib/camchain.yaml`` (Kalibr: all cameras,
``T_cam_imu`` when an IMU is configured, ``T_cn_cnm1`` between consecutive cameras).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from roslan.sensors.cameras.config import CameraIntrinsics
    from roslan.sensors.cameras.model import CameraModel

__all__ = [
    "calib_txt",
    "camera_folder",
    "root_camera",
    "root_camera_name",
    "root_imu",
    "write_calibration",
]

F64 = NDArray[np.float64]


def root_camera_name(sensors: Iterable[tuple[str, str]]) -> str | None:
    """Name of the camera whose files make up the OUTDIR root in the Event Camera Dataset
    layout (``images.txt``, ``images/``, ``calib.txt``), from the ``(type, name)`` of every
    sensor in config order: the first event camera, else the first frame camera (a stereo
    pair: its left eye, ``<name>_left``); None without cameras."""
    pairs = list(sensors)
    for types in (("event_camera",), ("camera", "stereo_camera")):
        for kind, name in pairs:
            if kind in types:
                return f"{name}_left" if kind == "stereo_camera" else name
    return None


def root_camera(sensors: Sequence[Any]) -> str | None:
    """:func:`root_camera_name` of sensor configs ``sensors``."""
    return root_camera_name((str(s.type), str(s.name)) for s in sensors)


def root_imu(sensors: Sequence[Any]) -> str | None:
    """Name of the IMU whose readings are the OUTDIR root's ``imu.txt`` (and
    ``calib/imu.yaml``): the first IMU in config order; every other IMU writes
    ``imu_<name>.txt``. None without IMUs."""
    return next((str(s.name) for s in sensors if s.type == "imu"), None)


def _is_camera(cfg: Any) -> bool:
    """A camera-like sensor config (:class:`CameraIntrinsics`: frame, stereo, depth, event)."""
    return hasattr(cfg, "calibration_cameras")


def camera_folder(root: str | None, camera: str) -> str:
    """``''`` for the root camera ``root``, else ``'<camera>/'``: the folder holding that
    camera's ``images.txt``, ``images/`` and ``calib.txt`` (and an event camera's events
    files)."""
    return "" if root == camera else f"{camera}/"


def calib_txt(model: CameraModel) -> str:
    """``fx fy cx cy k1 k2 p1 p2 k3`` (Event Camera Dataset; equidistant: ``k1..k4``)."""
    D = (
        list(model.D)
        if model.distortion_model == "equidistant"
        else (list(model.ros_D()) + [0.0] * 5)[:5]
    )
    return " ".join(repr(float(x)) for x in (model.fx, model.fy, model.cx, model.cy, *D)) + "\n"


def _write(outdir: Path, rel: str, text: str) -> None:
    p = outdir / rel
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(text, encoding="utf-8")


def write_calibration(outdir: Path, sensors: Sequence[Any]) -> None:
    """Write the camera calibration files of a run with sensor configs ``sensors`` into
    ``outdir`` (nothing without cameras)."""
    import yaml

    cams_cfgs: list[CameraIntrinsics] = [s for s in sensors if _is_camera(s)]
    if not cams_cfgs:
        return
    root = root_camera(sensors)
    for config in cams_cfgs:
        for cam in config.calibration_cameras():
            info = cam.model.to_camera_info_yaml(Tx=cam.Tx)
            text = yaml.safe_dump(info, sort_keys=False, default_flow_style=None)
            _write(outdir, f"calib/{cam.name}.yaml", text)
            if getattr(config, "type", None) != "depth_camera":
                folder = camera_folder(root, cam.name)
                _write(outdir, f"{folder}calib.txt", calib_txt(cam.model))
    imu = next((s for s in sensors if getattr(s, "type", None) == "imu"), None)
    T_base_imu = imu.pose.matrix() if imu is not None else None
    chain: dict[str, Any] = {}
    prev: F64 | None = None
    all_cams = [c for s in cams_cfgs for c in s.calibration_cameras()]
    for i, cam in enumerate(all_cams):
        T_cam_base = np.linalg.inv(cam.T_base_optical)
        chain[f"cam{i}"] = cam.model.to_kalibr(
            rostopic=cam.rostopic,
            T_cam_imu=(T_cam_base @ T_base_imu) if T_base_imu is not None else None,
            T_cn_cnm1=(T_cam_base @ prev) if prev is not None else None,
        )
        prev = cam.T_base_optical
    text = yaml.safe_dump(chain, sort_keys=False, default_flow_style=None)
    _write(outdir, "calib/camchain.yaml", text)
