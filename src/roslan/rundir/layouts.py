"""Ready viewer layouts of a run: ``landing.rviz`` (RViz) and ``landing.foxglove.json``.

Both are built from the run's own topics (``run.json``'s ``topics``: name -> type), so
they name nothing the bags lack. Displays, by message type:

=====================================  ==============================  ======================
type                                   RViz display                    Foxglove panel
=====================================  ==============================  ======================
visualization_msgs/MarkerArray         MarkerArray (``/scene``)        3D (topic visible)
tf2_msgs/TFMessage                     TF (frames, no topic)           3D (follows base_link)
nav_msgs/Odometry                      Odometry: the trajectory        (none: not drawn in 3D)
                                       (last 10000 poses as axes)
geometry_msgs/PoseStamped              (none: the Odometry shows it)   3D: the trajectory
sensor_msgs/Image ``*/image_raw``      Camera (with its camera_info)   Image
sensor_msgs/Image ``*/event_image``,   Image                           Image
``*/depthmap``, ``*/depth``
sensor_msgs/PointCloud2                PointCloud2 (intensity)         3D (topic visible)
sensor_msgs/LaserScan                  LaserScan                       3D (topic visible)
sensor_msgs/Range                      Range                           Plot (``.range``)
sensor_msgs/Imu                        (none in RViz)                  Plot (acceleration)
=====================================  ==============================  ======================

The fixed frame is ``world``. Neither tool draws ``dvs_msgs/EventArray``: the events are
shown as an image through the event camera's ``<topic>/event_image``
(:mod:`roslan.sensors.cameras.event_image`); its APS frames (``<topic>/image_raw``) get a
Camera display like any camera.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

__all__ = [
    "FOXGLOVE_3D_TYPES",
    "FOXGLOVE_FILE",
    "RVIZ_FILE",
    "foxglove_layout",
    "rviz_config",
    "write_layouts",
]

RVIZ_FILE = "landing.rviz"
FOXGLOVE_FILE = "landing.foxglove.json"
FIXED_FRAME = "world"


def _short(msgtype: str) -> str:
    return msgtype.replace("/msg/", "/")


def _image_topics(topics: Mapping[str, str]) -> list[str]:
    return [
        t
        for t, ty in topics.items()
        if _short(ty) == "sensor_msgs/Image"
        and t.rsplit("/", 1)[-1] in ("image_raw", "event_image", "depthmap", "depth", "image_rect")
    ]


def _rviz_displays(topics: Mapping[str, str]) -> list[dict[str, Any]]:
    d: list[dict[str, Any]] = [
        {"Class": "rviz/Grid", "Name": "Grid", "Enabled": True, "Reference Frame": FIXED_FRAME},
    ]
    for topic, msgtype in topics.items():
        ty = _short(msgtype)
        if ty == "visualization_msgs/MarkerArray":
            d.append(
                {
                    "Class": "rviz/MarkerArray",
                    "Name": f"Scene ({topic})",
                    "Enabled": True,
                    "Marker Topic": topic,
                    "Queue Size": 100,
                }
            )
        elif ty == "tf2_msgs/TFMessage" and topic == "/tf":
            d.append({"Class": "rviz/TF", "Name": "TF", "Enabled": True, "Show Names": False})
        elif ty == "nav_msgs/Odometry":
            d.append(
                {
                    "Class": "rviz/Odometry",
                    "Name": f"Trajectory ({topic})",
                    "Enabled": True,
                    "Topic": topic,
                    "Keep": 10000,
                    "Position Tolerance": 0.05,
                    "Angle Tolerance": 0.1,
                    "Shape": {"Value": "Axes", "Axes Length": 0.15, "Axes Radius": 0.01},
                }
            )
        elif ty == "sensor_msgs/PointCloud2":
            d.append(
                {
                    "Class": "rviz/PointCloud2",
                    "Name": f"Points ({topic})",
                    "Enabled": True,
                    "Topic": topic,
                    "Color Transformer": "Intensity",
                    "Channel Name": "intensity",
                    "Style": "Points",
                    "Size (Pixels)": 2,
                    "Decay Time": 0,
                }
            )
        elif ty == "sensor_msgs/LaserScan":
            d.append(
                {
                    "Class": "rviz/LaserScan",
                    "Name": f"Scan ({topic})",
                    "Enabled": True,
                    "Topic": topic,
                }
            )
        elif ty == "sensor_msgs/Range":
            d.append(
                {"Class": "rviz/Range", "Name": f"Range ({topic})", "Enabled": True, "Topic": topic}
            )
    for topic in _image_topics(topics):
        base = topic.rsplit("/", 1)[0]
        info = f"{base}/camera_info"
        if topic.endswith("/image_raw") and info in topics:
            d.append(
                {
                    "Class": "rviz/Camera",
                    "Name": f"Camera ({topic})",
                    "Enabled": True,
                    "Image Topic": topic,
                    "Transport Hint": "raw",
                    "Image Rendering": "background and overlay",
                    "Overlay Alpha": 0.5,
                }
            )
        else:
            d.append(
                {
                    "Class": "rviz/Image",
                    "Name": f"Image ({topic})",
                    "Enabled": True,
                    "Image Topic": topic,
                    "Transport Hint": "raw",
                    "Normalize Range": True,
                }
            )
    return d


def rviz_config(topics: Mapping[str, str]) -> str:
    """The text of ``landing.rviz`` (RViz 1 config, YAML) for a run with ``topics``."""
    doc: dict[str, Any] = {
        "Panels": [
            {"Class": "rviz/Displays", "Name": "Displays"},
            {"Class": "rviz/Time", "Name": "Time"},
        ],
        "Visualization Manager": {
            "Class": "",
            "Displays": _rviz_displays(topics),
            "Enabled": True,
            "Global Options": {
                "Background Color": "48; 48; 48",
                "Fixed Frame": FIXED_FRAME,
                "Frame Rate": 30,
            },
            "Name": "root",
            "Tools": [{"Class": "rviz/Interact"}, {"Class": "rviz/MoveCamera"}],
            "Value": True,
            "Views": {
                "Current": {
                    "Class": "rviz/Orbit",
                    "Name": "Current View",
                    "Target Frame": "base_link",
                    "Distance": 12.0,
                    "Pitch": 0.5,
                    "Yaw": 3.6,
                    "Focal Point": {"X": 0.0, "Y": 0.0, "Z": 0.0},
                }
            },
        },
        "Window Geometry": {"Height": 1000, "Width": 1600},
    }
    header = "# RViz (ROS 1) layout of this run: rviz -d landing.rviz (written by roslan)\n"
    return header + yaml.safe_dump(doc, sort_keys=False)


FOXGLOVE_3D_TYPES = frozenset(
    {
        "visualization_msgs/MarkerArray",
        "geometry_msgs/PoseStamped",
        "sensor_msgs/PointCloud2",
        "sensor_msgs/LaserScan",
    }
)
"""The run's message types the Foxglove 3D panel draws and the layout shows there (its
"supported messages"): the trajectory is ``/ground_truth/pose`` (PoseStamped, drawn as
an axis at each pose); nav_msgs/Odometry, which it does not draw, stays off the panel."""


def foxglove_layout(topics: Mapping[str, str]) -> dict[str, Any]:
    """Foxglove layout (import it in Foxglove: Layouts -> Import) for a run with ``topics``."""
    visible = {t: {"visible": True} for t, ty in topics.items() if _short(ty) in FOXGLOVE_3D_TYPES}
    config: dict[str, Any] = {
        "3D!scene": {
            "followTf": "base_link" if "/tf" in topics else FIXED_FRAME,
            "followMode": "follow-position",
            "scene": {"transforms": {"showLabel": False}},
            "layers": {
                "grid": {"layerId": "foxglove.Grid", "visible": True, "frameId": FIXED_FRAME}
            },
            "topics": visible,
            "cameraState": {
                "distance": 12.0,
                "phi": 60.0,
                "thetaOffset": 45.0,
                "perspective": True,
            },
        }
    }
    panels = ["3D!scene"]
    for i, topic in enumerate(_image_topics(topics)):
        key = f"Image!{i}"
        config[key] = {"imageMode": {"imageTopic": topic}, "cameraState": {}}
        panels.append(key)
    series = []
    for topic, ty in topics.items():
        if _short(ty) == "sensor_msgs/Imu":
            series += [
                {
                    "value": f"{topic}.linear_acceleration.{a}",
                    "enabled": True,
                    "timestampMethod": "headerStamp",
                }
                for a in "xyz"
            ]
        elif _short(ty) == "sensor_msgs/Range":
            series.append(
                {"value": f"{topic}.range", "enabled": True, "timestampMethod": "headerStamp"}
            )
    if series:
        config["Plot!series"] = {"paths": series, "showLegend": True}
        panels.append("Plot!series")
    side: Any = panels[-1]
    for key in reversed(panels[1:-1]):
        side = {"first": key, "second": side, "direction": "column"}
    layout: Any = (
        panels[0]
        if len(panels) == 1
        else {
            "first": panels[0],
            "second": side,
            "direction": "row",
            "splitPercentage": 60,
        }
    )
    return {
        "configById": config,
        "globalVariables": {},
        "userNodes": {},
        "playbackConfig": {"speed": 1.0},
        "layout": layout,
    }


def write_layouts(
    outdir: Path, topics: Mapping[str, str], formats: Sequence[str] = ("ros1", "ros2")
) -> None:
    """Write ``landing.foxglove.json`` into ``outdir``, and ``landing.rviz`` (an RViz 1
    layout: it plays landing.bag) when the run wrote the ROS 1 bag."""
    if "ros1" in formats:
        (outdir / RVIZ_FILE).write_text(rviz_config(topics), encoding="utf-8")
    text = json.dumps(foxglove_layout(topics), indent=2) + "\n"
    (outdir / FOXGLOVE_FILE).write_text(text, encoding="utf-8")
