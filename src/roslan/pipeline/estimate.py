"""Disk use and run time of a simulation, known before it runs.

Run time: the CPU seconds of the set-up (imports, checks, the scene and its BVH), of each
sensor's work, the ground truth, the writing and the plots, as measured on the dev
machine (:data:`IDLE_CPU_RATIO`); the wall time of an idle machine with this machine's
cores runs the set-up, then the main process beside one worker per heavy sensor (the
slowest of them, or all of them shared over the cores), then the plots. The first run on
a machine also compiles the event camera's kernels (:attr:`RunEstimate.first_run_seconds`).

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
from collections.abc import Callable, Mapping
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
_LABEL_POINT = 4.0  # bytes per point of a PointCloud2's uint32 label field
_LABEL_NPZ_POINT = 0.3  # bytes per point of a scan's compressed label array (warehouse: 0.20)
_LABEL_TEXT = 8.0  # bytes per label in laser_/range_<name>_labels.txt
_OBJECT_BYTES = {"ros1": 507.0, "ros2": 472.0}  # bytes per instance of the /objects message
_INSTANCES = {"warehouse": 799, "refinery": 89, "empty": 1, None: 0}
_INSTANCES_DEFAULT = 100  # a scene file's, before it is loaded
_GT_TICK = 1190.0  # bytes of /tf, pose, odometry, accel, tau per ground-truth tick
_FIXED = 0.7e6  # overview.png, trajectory.png, calib/, run.json...
_SCENE_EXPORT = {"warehouse": 7.0e6, "refinery": 3.0e6, "empty": 0.05e6, None: 0.0}
_SCENE_DEFAULT = 7.0e6

# CPU seconds per unit of work, as measured on the shared 2-core dev machine under load
# (benchmarks/bench_estimates.py, docs/performance.md "Run-time estimates")
_CPU_PER_MPIX_FRAME = 0.18  # a rendered (software, distorted) camera frame, per megapixel
_CPU_PER_MPIX_SAMPLE = 0.30  # an event camera render + pixel update, per megapixel
_CPU_PER_EVENT = 0.8e-6  # pixel model, packing and files, per event
_CPU_PER_MRAY = 1.5  # ray casting, per million rays
_CPU_PER_SCAN = 0.045  # rays, range model, packing and the .npz file of one scan
_CPU_PER_MB = 0.004  # serializing, compressing and writing, per MB written
_CPU_PER_GT_TICK = 0.5e-3  # ground truth: /tf, pose, odometry, accel, tau per tick
_CPU_START = 3.0  # imports, the config and the checks (clearance), the trajectory files
_CPU_SCENE = {"warehouse": 1.5, "refinery": 2.0, "empty": 0.2, None: 0.0}
"""The scene: building it (textures), its BVH, its export and its marker message."""
_CPU_SCENE_FILE = 1.0
_CPU_PLOTS = 2.0  # overview.png, trajectory.png, run.json, README
_HEAVY = ("camera", "stereo_camera", "depth_camera", "event_camera", "lidar", "solid_state_lidar")
"""Sensors a run gives a worker process of their own (pipeline.worker)."""
_KERNEL_COMPILE_S = 2.0
"""Seconds the first run on a machine adds to compile the event camera's numba kernels
(cached after; docs/performance.md)."""
IDLE_CPU_RATIO = 0.5
"""Seconds of an idle core per CPU second as the constants above were measured (the shared
2-core dev machine at load average 9-12, 2026-12-01): the default job's estimated 67 CPU-s
(61.7 measured there), run as its processes run, against its wall time on the quiet
2-core machine, 18.4-19.9 s (real-time factor 3.6-3.9, 2026-11-28)."""
PARALLEL_EFFICIENCY = 0.7
"""Measured CPU use per core a batch gets (185 % for the paper dataset on 2 workers;
:func:`batch_seconds`)."""


_LABEL_PNG_RATIO = 0.25
"""Bytes of a camera's instance + semantic PNGs per pixel (uint16, mostly flat regions:
0.15 + 0.10 measured at 96x72 in the warehouse, 2026-12-02; less at larger sizes)."""
_LABEL_FRAME_JSON = 60e3
"""Bytes of one frame's COCO annotations (about 150 visible instances of ~400 bytes with
their RLE masks in the warehouse)."""
_LABEL_FRAME_DETECTIONS = 15e3
"""Bytes of one frame's Detection2DArray (about 150 detections)."""
_LABEL_TABLES = 250e3
"""classes.json + instances.json (799 warehouse instances with their boxes)."""


