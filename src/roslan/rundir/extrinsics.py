"""``calib/extrinsics.yaml``: every sensor's mount and the /tf_static tree, once per run."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from roslan.frames import matrix_to_quat_xyzw, matrix_to_rpy
from roslan.sensors.base import Sensor, StaticTransform
from roslan.sensors.ground_truth import BASE_FRAME, WORLD_FRAME

__all__ = ["EXTRINSICS_FILE", "extrinsics", "static_transforms", "write_extrinsics"]

EXTRINSICS_FILE = "calib/extrinsics.yaml"


def static_transforms(sensors: Sequence[Sensor]) -> list[StaticTransform]:
    """/tf_static content: ``base_link -> frame`` from each sensor's extrinsics, then each
    sensor's own ``static_transforms()`` (a returned child frame replaces the default one)."""
    by_child: dict[str, StaticTransform] = {}
    for s in sensors:
        by_child[s.config.frame] = StaticTransform(
            BASE_FRAME, s.config.frame, s.config.pose.matrix()
        )
        for tf in s.static_transforms():
            by_child[tf.child] = StaticTransform(
                tf.parent, tf.child, np.asarray(tf.T, dtype=np.float64)
            )
    return list(by_child.values())


def _matrix(T: Any) -> list[list[float]]:
    return [[float(v) for v in row] for row in np.asarray(T)]


def extrinsics(sensors: Sequence[Sensor], static: Sequence[StaticTransform]) -> dict[str, Any]:
    """The content of ``calib/extrinsics.yaml``."""
    out: dict[str, Any] = {"base_frame": BASE_FRAME, "world_frame": WORLD_FRAME, "sensors": {}}
    for s in sensors:
        c = s.config
        T = c.pose.matrix()
        out["sensors"][c.name] = {
            "type": c.type,
            "frame_id": c.frame,
            "topic": c.topic,
            "T_base_link_sensor": _matrix(T),
            "position": [float(v) for v in T[:3, 3]],
            "rpy": [float(v) for v in matrix_to_rpy(T[:3, :3])],
            "quaternion_xyzw": [float(v) for v in matrix_to_quat_xyzw(T[:3, :3])],
        }
    out["static_transforms"] = [
        {"parent": t.parent, "child": t.child, "T": _matrix(t.T)} for t in static
    ]
    return out


def write_extrinsics(
    outdir: Path, sensors: Sequence[Sensor], static: Sequence[StaticTransform]
) -> None:
    """Write ``OUTDIR/calib/extrinsics.yaml``."""
    path = outdir / EXTRINSICS_FILE
    path.parent.mkdir(exist_ok=True)
    with path.open("w", encoding="utf-8") as fh:
        fh.write("# T_base_link_sensor of every sensor and the /tf_static tree (roslan)\n")
        yaml.safe_dump(extrinsics(sensors, static), fh, sort_keys=False)
