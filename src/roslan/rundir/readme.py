"""``README.md`` of a simulation OUTDIR: what each file holds, column by column.

The dataset text files have no header or comment lines (as in the Event Camera Dataset,
Mueggler et al. 2017, and TUM), so every one loads with
``pandas.read_csv(path, sep=" ", header=None)``; their columns are described here instead.
The text depends only on the files present and the root camera, so it is deterministic.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

__all__ = ["FlowNote", "flow_notes", "flow_text", "outdir_readme"]


class FlowNote(NamedTuple):
    """The settings behind an event camera's DSEC flow maps, for the README."""

    interval: float
    """``flow_interval``, s."""
    sky: str
    """``flow_sky``: ``valid`` or ``invalid``."""
    distorted: bool
    """The camera has lens distortion."""


def flow_notes(sensors: Sequence[Any]) -> dict[str, FlowNote]:
    """:class:`FlowNote` of every event camera with ``optic_flow`` (sensor configs)."""
    return {
        str(s.name): FlowNote(
            float(s.flow_interval), str(s.flow_sky), not s.camera_model().is_pinhole
        )
        for s in sensors
        if s.type == "event_camera" and getattr(s, "optic_flow", False)
    }


def flow_text(note: FlowNote | None) -> str:
    """The README's description of a ``flow`` folder (DSEC layout) and its settings."""
    interval = f"`flow_interval`: {note.interval:g} s" if note else "`flow_interval`"
    sky = f"`flow_sky: {note.sky}`" if note else "`flow_sky`"
    lens = (
        "this camera has no lens distortion, so they are rectified too"
        if note is not None and not note.distorted
        else "with the lens distortion: not rectified"
    )
    return (
        "DSEC optical-flow layout: `flow/forward/NNNNNN.png` 16-bit RGB, R = flow_x * 128 + "
        "2^15, G = flow_y * 128 + 2^15, B = valid (1/0), decoded `flow = (png[..., :2] - "
        "2**15) / 128`, listed in `flow/forward_timestamps.txt` (header line, then `from, to` "
        "absolute microseconds per PNG). The PNG is the true displacement (px) of each "
        "pixel's scene point from `from_timestamp_us` to `to_timestamp_us` "
        f"({interval}), in the pixel coordinates of `events.h5`'s `x, y`: raw, distorted "
        f"sensor pixels ({lens}). valid = 0 where the point is occluded at `to` (more than "
        "2 % behind every surface seen on the 3x3 pixels around its new position), leaves "
        "the image, moves 256 px or more, or where nothing is hit "
        f"({sky}). The bag's `<topic>/optic_flow` is another quantity: the instantaneous "
        "motion field (px/s) at its stamp. Maps start at the ground-truth instants after "
        "the first event whose interval ends by the end of the run."
    )


