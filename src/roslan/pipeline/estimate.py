"""Disk use and run time of a simulation, known before it runs.

Every output is (number of messages or rows) x (bytes each) x (compression ratio): the
numbers of messages come from the sensors' rates and the trajectory's duration (closed
form, cheap); the bytes per message and per file row are those of the wire formats
(exact for fixed-size messages); the compression ratios, the event rate per pixel, the
LiDAR hit fraction and the CPU cost per unit of work were measured on the default job
(warehouse, 5.1 s; docs/performance.md). Event counts depend on the scene's texture and
the motion, so an estimate is a planning figure (aimed at a factor 1.5), not a promise.
"""

from __future__ import annotations

import math
import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from roslan.config.sim import SimConfig
from roslan.errors import OutputError
from roslan.limits import format_bytes

__all__ = [
    "RunEstimate",
    "batch_seconds",
    "check_free_space",
    "estimate_run",
    "format_bytes",
    "format_seconds",
]

# ---- measured on the default job (warehouse, DAVIS346 + 640x480 camera + HDL-32E)
EVENTS_PER_PIXEL_S = {"warehouse": 22.0, "refinery": 3.5, "empty": 20.0, None: 2.0}
"""Events per pixel per second of trajectory (DAVIS346, realistic preset; the paper
dataset: warehouse 10-13 M, refinery 1.5-2.5 M events per 7 s landing; the default job:
15.7 on 2026-11-25, 21.5 on 2026-11-26 with its flapping and the in-shader texture
filtering, 9.86 M events; 22.0 on 2026-11-28 with the davis346 noise fitted to a real
recording, 10.10 M events); scene files:
:data:`EVENTS_DEFAULT` (textured like the warehouse)."""
EVENTS_DEFAULT = 20.0
LIDAR_HIT_FRACTION = {"refinery": 0.8, "empty": 0.7, None: 0.0}
"""Fraction of LiDAR beams that return; enclosed scenes (not listed): 1.0."""

# compression ratio (compressed / raw) of each kind of payload per codec
_RATIO: dict[str, dict[str, float]] = {
    # (2026-11-26, ROS 1 lz4 fast mode, ROS 2 zstd level 1; measured: mono8 0.65 / 0.47,
    # events 0.65 / 0.43, HDL-32E clouds 0.84 / 0.66; rgb8 scaled from level 3's 0.38 / 0.34)
    "image": {"lz4": 0.5, "bz2": 0.4, "zstd": 0.41, "none": 1.0},
    "mono": {"lz4": 0.66, "bz2": 0.5, "zstd": 0.48, "none": 1.0},
    "events": {"lz4": 0.66, "bz2": 0.45, "zstd": 0.44, "none": 1.0},
    "cloud": {"lz4": 0.85, "bz2": 0.75, "zstd": 0.68, "none": 1.0},
    "small": {"lz4": 0.35, "bz2": 0.25, "zstd": 0.25, "none": 1.0},
    # the event camera's ground-truth images (2026-11-26, default landing, DAVIS346 at
    # 25 Hz; benchmarks/bench_outputs.py: 32FC2 optic_flow 0.89 / 0.79, 32FC1 depthmap
    # 0.86 / 0.68; bz2 not measured: taken as zstd)
    "flow": {"lz4": 0.89, "bz2": 0.79, "zstd": 0.79, "none": 1.0},
    "depth": {"lz4": 0.86, "bz2": 0.68, "zstd": 0.68, "none": 1.0},
}
_FLOW_PX = 8  # bytes per pixel of a 32FC2 optic_flow image (vx, vy float32, px/s)
_DEPTH_PX = 4  # bytes per pixel of a 32FC1 depthmap image (float32, m)
_PNG_RATIO = {"image": 0.33, "mono": 0.36, "depth": 0.5, "flow": 0.11}
# (flow: DSEC 16-bit RGB flow PNGs, 6 bytes per pixel raw; depth.h5: gzip-1 float32 with
# shuffle, 4 bytes per pixel raw; both measured 2026-11-28 on benchmarks/flow_epe.py's
# warehouse run, DAVIS346: 0.11 and 0.30)
_DEPTH_H5_RATIO = 0.3
_EVENT_TXT = 21.5  # bytes per events.txt line
_EVENT_H5 = {False: 2.9, True: 4.7}  # bytes per event in events.h5 (gzip), with t_ns?
_EVENT_ROS = {"ros1": 13.0, "ros2": 16.0}  # bytes per dvs_msgs/Event
_NPZ_POINT = 14.0  # bytes per point in a compressed .npz scan (8-bit intensities)
_POINT = 22.0  # bytes per PointCloud2 point (x y z intensity ring time)
_GT_TICK = 1190.0  # bytes of /tf, pose, odometry, accel, tau per ground-truth tick
_FIXED = 0.7e6  # overview.png, trajectory.png, calib/, run.json...
_SCENE_EXPORT = {"warehouse": 7.0e6, "refinery": 3.0e6, "empty": 0.05e6, None: 0.0}
_SCENE_DEFAULT = 7.0e6

