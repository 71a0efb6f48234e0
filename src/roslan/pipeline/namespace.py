"""The output namespace of a run: every sensor's frame ids and output names, checked in one
place before anything is written.

A sensor claims its ``name``, the names of its sub-cameras (a stereo camera ``st`` claims
``st_left`` and ``st_right``: they name its image folders and calibration files), its
``frame_id`` and every child frame it publishes on /tf_static (``st_left_optical``...).
Two sensors must not claim the same name or frame (their files or transforms would
overwrite each other), and no sensor may use a frame the ground truth owns (``world``,
``base_link``) as its own.
"""

from __future__ import annotations

from collections.abc import Sequence

from roslan.errors import ConfigError
from roslan.sensors.base import Sensor

__all__ = ["RESERVED_FRAMES", "check_namespace"]

RESERVED_FRAMES = ("world", "base_link", "map", "odom")
"""Frames the ground truth publishes (world -> base_link) or ROS reserves by convention."""


def claims(sensor: Sensor) -> dict[str, str]:
    """What ``sensor`` writes under a name: ``{name_or_frame: what}``."""
    c = sensor.config
    out: dict[str, str] = {c.name: "name"}
    for eye in getattr(sensor, "_eyes", None) or ():
        suffix = getattr(eye, "suffix", "")
        if suffix:
            out.setdefault(f"{c.name}_{suffix}", f"camera {c.name}_{suffix}")
    out.setdefault(c.frame, "frame_id")
    for tf in sensor.static_transforms():
        out.setdefault(tf.child, f"frame {tf.child}")
    return out


def check_namespace(sensors: Sequence[Sensor], source: str) -> None:
    """ConfigError naming both sensors when two claim one name or frame, or a sensor uses a
    reserved frame."""
    owner: dict[str, tuple[int, str, str]] = {}
    for i, s in enumerate(sensors):
        c = s.config
        for key, what in claims(s).items():
            if key in RESERVED_FRAMES:
                field = "frame_id" if key == c.frame else "name"
                msg = (
                    f"{source}: sensors[{i}].{field} = {key!r}: reserved frame "
                    f"({', '.join(RESERVED_FRAMES)} belong to the ground truth); "
                    "choose another name"
                )
                raise ConfigError(msg)
            if key in owner and owner[key][0] != i:
                j, other, other_what = owner[key]
                msg = (
                    f"{source}: sensors[{i}] ({c.name}): {what} {key!r} collides with "
                    f"sensors[{j}] ({other}) {other_what}: their files or transforms would "
                    "overwrite each other; rename one (or give a distinct frame_id)"
                )
                raise ConfigError(msg)
            owner[key] = (i, c.name, what)