_ROOT_FILES: tuple[tuple[str, str], ...] = (
    (
        "events.txt",
        "`t x y p`: one event per line; t in s since the trajectory start "
        "(9 decimals), x, y pixel (0, 0 = top left), p 1 ON (brighter) / 0 OFF.",
    ),
    (
        "events.h5",
        "DSEC layout: `events/t` (int64, microseconds since the trajectory "
        "start), `events/x`, `events/y` (uint16), `events/p` (uint8, 1 ON / 0 OFF), `t_offset` "
        "(microseconds to add for the absolute bag stamp), `ms_to_idx` (index of the first "
        "event of each millisecond), and, only for event times finer than the sensor's 1 us "
        "(`timestamp_resolution`), `events/t_ns` (the exact nanosecond times).",
    ),
    (
        "images.txt",
        "`t path`: one frame per line, t in s since the trajectory start "
        "(middle of the shutter window: of the middle row's exposure), path relative to "
        "this folder (`images/NNNNNNNN.png`).",
    ),
    (
        "exposures.txt",
        "`t exposure`: the exposure (s) of each frame of `images.txt` (same t), "
        "auto-exposure's choice or the fixed `exposure_time`.",
    ),
    (
        "calib.txt",
        "`fx fy cx cy k1 k2 p1 p2 k3` of the camera whose frames `images.txt` "
        "lists (pixels; equidistant lens: `fx fy cx cy k1 k2 k3 k4`).",
    ),
    (
        "imu.txt",
        "`t ax ay az gx gy gz`: t in s since the trajectory start, specific force "
        "in m/s^2 and angular rate in rad/s, in the IMU frame.",
    ),
    (
        "groundtruth.txt",
        "`t px py pz qx qy qz qw` (TUM): pose of base_link in the world "
        "frame, m and unit quaternion; t in s since the trajectory start; one row per "
        "`/ground_truth/pose` message (`output.ground_truth_rate`, plus the end of the run).",
    ),
    (
        "trajectory.csv",
        "comma-separated, with a header line: `t` and the 18 tau-trajectory "
        "components (gaps, rates, accelerations) in the goal frame F.",
    ),
    ("landing.bag", "ROS 1 bag (v2.0, chunked); `rosbag info landing.bag`."),
    (
        "depth.h5",
        "MVSEC layout: `davis/left/depth_image_raw` (N, H, W) float32 depth of the root event "
        "camera in m along the optical axis (NaN: nothing hit), `davis/left/depth_image_raw_ts` "
        "(N,) float64 absolute s (bag stamps), `davis/left/depth_image_raw_t_ns` (N,) int64 ns "
        "since the trajectory start; the same images as `<topic>/depthmap`.",
    ),
    ("flow", ""),  # (flow_text: the camera's settings)
    ("landing.rviz", "RViz layout of the bag's topics: `rviz -d landing.rviz`."),
    (
        "landing.foxglove.json",
        "Foxglove layout of the bag's topics (Layouts > Import from file).",
    ),
    (
        "landing_ros2",
        "ROS 2 bag (MCAP, compressed chunks) and metadata.yaml; `ros2 bag info landing_ros2`.",
    ),
    (
        "lidar",
        "`lidar/<name>/NNNNNN.npz` (compressed NumPy arrays `x y z intensity ring time`"
        " and `stamp` in ns) listed in `lidar/<name>/timestamps.txt` (`t <name>/NNNNNN.npz`).",
    ),
    (
        "calib",
        "`calib/<camera>.yaml` (ROS camera_info), `camchain.yaml` (Kalibr), "
        "`imu.yaml` (Kalibr IMU noise), `extrinsics.yaml` (every `T_base_link_sensor`).",
    ),
    (
        "scene",
        "the scene's models and poses (also in both bags: the latched `/scene` MarkerArray).",
    ),
    (
        "images",
        "`NNNNNNNN.png`: the frames `images.txt` lists (8-bit PNG, the camera's encoding).",
    ),
    (
        "summary.json",
        "the landing's figures: touchdown time, tau(0), k, the goal (of base_link), the "
        "terminal behaviour.",
    ),
    (
        "trajectory.png",
        "left, the 3-D path in the goal frame F (a file trajectory: relative to its last "
        "pose) with start, goal and velocity arrows; right, the six gaps (x, y, z in m; "
        "roll, pitch, yaw in rad) against time, touchdown T dashed.",
    ),
    (
        "overview.png",
        "one look at the run: the path in the goal frame, a camera frame, the events and "
        "a LiDAR scan or the IMU of the same instant.",
    ),
    (
        "depth",
        "`depth/<name>/NNNNNNNN.png` of each depth camera: 16-bit PNGs in millimetres "
        "(0 = no return), listed in `depth_<name>.txt`.",
    ),
    ("README.md", "this file."),
    (
        "run.json",
        "resolved config, seed, versions, messages per topic, and every file the run wrote "
        "(what `--overwrite` may replace).",
    ),
    (
        "episode.json",
        "the closed-loop episode (`roslan fly`, `roslan.env` with `record`): policy, seed, "
        "success, reason (touchdown, collision, ...), touchdown time and speeds, position and "
        "heading error.",
    ),
    ("timing.json", "wall time and real-time factor of this run."),
    ("PLAYBACK.md", "how to play the bags."),
)