# CPU seconds per unit of work (2-core machine of docs/performance.md)
_CPU_PER_MPIX_FRAME = 0.28  # a rendered (software, distorted) camera frame, per megapixel
_CPU_PER_MPIX_SAMPLE = 0.045  # an event camera render + pixel update, per megapixel
_CPU_PER_EVENT = 0.8e-6  # pixel model, packing and files, per event
_CPU_PER_MRAY = 1.5  # ray casting, per million rays
_CPU_PER_MB = 0.004  # serializing, compressing and writing, per MB written
_CPU_FIXED = 4.0  # start-up (worker processes), scene, overview
PARALLEL_EFFICIENCY = 0.7
"""Measured CPU use per core a run or a batch gets (139 % on 2 cores for one run; 185 %
for the paper dataset on 2 workers)."""


@dataclass
class RunEstimate:
    """Disk bytes and wall seconds of one run, with the bytes of each output."""

    bytes: float
    seconds: float
    cpu: float
    """CPU seconds (a batch's wall time is their sum over its cores)."""
    parts: dict[str, float] = field(default_factory=dict)


def _scene_key(scene: Any) -> str | None:
    return scene if scene in EVENTS_PER_PIXEL_S else "other"


def _flow_maps(s: Any, duration: float) -> int:
    """DSEC flow maps of an event camera: its ground-truth instants after the first (the
    first event comes after it) whose ``flow_interval`` ends by the end of the run."""
    rate = float(s.ground_truth_rate or s.rate)
    return max(0, math.floor((duration - float(s.flow_interval)) * rate + 1e-9))


def estimate_run(config: SimConfig, formats: tuple[str, ...] | None = None) -> RunEstimate:
    """Estimated disk use and wall time of ``run_simulation(config)``."""
    from roslan.trajectory import TauTrajectory

    fmts = tuple(formats or config.output.formats)
    duration = float(TauTrajectory(config.trajectory, warn=False).duration)
    codec = {"ros1": config.output.compression, "ros2": config.output.ros2_compression}
    key = _scene_key(config.scene)
    ev_rate = EVENTS_PER_PIXEL_S.get(key, EVENTS_DEFAULT) if key != "other" else EVENTS_DEFAULT
    hit = LIDAR_HIT_FRACTION.get(key, 1.0) if key != "other" else 1.0
    parts: dict[str, float] = {}
    cpu = _CPU_FIXED

    def add(name: str, nbytes: float) -> None:
        parts[name] = parts.get(name, 0.0) + nbytes

    def bag(kind: str, raw: float) -> None:
        for f in fmts:
            add(f"bag_{f}", raw * _RATIO[kind][codec[f]])

    n_gt = duration * config.output.ground_truth_rate
    bag("small", n_gt * _GT_TICK)
    add("files", duration / config.trajectory.sample_dt * 200.0)  # trajectory.csv, groundtruth
    for s in config.sensors:
        n = duration * float(getattr(s, "rate", 0.0) or 0.0)
        t = s.type
        if t in ("camera", "stereo_camera", "depth_camera", "event_camera"):
            w, h = _resolution(s)
            mpix = w * h / 1e6 * int(getattr(s, "supersampling", 1)) ** 2  # rendered pixels
            bag("small", n * 400.0)  # camera_info
            if t == "event_camera":
                events = ev_rate * w * h * duration
                for f in fmts:
                    add(f"bag_{f}", events * _EVENT_ROS[f] * _RATIO["events"][codec[f]])
                if getattr(s, "write_txt", True):
                    add("events.txt", events * _EVENT_TXT)
                if getattr(s, "write_h5", True):
                    exact = s.sub_microsecond_times  # type: ignore[attr-defined]
                    add("events.h5", events * _EVENT_H5[exact])
                n_truth = duration * float(s.ground_truth_rate or s.rate)  # type: ignore[attr-defined]
                if getattr(s, "optic_flow", False):
                    bag("flow", n_truth * (w * h * _FLOW_PX + 300.0))
                    add("flow", _flow_maps(s, duration) * w * h * 6 * _PNG_RATIO["flow"])
                if getattr(s, "depthmap", False):
                    bag("depth", n_truth * (w * h * _DEPTH_PX + 300.0))
                    add("depth.h5", n_truth * w * h * _DEPTH_PX * _DEPTH_H5_RATIO)
                if getattr(s, "aps", None) is not False:
                    bag("mono", n * w * h)
                    add("images", n * w * h * _PNG_RATIO["mono"])
                samples = duration * 0.5 * (float(s.min_rate) + float(s.max_rate))  # type: ignore[attr-defined]
                cpu += samples * mpix * _CPU_PER_MPIX_SAMPLE
                cpu += events * _CPU_PER_EVENT
            elif t == "depth_camera":
                bag("mono", n * w * h * 4)
                add("images", n * w * h * 2 * _PNG_RATIO["depth"])
                cpu += n * mpix * _CPU_PER_MPIX_FRAME
            else:
                eyes = 2 if t == "stereo_camera" else 1
                ch = 1 if getattr(s, "encoding", "rgb8") == "mono8" else 3
                kind = "mono" if ch == 1 else "image"
                bag(kind, eyes * n * w * h * ch)
                if getattr(s, "write_images", True):
                    add("images", eyes * n * w * h * ch * _PNG_RATIO[kind])
                sub = (
                    int(getattr(s, "exposure_samples", 1)) if getattr(s, "exposure_time", 0) else 1
                )
                cpu += eyes * n * mpix * _CPU_PER_MPIX_FRAME * max(1, sub)
        elif t in ("lidar", "solid_state_lidar"):
            rays = _rays_per_scan(s)
            points = rays * hit
            bag("cloud", n * (points * _POINT + 200.0))
            add("lidar", n * points * _NPZ_POINT)
            cpu += n * rays / 1e6 * _CPU_PER_MRAY
        elif t == "laser":
            beams = round((s.angle_max - s.angle_min) / s.angle_increment) + 1  # type: ignore[attr-defined]
            bag("small", n * (beams * 8.0 + 120.0))
            add("files", n * beams * 10.0)
            cpu += n * beams / 1e6 * _CPU_PER_MRAY
        elif t == "imu":
            bag("small", n * 315.0)
            add("imu.txt", n * 90.0)
        else:  # sonar, altimeter and other range-like sensors
            bag("small", n * 40.0)
            add("files", n * 25.0)
            cpu += n * 64 / 1e6 * _CPU_PER_MRAY
    add("scene", _SCENE_EXPORT.get(key, _SCENE_DEFAULT) if key != "other" else _SCENE_DEFAULT)
    add("other", _FIXED)
    total = sum(parts.values())
    cpu += total / 1e6 * _CPU_PER_MB
    heavy = sum(
        s.type in ("camera", "stereo_camera", "depth_camera", "event_camera", "lidar")
        for s in config.sensors
    )
    cores = max(1, min(os.cpu_count() or 1, 1 + heavy))  # one worker per heavy sensor
    seconds = cpu / max(1.0, cores * PARALLEL_EFFICIENCY)
    return RunEstimate(bytes=total, seconds=seconds, cpu=cpu, parts=parts)