@dataclass
class RunEstimate:
    """Disk bytes and wall seconds of one run, with the bytes of each output."""

    bytes: float
    seconds: float
    cpu: float
    """CPU seconds (a batch's wall time is their sum over its cores)."""
    parts: dict[str, float] = field(default_factory=dict)
    cores: int = 1
    """The cores the wall time assumes (an idle machine with this many)."""
    setup_seconds: float = 0.0
    """Of ``seconds``: the fixed set-up (imports, checks, the scene and its BVH)."""
    first_run_seconds: float = 0.0
    """Added on the first run on a machine (compiling the event camera's kernels)."""
    sensor_cpu: dict[str, float] = field(default_factory=dict)
    """Of ``cpu``: each sensor's own work (the rest: set-up, ground truth, writing, plots)."""
    label_files: int = 0
    """Files of ``output.labels`` (PNGs, annotations, tables) the run writes; their bytes
    are ``parts['labels']``."""

    def assumption(self) -> str:
        """What ``seconds`` assumes, for the dry run's summary line."""
        text = (
            f"on an idle machine with {self.cores} core{'s' if self.cores != 1 else ''}, "
            f"{math.ceil(self.setup_seconds):d} s of it set-up"
        )
        if self.first_run_seconds:
            first = self.first_run_seconds
            text += f"; the first run on a machine adds ~{first:.0f} s of kernel compilation"
        return text


def _scene_key(scene: Any) -> str | None:
    return scene if scene in EVENTS_PER_PIXEL_S else "other"


def _flow_maps(s: Any, duration: float) -> int:
    """DSEC flow maps of an event camera: its ground-truth instants after the first (the
    first event comes after it) whose ``flow_interval`` ends by the end of the run."""
    rate = float(s.ground_truth_rate or s.rate)
    return max(0, math.floor((duration - float(s.flow_interval)) * rate + 1e-9))


def _camera_labels(kind: str, n: float, w: int, h: int) -> tuple[int, float, float, float]:
    """A labelled frame/stereo/depth camera (or event camera's APS frames) of ``n`` frames:
    (files, disk bytes, raw mono16 bag bytes of ``<topic>/semantic`` and ``/instance``,
    raw detection bytes)."""
    eyes = 2 if kind == "stereo_camera" else 1
    frames = eyes * (math.floor(n + 1e-9) + 1)  # stamps from t = 0 on
    files = 2 * frames + eyes  # two PNGs a frame, annotations.json
    disk = frames * (w * h * _LABEL_PNG_RATIO + _LABEL_FRAME_JSON)
    return files, disk, frames * w * h * 4.0, frames * _LABEL_FRAME_DETECTIONS


def _spend_labels(
    add: Callable[[str, float], None],
    bag: Callable[[str, float], None],
    files: int,
    disk: float,
    mono: float,
    small: float,
) -> int:
    """Count a camera's label outputs (:func:`_camera_labels`): their disk and bag bytes;
    returns the number of files."""
    add("labels", disk)
    bag("mono", mono)
    bag("small", small)
    return files


def estimate_run(
    config: SimConfig,
    formats: tuple[str, ...] | None = None,
    *,
    base_dir: Path | None = None,
    duration: float | None = None,
) -> RunEstimate:
    """Estimated disk use and wall time of ``run_simulation(config)`` on an idle machine
    with this machine's cores. ``duration``: the trajectory's (s), when known; else built
    from the config (a pose file read from ``base_dir``)."""
    fmts = tuple(formats or config.output.formats)
    if duration is None:
        from roslan.trajectory import TauTrajectory
        from roslan.trajectory.spline import make_trajectory

        try:
            duration = make_trajectory(config.trajectory, base_dir=base_dir, warn=False).duration
        except Exception:  # an unreadable pose file is the run's error to report, not ours
            duration = TauTrajectory(config.trajectory, warn=False).duration
    duration = float(duration)
    codec = {"ros1": config.output.compression, "ros2": config.output.ros2_compression}
    key = _scene_key(config.scene)
    ev_rate = EVENTS_PER_PIXEL_S.get(key, EVENTS_DEFAULT) if key != "other" else EVENTS_DEFAULT
    hit = LIDAR_HIT_FRACTION.get(key, 1.0) if key != "other" else 1.0
    parts: dict[str, float] = {}
    work: dict[str, float] = {}  # CPU seconds of each sensor's own work
    label_files = 2 if config.output.labels else 0  # classes.json, instances.json
    if config.output.labels:
        parts["labels"] = _LABEL_TABLES

    def add(name: str, nbytes: float) -> None:
        parts[name] = parts.get(name, 0.0) + nbytes

    def spend(s: Any, seconds: float) -> None:
        work[s.name] = work.get(s.name, 0.0) + seconds

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
            aps = t != "event_camera" or getattr(s, "aps", None) is not False
            if getattr(s, "writes_labels", False) and aps:  # an event camera's APS frames too
                label_files += _spend_labels(add, bag, *_camera_labels(t, n, w, h))
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
                # adaptive sampling runs near max_rate through most of a landing
                samples = duration * (0.2 * float(s.min_rate) + 0.8 * float(s.max_rate))  # type: ignore[attr-defined]
                spend(s, samples * mpix * _CPU_PER_MPIX_SAMPLE + events * _CPU_PER_EVENT)
            elif t == "depth_camera":
                bag("mono", n * w * h * 4)
                add("images", n * w * h * 2 * _PNG_RATIO["depth"])
                spend(s, n * mpix * _CPU_PER_MPIX_FRAME)
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
                spend(s, eyes * n * mpix * _CPU_PER_MPIX_FRAME * max(1, sub))
        elif t in ("lidar", "solid_state_lidar"):
            rays = _rays_per_scan(s)
            points = rays * hit
            bag("cloud", n * (points * _POINT + 200.0))
            add("lidar", n * points * _NPZ_POINT)
            spend(s, n * (rays / 1e6 * _CPU_PER_MRAY + _CPU_PER_SCAN))
        elif t == "laser":
            beams = round((s.angle_max - s.angle_min) / s.angle_increment) + 1  # type: ignore[attr-defined]
            bag("small", n * (beams * 8.0 + 120.0))
            add("files", n * beams * 10.0)
            spend(s, n * beams / 1e6 * _CPU_PER_MRAY)
        elif t == "imu":
            bag("small", n * 315.0)
            add("imu.txt", n * 90.0)
        else:  # sonar, altimeter and other range-like sensors
            bag("small", n * 40.0)
            add("files", n * 25.0)
            spend(s, n * 64 / 1e6 * _CPU_PER_MRAY)
    for name, nbytes in _beam_labels(config, duration, hit, fmts, codec).items():
        add(name, nbytes)
    add("scene", _SCENE_EXPORT.get(key, _SCENE_DEFAULT) if key != "other" else _SCENE_DEFAULT)
    add("other", _FIXED)
    total = sum(parts.values())
    est = _timing(config, key, work, total, n_gt)
    est.bytes, est.parts = total, parts
    est.label_files = label_files
    return est


