"""Shared helpers of the pipeline / bag / IMU tests: tiny jobs that run in well under a second."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from roslan.config.sim import SimConfig

SHORT_TRAJECTORY: dict[str, Any] = {
    # T = z0 / (k v0) = 1.0 / (0.5 * 2.0) = 1 s, then 0.2 s at rest on the goal
    "k": 0.5,
    "initial": {"position": [-1.0, 0.5, 1.0], "rpy": [0.05, 0.1, 0.2], "descent_rate": 2.0},
    "hold": 0.2,
    # the world origin, given (the empty scene has no marker: without it, a warning)
    "goal": {"position": [0.0, 0.0, 0.0], "rpy": [0.0, 0.0, 0.0]},
}


def short_config(**overrides: Any) -> SimConfig:
    """A 1.2 s landing with one IMU (200 Hz) and 50 Hz ground truth."""
    data: dict[str, Any] = {
        "trajectory": SHORT_TRAJECTORY,
        "sensors": [
            {
                "type": "imu",
                "name": "imu",
                "rate": 200.0,
                "topic": "/imu",
                "pose": {"position": [0.05, -0.02, 0.03], "rpy": [0.1, -0.2, 0.3]},
            }
        ],
        "output": {"ground_truth_rate": 50.0},
        "seed": 3,
    }
    data.update(overrides)
    return SimConfig.model_validate(data)


def tree_bytes(
    root: Path, skip: tuple[str, ...] = ("timing.json", "PLAYBACK.md")
) -> dict[str, bytes]:
    """Every file under ``root`` (relative path -> content), except the documented
    non-deterministic ones."""
    return {
        str(p.relative_to(root)): p.read_bytes()
        for p in sorted(root.rglob("*"))
        if p.is_file() and p.name not in skip
    }