def batch_seconds(estimates: list[RunEstimate], workers: int | None) -> float:
    """Wall time of running ``estimates`` on ``workers`` local processes (None: one per
    core; 0 or 1: one after the other)."""
    if not estimates:
        return 0.0
    if workers is not None and workers <= 1:
        return sum(e.seconds for e in estimates)
    cores = os.cpu_count() or 1
    par = min(cores, workers or cores, len(estimates))
    if par <= 1:
        return sum(e.seconds for e in estimates)
    return sum(e.cpu for e in estimates) / (par * 0.93)


def _resolution(s: Any) -> tuple[int, int]:
    res = getattr(s, "resolution", None)
    if res:
        return int(res[0]), int(res[1])
    try:
        model = s.camera_model()
        return int(model.width), int(model.height)
    except Exception:
        return 640, 480


def _rays_per_scan(s: Any) -> float:
    try:
        if s.type == "solid_state_lidar":
            spec = s.resolved()
            return float(spec.point_rate) / float(s.rate)
        spec = s.spec()
        return float(spec.azimuth_steps * spec.n_lasers)
    except Exception:
        return 32 * 2170 * 10.0 / float(s.rate)


def format_seconds(s: float) -> str:
    """``45 s``, ``3.5 min``, ``2.1 h``."""
    if s < 90:
        return f"{math.ceil(s):d} s"
    if s < 5400:
        return f"{s / 60:.1f} min"
    return f"{s / 3600:.1f} h"


def check_free_space(target: Path, needed: float, what: str) -> None:
    """Raise OutputError when the file system of ``target`` (or its nearest existing
    parent) has less than ``needed`` bytes free (plus 5 % margin)."""
    probe = Path(target).absolute()
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    free = shutil.disk_usage(probe).free
    if free < needed * 1.05:
        msg = (
            f"{target}: {what} needs about {format_bytes(needed)} (estimate) but only "
            f"{format_bytes(free)} is free on that file system; free space or choose another "
            "output folder"
        )
        raise OutputError(msg)