def _beam_labels(
    config: SimConfig,
    duration: float,
    hit: float,
    fmts: tuple[str, ...],
    codec: Mapping[str, str],
) -> dict[str, float]:
    """Disk bytes of the beam sensors' labels and /objects with ``output.labels``
    (docs/guide/labels.md): the ``label`` array of each LiDAR scan (``lidar labels``), its
    4 bytes per point in each bag's PointCloud2, the laser's and range sensors' label text
    files (``label text files (N)``), and the one /objects message in each bag."""
    if not config.output.labels:
        return {}
    parts: dict[str, float] = {}
    n_files = 0
    text = 0.0
    for s in config.sensors:
        if not getattr(s, "labels", False):
            continue
        n = duration * float(getattr(s, "rate", 0.0) or 0.0)
        if s.type in ("lidar", "solid_state_lidar"):
            points = n * _rays_per_scan(s) * hit
            parts["lidar labels"] = parts.get("lidar labels", 0.0) + points * _LABEL_NPZ_POINT
            for f in fmts:
                raw = points * _LABEL_POINT
                parts[f"bag_{f}"] = parts.get(f"bag_{f}", 0.0) + raw * _RATIO["small"][codec[f]]
        elif s.type == "laser":
            beams = round((s.angle_max - s.angle_min) / s.angle_increment) + 1  # type: ignore[attr-defined]
            text += n * beams * _LABEL_TEXT
            n_files += 1
        elif s.type in ("sonar", "altimeter"):
            text += n * (15.0 + _LABEL_TEXT)
            n_files += 1
    if n_files:
        parts[f"label text files ({n_files})"] = text
    if config.scene is not None:
        key = _scene_key(config.scene)
        n_inst = _INSTANCES.get(key, _INSTANCES_DEFAULT) if key != "other" else _INSTANCES_DEFAULT
        for f in fmts:
            raw = n_inst * _OBJECT_BYTES[f]
            parts[f"bag_{f}"] = parts.get(f"bag_{f}", 0.0) + raw * _RATIO["small"][codec[f]]
    return parts


def _timing(
    config: SimConfig, key: str | None, work: dict[str, float], total: float, n_gt: float
) -> RunEstimate:
    """The CPU and idle wall seconds of a run whose sensors do ``work`` (CPU seconds per
    sensor) and which writes ``total`` bytes and ``n_gt`` ground-truth ticks."""
    scene_cpu = _CPU_SCENE.get(key, _CPU_SCENE_FILE) if key != "other" else _CPU_SCENE_FILE
    setup = _CPU_START + scene_cpu
    # the main process's own stream: ground truth, the bags' writing, the light sensors
    main = n_gt * _CPU_PER_GT_TICK + total / 1e6 * _CPU_PER_MB
    heavy = [work.get(s.name, 0.0) for s in config.sensors if s.type in _HEAVY]
    main += sum(work.values()) - sum(heavy)
    cores = max(1, os.cpu_count() or 1)
    lanes = min(cores, 1 + len(heavy))  # the main process and one worker per heavy sensor
    stream = max([main, *heavy, (main + sum(heavy)) / lanes])
    events = any(s.type == "event_camera" for s in config.sensors)
    return RunEstimate(
        bytes=total,
        seconds=IDLE_CPU_RATIO * (setup + stream + _CPU_PLOTS),
        cpu=setup + _CPU_PLOTS + main + sum(heavy),
        cores=cores,
        setup_seconds=IDLE_CPU_RATIO * setup,
        first_run_seconds=_KERNEL_COMPILE_S if events else 0.0,
        sensor_cpu=work,
    )


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
    return IDLE_CPU_RATIO * sum(e.cpu for e in estimates) / (par * 0.93)


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
