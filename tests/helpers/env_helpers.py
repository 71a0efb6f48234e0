"""Shared helpers of the closed-loop tests: a landing that flies in about a second."""

from __future__ import annotations

from typing import Any

__all__ = ["marker_landing", "tiny_config"]


def tiny_config(**over: Any) -> dict[str, Any]:
    """A 1 s landing on the empty scene's ground: 500 Hz IMU, 64x48 downward event camera."""
    cfg: dict[str, Any] = {
        "trajectory": {
            "k": 0.5,
            "initial": {"position": [-1.0, 0.5, 1.0], "rpy": [0.05, 0.1, 0.2], "descent_rate": 2.0},
            "hold": 0.1,
            "flapping": {"frequency": 4.5, "heave": 0.008, "pitch": 0.035},
            "goal": {"position": [0.0, 0.0, 0.0], "rpy": [0.0, 0.0, 0.2]},
        },
        "scene": "empty",
        "sensors": [
            {"type": "imu", "name": "imu", "rate": 500.0},
            {
                "type": "event_camera",
                "name": "dvs",
                "rate": 10.0,
                "resolution": [64, 48],
                "max_rate": 300.0,
                "pose": {"position": [0.0, 0.0, -0.045], "rpy": [0.0, 1.5707963, 0.0]},
            },
        ],
        "output": {"ground_truth_rate": 50.0, "formats": ["ros1", "ros2"]},
    }
    cfg.update(over)
    return cfg


def marker_landing(
    closed_loop: dict[str, Any] | None = None, accelerometer_bias_sigma: float = 0.0
) -> dict[str, Any]:
    """A ~1.5 s landing onto the warehouse's marker from 1.5 m, flapping on, with a 500 Hz
    IMU (turn-on accelerometer bias ``accelerometer_bias_sigma``, m/s^2) and a 128x96
    downward event camera (realistic pixel); ``closed_loop``: the block, if any."""
    imu: dict[str, Any] = {"type": "imu", "name": "imu", "rate": 500.0}
    if accelerometer_bias_sigma:
        imu["accelerometer_turn_on_bias_sigma"] = accelerometer_bias_sigma
    cfg: dict[str, Any] = {
        "trajectory": {
            "k": 0.5,
            "initial": {
                "position": [0.6, -0.3, 1.5],
                "rpy": [0.02, 0.05, 0.3],
                "descent_rate": 2.0,
            },
            "hold": 0.1,
            "flapping": {"frequency": 4.5, "heave": 0.008, "pitch": 0.035},
            "goal": {"position": [2.0, -1.0, 0.01], "rpy": [0.0, 0.0, 0.3]},
        },
        "scene": "warehouse",
        "sensors": [
            imu,
            {
                "type": "event_camera",
                "name": "dvs",
                "rate": 10.0,
                "resolution": [128, 96],
                "max_rate": 300.0,
                "pose": {"position": [0.0, 0.0, -0.045], "rpy": [0.0, 1.5707963, 0.0]},
            },
        ],
        "output": {"ground_truth_rate": 50.0},
    }
    if closed_loop is not None:
        cfg["closed_loop"] = closed_loop
    return cfg