_PATTERNS: tuple[tuple[str, str], ...] = (
    ("imu_*.txt", "`t ax ay az gx gy gz` of the IMU `<name>` (as imu.txt)."),
    (
        "range_*.txt",
        "`t range` of the range sensor `<name>`: m, `inf` no return, `-inf` "
        "closer than the minimum.",
    ),
    (
        "laser_*.txt",
        "`t r_0 .. r_n` of the laser `<name>`: ranges in m at angles "
        "`angle_min + i * angle_increment` (run.json); `inf` no return, `-inf` too close.",
    ),
    (
        "range_*_labels.txt",
        "`t label` of the range sensor `<name>` (`output.labels`): uint32, class id in the "
        "low 16 bits, instance id in the high 16, of the surface read; 0: no finite range.",
    ),
    (
        "laser_*_labels.txt",
        "`t l_0 .. l_n` of the laser `<name>` (`output.labels`): uint32 per beam, class id in "
        "the low 16 bits, instance id in the high 16; 0: no finite range.",
    ),
    (
        "depth_*.txt",
        "`t path` of the depth camera `<name>`; 16-bit PNGs in millimetres "
        "(0 = no return) under `depth/<name>/`.",
    ),
)


def outdir_readme(
    outdir: Path, root_camera: str | None, flow: Mapping[str, FlowNote] | None = None
) -> str:
    """The README text for the files now in ``outdir`` (``flow``: :func:`flow_notes`)."""
    flow = flow or {}
    names = {p.name for p in outdir.iterdir() if not p.name.startswith(".")}
    names |= {"run.json", "README.md"}  # written after this text
    lines = [
        "# roslan simulation output",
        "",
        "Event Camera Dataset layout. Text files have no header or comment lines: each loads",
        'with `pandas.read_csv(path, sep=" ", header=None)` (or `numpy.loadtxt`). Times are',
        "seconds since the trajectory start with nine decimals; add `output.start_time`",
        "(run.json) for the absolute bag stamp.",
        "",
    ]
    if root_camera is not None:
        lines += [
            f"The root `images.txt`, `images/` and `calib.txt` are the camera `{root_camera}`'s"
            " (the first event camera, else the first camera); every other camera has the",
            "same files in its own folder `<name>/` (an event camera also `events.txt`,",
            "`events.h5`).",
            "",
        ]
    lines += ["| file | content |", "|---|---|"]
    for name, text in _ROOT_FILES:
        if name == "flow" and name in names:
            note = flow.get(root_camera) if root_camera is not None else None
            lines.append(f"| `flow` | the root event camera's {flow_text(note)} |")
        elif name in names:
            lines.append(f"| `{name}` | {text} |")
    for pattern, text in _PATTERNS:
        for p in sorted(outdir.glob(pattern)):
            if p.stem.endswith("_labels") != pattern.endswith("_labels.txt"):
                continue  # a labels file has its own row
            name = p.stem.split("_", 1)[1].removesuffix("_labels")
            lines.append(f"| `{p.name}` | {text.replace('<name>', name)} |")
    for d in sorted(p for p in outdir.iterdir() if p.is_dir() and (p / "images.txt").is_file()):
        files = ", ".join(
            f"`{f}`"
            for f in (
                "images.txt",
                "exposures.txt",
                "calib.txt",
                "events.txt",
                "events.h5",
                "depth.h5",
                "flow",
            )
            if (d / f).exists()
        )
        text = f"camera `{d.name}`: {files}, `images/` (as at the root)"
        if (d / "flow").is_dir():
            text += f"; its `flow`: {flow_text(flow.get(d.name))}"
        lines.append(f"| `{d.name}/` | {text} |")
    return "\n".join(lines) + "\n"
