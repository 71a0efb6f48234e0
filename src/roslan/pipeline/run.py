"""The simulation pipeline: trajectory -> sensors -> stamp-merged stream -> bags and files.

Steps of :func:`run_simulation`:

1. Validate everything that can fail before touching the disk: the trajectory, the
   cheap checks of :func:`preflight` (a scene for every sensor that needs one), every
   sensor (constructed from its config), topic uniqueness (sensors and ground truth),
   the scene and its clearance along the path (unless ``allow_collision``), the output
   folder (refused if it exists, unless ``overwrite``).
2. Write into a temporary sibling ``.<OUTDIR>.partial-XXXX``: trajectory files, the scene
   export, then stream every sensor's lazy message generator through one
   ``heapq.merge`` keyed by ``t_ns`` (ties broken by a stable order: ground truth
   first, then sensors in config order) into the ROS 1 and/or ROS 2 writers. Memory is
   bounded by what each sensor holds for its current chunk, not by the trajectory length.
   With ``workers`` (default ``output.workers: auto``), render-heavy sensors run in child
   processes (:mod:`roslan.pipeline.worker`) that send ready wire bytes through bounded
   queues, so rendering overlaps the writing here; the merge order and every output byte
   are the same as with ``workers=0``.
3. Close sensors (dataset files, calibration), bags, write ``calib/extrinsics.yaml``,
   ``PLAYBACK.md``, ``timing.json`` and finally ``run.json`` with ``"complete": true``;
   then rename the folder to OUTDIR (replacing an old OUTDIR only now, on success).

Any exception, Ctrl-C or SIGTERM removes the temporary folder; a SIGKILL leaves only the
hidden ``.partial`` folder, never an OUTDIR. Same config + seed => byte-identical files,
except ``timing.json`` and ``PLAYBACK.md``, which report this run's measured speed
(``run.json`` is deterministic; it points to ``timing.json``).
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import heapq
import json
import multiprocessing
import multiprocessing.process
import os
import platform
import shutil
import signal
import sys
import tempfile
import threading
import time
from collections.abc import Iterable, Iterator, Sequence
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from types import FrameType
from typing import Any

import numpy as np
import yaml

from roslan import __version__
from roslan.config.sim import SimConfig
from roslan.errors import ConfigError, OutputError, SensorError
from roslan.estimate import check_free_space, estimate_run
from roslan.io.bag import BAG_NAMES, BagTopic, MultiBagWriter
from roslan.io.messages import Flavor
from roslan.limits import preflight as check_limits
from roslan.pipeline.context import Context
from roslan.pipeline.namespace import check_namespace
from roslan.pipeline.worker import (
    MERGE_KEY,
    MergeItem,
    WorkerJob,
    WorkerPool,
    plan_workers,
    resolve_workers,
    worker_nice,
)
from roslan.rundir.calibration import root_camera, write_calibration
from roslan.sensors.base import Message, Sensor, StaticTransform
from roslan.sensors.ground_truth import BASE_FRAME, WORLD_FRAME, GroundTruth
from roslan.sensors.registry import sensor_class
from roslan.trajectory.frames import matrix_to_quat_xyzw, matrix_to_rpy
from roslan.trajectory.generator import Trajectory
from roslan.trajectory.spline import make_trajectory
from roslan.vehicle import base_link_trajectory

__all__ = ["RUN_FILE", "TIMING_FILE", "run_simulation", "static_transforms"]

RUN_FILE = "run.json"
TIMING_FILE = "timing.json"
PLOT_TIMEOUT_S = 300.0
"""Longest wait for the background trajectory plot before rendering it in-process."""
DEPENDENCIES = ("numpy", "scipy", "pydantic", "rosbags", "PyYAML", "trimesh", "moderngl", "embreex")


# ---------------------------------------------------------------------------- helpers
def _versions() -> dict[str, str]:
    out = {"roslan": __version__, "python": platform.python_version()}
    for dep in DEPENDENCIES:
        try:
            out[dep] = version(dep)
        except PackageNotFoundError:
            out[dep] = "not installed"
    return out


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


class _Stream:
    """One sensor's message generator, checked (time order, declared topics), optionally timed."""

    def __init__(self, name: str, gen: Iterator[Message], topics: set[str], profile: bool) -> None:
        self.name = name
        self.gen = gen
        self.topics = topics
        self.profile = profile
        self.seconds = 0.0
        self.count = 0

    def __iter__(self) -> Iterator[Message]:
        last = -1
        it = self.gen
        topics = self.topics
        perf = time.perf_counter
        while True:
            if self.profile:
                t0 = perf()
                msg = next(it, None)
                self.seconds += perf() - t0
            else:
                msg = next(it, None)
            if msg is None:
                return
            if msg.t_ns < last or msg.t_ns < 0:
                err = (
                    f"sensor {self.name!r} yielded t_ns={msg.t_ns} after {last}: "
                    "streams must be time-ordered"
                )
                raise SensorError(err)
            if msg.topic not in topics:
                err = (
                    f"sensor {self.name!r} yielded topic {msg.topic!r} not declared in "
                    f"its topics(): {sorted(topics)}"
                )
                raise SensorError(err)
            last = msg.t_ns
            self.count += 1
            yield msg


class _Progress:
    """Progress from the first second (stderr; nothing when quiet).

    Setup phases (loading the scene, building the BVH, preparing sensors, writing the
    overview) show a spinner on a terminal and one line each otherwise; the simulation
    itself is a bar with trajectory seconds done, the real-time factor and the time left.
    """

    def __init__(self, quiet: bool) -> None:
        self.total = 0.0
        self._bar: Any = None
        self._task: Any = None
        self._status: Any = None
        self._console: Any = None
        self._t0 = time.perf_counter()
        self.quiet = quiet
        if quiet:
            return
        from rich.console import Console

        self._console = Console(stderr=True)

    @property
    def tty(self) -> bool:
        return self._console is not None and bool(self._console.is_terminal)

    def phase(self, text: str) -> None:
        """Start a named setup phase (ends at the next phase, the bar or :meth:`stop`)."""
        if self._console is None:
            return
        self._end_status()
        if self.tty:
            self._status = self._console.status(f"{text}...")
            self._status.start()
        else:
            print(f"roslan: {text}...", file=sys.stderr, flush=True)

    def start(self, total_s: float) -> None:
        """The simulation bar over ``total_s`` seconds of trajectory."""
        self.total = total_s
        self._t0 = time.perf_counter()
        if self._console is None:
            return
        self._end_status()
        if not self.tty:
            print(f"roslan: simulating {total_s:.2f} s of trajectory...", file=sys.stderr)
            return
        from rich.progress import (
            BarColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        self._bar = Progress(
            TextColumn("simulating"),
            BarColumn(),
            TextColumn("{task.completed:.2f}/{task.total:.2f} s of trajectory"),
            TextColumn("{task.fields[rtf]}"),
            TimeElapsedColumn(),
            TextColumn("left"),
            TimeRemainingColumn(),
            console=self._console,
        )
        self._task = self._bar.add_task("sim", total=total_s, rtf="")
        self._bar.start()

    def update(self, t_s: float) -> None:
        if self._bar is None:
            return
        wall = time.perf_counter() - self._t0
        rtf = f"real-time factor {wall / t_s:.2f}" if t_s > 0 else ""
        self._bar.update(self._task, completed=min(t_s, self.total), rtf=rtf)

    def _end_status(self) -> None:
        if self._status is not None:
            self._status.stop()
            self._status = None
        if self._bar is not None:
            self._bar.stop()
            self._bar = None

    def stop(self) -> None:
        self._end_status()


_RAY_TYPES = frozenset({"lidar", "solid_state_lidar", "laser", "sonar", "altimeter"})
"""Sensor types that ray cast the scene (its BVH is built before the simulation starts)."""


def preflight(config: SimConfig, traj: Trajectory) -> None:
    """Every check that needs no rendering and no scene loaded, run before any work
    (before the scene loads, worker processes start or anything is written); each
    failure names the key or sensor concerned. Add further cheap checks here."""
    del traj  # kept in the signature for checks on the path
    for i, sc in enumerate(config.sensors):
        if config.scene is None and sc.needs_scene:
            msg = (
                f"sensors[{i}] ({sc.name!r}, type {sc.type}) needs a scene but the config "
                "has none; add e.g. 'scene: warehouse' (built-ins: warehouse, refinery, "
                "empty) or a scene YAML path"
            )
            raise ConfigError(msg)


def _plot_child(traj: Trajectory, folder: Path) -> None:
    # the parent handles Ctrl-C / SIGTERM and terminates this child: die quietly
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    from roslan.trajectory.export import write_trajectory_files

    write_trajectory_files(traj, folder, plot=True)


class _BackgroundPlot:
    """Renders trajectory.png (about a second of matplotlib) in a forked child process while
    the parent streams the sensors, so the one-off plot overlaps the simulation on a second
    core. Where ``fork`` is not safe (non-Linux, or other Python threads running) it renders
    in-process at :meth:`finish`."""

    def __init__(self, traj: Trajectory, tmp: Path) -> None:
        self.tmp = tmp
        self.folder = tmp / ".plot"
        self.proc: multiprocessing.process.BaseProcess | None = None
        self.folder.mkdir()
        self.traj = traj
        # fork only from a single-threaded process (a fork while another Python thread holds
        # a lock can deadlock the child); otherwise render in-process at finish()
        if sys.platform.startswith("linux") and threading.active_count() == 1:
            mp = multiprocessing.get_context("fork")
            self.proc = mp.Process(target=_plot_child, args=(traj, self.folder), daemon=True)
            self.proc.start()

    def finish(self) -> None:
        """Wait for the child; move its trajectory.png into place (OutputError if it failed)."""
        if self.proc is None:
            _plot_child_inline(self.traj, self.folder)
        else:
            self.proc.join(PLOT_TIMEOUT_S)
            if self.proc.is_alive():  # pragma: no cover - a stuck child: render here instead
                self.kill()
                _plot_child_inline(self.traj, self.folder)
            elif self.proc.exitcode != 0:
                msg = f"rendering trajectory.png failed (child exit code {self.proc.exitcode})"
                raise OutputError(msg)
        png = self.folder / "trajectory.png"
        if png.exists():
            png.replace(self.tmp / "trajectory.png")
        shutil.rmtree(self.folder, ignore_errors=True)

    def kill(self) -> None:
        if self.proc is not None and self.proc.is_alive():
            self.proc.terminate()
            self.proc.join(5)


def _plot_child_inline(traj: Trajectory, folder: Path) -> None:
    from roslan.trajectory.export import write_trajectory_files

    write_trajectory_files(traj, folder, plot=True)


@contextlib.contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """Turn SIGTERM into KeyboardInterrupt while running, so cleanup runs (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: FrameType | None) -> None:
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def _check_outdir(outdir: Path, overwrite: bool) -> None:
    if outdir.exists() or outdir.is_symlink():
        if not overwrite:
            msg = f"output folder {outdir} exists; pass --overwrite to replace it"
            raise OutputError(msg)
        if not outdir.is_dir():
            msg = f"output path {outdir} exists and is not a folder; refusing to replace it"
            raise OutputError(msg)
        if any(outdir.iterdir()) and not (outdir / RUN_FILE).exists():
            msg = (
                f"output folder {outdir} is not empty and holds no {RUN_FILE} "
                "(not a roslan output); "
                "refusing to replace it even with --overwrite"
            )
            raise OutputError(msg)


def _make_temp(outdir: Path) -> Path:
    parent = outdir.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{outdir.name}.partial-", dir=parent))
    except OSError as err:
        msg = f"cannot write output folder {outdir}: {err.strerror or err}"
        raise OutputError(msg) from err
    if not os.access(tmp, os.W_OK | os.X_OK):  # pragma: no cover - mkdtemp made it 0700
        shutil.rmtree(tmp, ignore_errors=True)
        msg = f"cannot write output folder {outdir}: not writable"
        raise OutputError(msg)
    return tmp


def _finalize(tmp: Path, outdir: Path, overwrite: bool = True) -> None:
    """Move the finished temporary folder to OUTDIR; an old OUTDIR is removed only now,
    and only with ``overwrite`` (one that appeared during the run is never replaced)."""
    tmp.chmod(0o755)  # mkdtemp creates 0700
    old: Path | None = None
    if not overwrite and (outdir.exists() or outdir.is_symlink()):
        msg = (
            f"output folder {outdir} appeared while this run was writing; not replacing it "
            "(pass --overwrite to replace it)"
        )
        raise OutputError(msg)
    if outdir.exists() or outdir.is_symlink():
        old = Path(tempfile.mkdtemp(prefix=f".{outdir.name}.old-", dir=outdir.parent))
        old.rmdir()
        outdir.rename(old)
    try:
        tmp.rename(outdir)
    except OSError as err:
        if old is not None:
            old.rename(outdir)
        msg = f"cannot move the finished output into {outdir}: {err}"
        raise OutputError(msg) from err
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def _write_json(path: Path, data: Any) -> None:
    path.write_text(json.dumps(data, indent=2, sort_keys=False) + "\n", encoding="utf-8")


def _extrinsics(sensors: Sequence[Sensor], static: Sequence[StaticTransform]) -> dict[str, Any]:
    out: dict[str, Any] = {"base_frame": BASE_FRAME, "world_frame": WORLD_FRAME, "sensors": {}}
    for s in sensors:
        c = s.config
        T = c.pose.matrix()
        out["sensors"][c.name] = {
            "type": c.type,
            "frame_id": c.frame,
            "topic": c.topic,
            "T_base_link_sensor": [[float(v) for v in row] for row in T],
            "position": [float(v) for v in T[:3, 3]],
            "rpy": [float(v) for v in matrix_to_rpy(T[:3, :3])],
            "quaternion_xyzw": [float(v) for v in matrix_to_quat_xyzw(T[:3, :3])],
        }
    out["static_transforms"] = [
        {
            "parent": t.parent,
            "child": t.child,
            "T": [[float(v) for v in row] for row in np.asarray(t.T)],
        }
        for t in static
    ]
    return out


def _playback(
    duration_s: float, wall_s: float, formats: Sequence[str], topics: dict[str, int]
) -> str:
    rtf = duration_s / wall_s if wall_s > 0 else float("inf")
    lines = [
        "# Playing this landing",
        "",
        f"Trajectory: {duration_s:.3f} s; this simulation took {wall_s:.3f} s of wall time "
        f"(R = trajectory time / simulation time = {rtf:.2f}).",
        "",
    ]
    if "ros1" in formats:
        lines += [
            "## ROS 1",
            "",
            "```bash",
            "rosbag info landing.bag",
            "rosparam set use_sim_time true   # stamps = start_time + trajectory time",
            "rosbag play --clock landing.bag             # real time",
            f"rosbag play --clock landing.bag -r {rtf:.2f}   # at the pace this simulation ran",
            "```",
            "",
        ]
    if "ros2" in formats:
        lines += [
            "## ROS 2",
            "",
            "```bash",
            "ros2 bag info landing_ros2",
            "ros2 bag play landing_ros2 --clock",
            f"ros2 bag play landing_ros2 --clock -r {rtf:.2f}",
            "```",
            "",
        ]
    lines += [
        "## Foxglove",
        "",
        "Open Foxglove Studio -> *Open local file* -> `landing_ros2/landing_ros2.mcap` (or "
        "`landing.bag`). Add a 3D panel (fixed frame `world`; /tf and /tf_static give "
        "`world -> base_link -> sensors`) and plots of `/ground_truth/odometry` and `/tau/state`.",
        "",
        "## Topics",
        "",
        "| topic | messages |",
        "|---|---|",
        *(f"| `{t}` | {n} |" for t, n in topics.items()),
        "",
    ]
    return "\n".join(lines)


# ---------------------------------------------------------------------------- main entry
def run_simulation(
    config: SimConfig,
    outdir: Path,
    *,
    overwrite: bool = False,
    quiet: bool = False,
    formats: Sequence[str] | None = None,
    allow_collision: bool = False,
    profile: bool = False,
    config_path: Path | None = None,
    overview: bool = True,
    workers: int | str | None = None,
) -> dict[str, Any]:
    """Simulate ``config`` into ``outdir`` atomically; returns the content of run.json.

    Holds an exclusive lock on ``outdir`` for the whole run (a second run into the same
    OUTDIR fails at once with OutputError) and first removes partial folders that dead
    runs left there. See :func:`_run_simulation` for the arguments.
    """
    from roslan.pipeline.outdir import clean_stale, outdir_lock

    outdir = Path(outdir).absolute()
    with outdir_lock(outdir):
        clean_stale(outdir)
        return _run_simulation(
            config,
            outdir,
            overwrite=overwrite,
            quiet=quiet,
            formats=formats,
            allow_collision=allow_collision,
            profile=profile,
            config_path=config_path,
            overview=overview,
            workers=workers,
        )


def _run_simulation(
    config: SimConfig,
    outdir: Path,
    *,
    overwrite: bool = False,
    quiet: bool = False,
    formats: Sequence[str] | None = None,
    allow_collision: bool = False,
    profile: bool = False,
    config_path: Path | None = None,
    overview: bool = True,
    workers: int | str | None = None,
) -> dict[str, Any]:
    """Simulate ``config`` into ``outdir`` atomically; returns the content of run.json.

    Args:
        config: validated simulation config.
        outdir: output folder (must not exist unless ``overwrite``).
        overwrite: replace an existing roslan output folder (only once the new one is complete).
        quiet: no progress bar or profile table.
        formats: bag flavours (``'ros1'``, ``'ros2'``); default ``config.output.formats``.
        allow_collision: skip the scene clearance check.
        profile: record (and print unless quiet) per-sensor time in timing.json.
        overview: draw ``overview.png`` (trajectory, camera, events, scan) at the end.
        config_path: the YAML file the config came from (relative scene paths, run.json).
        workers: worker processes for the render-heavy sensors (``'auto'``, ``0`` = all
            in this process, ``N``); default ``config.output.workers``. Outputs are
            byte-identical whatever the value; timing.json records the one used.
    Raises:
        ConfigError: invalid sensors/topics/scene, or a path that hits the scene.
        OutputError: OUTDIR exists (without overwrite) or cannot be written.
    """
    wall0 = time.perf_counter()
    outdir = Path(outdir).absolute()
    fmts = tuple(formats) if formats is not None else tuple(config.output.formats)
    for f in fmts:
        if f not in ("ros1", "ros2"):
            msg = f"bag format {f!r}: allowed 'ros1', 'ros2'"
            raise ConfigError(msg)
    fmts = tuple(dict.fromkeys(fmts))
    base_dir = config_path.parent.resolve() if config_path is not None else None

    # ---- 1. validate before writing anything
    _check_outdir(outdir, overwrite)
    traj = make_trajectory(config.trajectory, base_dir=base_dir)
    source = str(config_path) if config_path is not None else "<config>"
    check_limits(config, traj.duration, fmts, source)
    preflight(config, traj)
    check_free_space(outdir, estimate_run(config, fmts).bytes, "this run")
    sensors: list[Sensor] = []
    for i, sc in enumerate(config.sensors):
        try:
            sensors.append(sensor_class(sc.type)(sc))
        except ValueError as err:
            msg = f"sensors[{i}] ({sc.name}): {err}"
            raise SensorError(msg) from err
    check_namespace(sensors, source)
    gt = GroundTruth(config.output.ground_truth_rate, static_transforms(sensors))
    owners: dict[str, str] = {t.topic: "ground_truth" for t in gt.topics()}
    bag_topics = [BagTopic(t.topic, t.msgtype, t.topic in gt.LATCHED) for t in gt.topics()]
    for s in sensors:
        for t in s.topics():
            if t.topic in owners:
                msg = (
                    f"sensors: topic {t.topic!r} of sensor {s.config.name!r} "
                    "is already published by "
                    f"{owners[t.topic]!r}; every topic must be unique"
                )
                raise ConfigError(msg)
            owners[t.topic] = s.config.name
            bag_topics.append(BagTopic(t.topic, t.msgtype))
    n_workers = resolve_workers(
        config.output.workers if workers is None else workers, config.sensors
    )
    # (children need an interpreter to start and a POSIX fd to talk through)
    groups = (
        plan_workers(config.sensors, n_workers) if sys.executable and os.name == "posix" else []
    )
    # the worker interpreters start (imports) while this process loads the scene
    pool: WorkerPool | None = WorkerPool(groups, config.sensors) if groups else None
    progress = _Progress(quiet)
    try:
        scene = None
        if config.scene is not None:
            import roslan.scene as scene_mod

            progress.phase(f"loading scene {config.scene!r}")
            scene = scene_mod.load_scene(config.scene, base_dir=base_dir, seed=config.seed)
        # the goal is where the vehicle's contact point meets the surface: base_link's
        # trajectory ends above it (roslan.vehicle); only the goal moves, not the timing
        traj_config = base_link_trajectory(config.trajectory, config.vehicle, scene)
        if traj_config is not config.trajectory:
            traj = Trajectory(traj_config, warn=False)
        if scene is not None and not allow_collision:
            progress.phase("checking the path's clearance")
            hit = scene_mod.check_clearance(
                scene, traj, vehicle=config.vehicle, sensors=config.sensors
            )
            if hit is not None:
                msg = (
                    f"scene {config.scene!r}: {hit}; change the trajectory, the sensor "
                    "mounts or the vehicle block, or pass --allow-collision"
                )
                raise ConfigError(msg)
        # ---- 2. write into a temporary sibling
        tmp = _make_temp(outdir)
    except BaseException:
        progress.stop()
        if pool is not None:
            pool.kill()
        raise
    writers: MultiBagWriter | None = None
    plot: _BackgroundPlot | None = None
    streams: list[_Stream] = []
    try:
        with _sigterm_as_interrupt():
            from roslan.trajectory.export import write_trajectory_files

            t_setup = time.perf_counter()
            remote = pool.assigned if pool is not None else set()
            if scene is not None and any(
                sc.type in _RAY_TYPES for i, sc in enumerate(config.sensors) if i not in remote
            ):
                from roslan.render.raycast import get_raycaster

                progress.phase("building the scene's BVH (ray casting)")
                get_raycaster(scene)
            progress.phase("preparing sensors (the first run compiles kernels, then cached)")
            if pool is not None:  # the workers render while this process sets up
                nices = dict(
                    zip(pool.groups, worker_nice(pool.groups, config.sensors), strict=True)
                )
                pool.send(
                    lambda g: WorkerJob(
                        trajectory=traj_config,
                        outdir=tmp,
                        seed=config.seed,
                        start_time_ns=config.output.start_time,
                        sensors=tuple(config.sensors),
                        assigned=g,
                        classes=tuple(type(sensors[i]) for i in g),
                        scene=scene,
                        scene_spec=config.scene,
                        base_dir=base_dir,
                        formats=fmts,
                        profile=profile,
                        nice=nices[g],
                    )
                )
            write_trajectory_files(traj, tmp, plot=False)
            plot = _BackgroundPlot(traj, tmp)
            if scene is not None:
                import roslan.scene as scene_mod

                scene_mod.export_scene(scene, tmp / "scene")
            ctx = Context(
                traj,
                tmp,
                seed=config.seed,
                start_time_ns=config.output.start_time,
                sensors=config.sensors,
                scene_spec=config.scene,
                base_dir=base_dir,
                scene=scene,
            )
            writers = MultiBagWriter(
                tmp, fmts, bag_topics, config.output.compression, config.output.ros2_compression
            )
            t_stream = time.perf_counter()
            # merge order: ground truth 0, sensor i -> i + 1 (ties resolve alike in workers)
            streams = [
                _Stream("ground_truth", gt.messages(ctx), {t.topic for t in gt.topics()}, profile)
            ]
            orders = [0]
            for i, s in enumerate(sensors):
                if i not in remote:
                    topics = {t.topic for t in s.topics()}
                    streams.append(_Stream(s.config.name, s.messages(ctx), topics, profile))
                    orders.append(i + 1)
            sources: list[Iterable[MergeItem]] = [
                _tagged(o, st) for o, st in zip(orders, streams, strict=True)
            ]
            if pool is not None:
                sources += pool.streams(fmts)
            progress.start(traj.duration)
            write_seconds, build_seconds = _pump(
                sources, writers, ctx.start_time_ns, progress, profile, owners
            )
            progress.update(traj.duration)
            progress.phase("closing sensors and bags")
            if pool is not None:
                pool.finish()
            plot.finish()
            close_seconds: dict[str, float] = {}
            for i, s in enumerate(sensors):
                if i not in remote:
                    t0 = time.perf_counter()
                    s.close(ctx)
                    close_seconds[s.config.name] = time.perf_counter() - t0
            t0 = time.perf_counter()
            writers.close()
            write_seconds += time.perf_counter() - t0
            writers_counts, writers = writers.counts, None
            t_done = time.perf_counter()

            write_calibration(tmp, config.sensors)
            calib = tmp / "calib"
            calib.mkdir(exist_ok=True)
            with (calib / "extrinsics.yaml").open("w", encoding="utf-8") as fh:
                fh.write("# T_base_link_sensor of every sensor and the /tf_static tree (roslan)\n")
                yaml.safe_dump(_extrinsics(sensors, gt.static), fh, sort_keys=False)
            counts = dict(writers_counts)
            run = {
                "complete": True,
                "roslan_version": __version__,
                "config_file": str(config_path) if config_path is not None else None,
                "seed": config.seed,
                "start_time_ns": config.output.start_time,
                "start_time_utc": _dt.datetime.fromtimestamp(
                    config.output.start_time / 1e9, tz=_dt.UTC
                ).isoformat(),
                "time_offset_note": "bag stamps = start_time_ns + trajectory time; text files use "
                "seconds since the trajectory start",
                "trajectory_duration_s": traj.duration,
                "touchdown_time_s": traj.T,
                "formats": list(fmts),
                "bags": {f: BAG_NAMES[Flavor(f)] for f in fmts},
                "topics": {
                    t.topic: {
                        "type": t.msgtype,
                        "messages": counts[t.topic],
                        "publisher": owners[t.topic],
                    }
                    for t in bag_topics
                },
                "messages_total": sum(counts.values()),
                "sensors": [s.config.name for s in sensors],
                "versions": _versions(),
                "timing": f"{TIMING_FILE} (wall-clock figures; the only files that differ between "
                "identical runs are timing.json and PLAYBACK.md)",
                "config": config.model_dump(mode="json"),
            }
            wall = time.perf_counter() - wall0
            timing: dict[str, Any] = {
                "wall_time_s": wall,
                "setup_s": t_stream - t_setup,
                "stream_s": t_done - t_stream,
                # real-time factor = simulation wall time / trajectory time (<= 1: faster
                # than real time); speedup is its inverse.
                "real_time_factor": wall / traj.duration,
                "stream_real_time_factor": (t_done - t_stream) / traj.duration,
                "speedup": traj.duration / wall if wall > 0 else None,
                "workers": len(groups),
                "worker_sensors": [[sensors[i].config.name for i in g] for g in groups],
            }
            if profile:
                local = {
                    st.name: {
                        "generator_s": st.seconds,
                        "build_s": build_seconds.get(st.name, 0.0),
                        "close_s": close_seconds.get(st.name, 0.0),
                        "messages": st.count,
                    }
                    for st in streams
                }
                # worker figures are the child's own (its wall clock, its build of the bytes)
                away = pool.profile() if pool is not None else {}
                per = {
                    name: away.get(name) or local[name]
                    for name in ["ground_truth", *(s.config.name for s in sensors)]
                }
                timing["profile"] = {"sensors": per, "writers_s": write_seconds}
                if pool is not None:
                    timing["profile"]["worker_wait"] = pool.wait_seconds()
                if not quiet:
                    progress.stop()
                    _print_profile(per, write_seconds)
            if overview:
                from roslan.plots.overview import write_overview

                progress.phase("drawing overview.png")
                t0 = time.perf_counter()
                scene_name = config.scene or "no scene"
                write_overview(tmp, title=f"roslan run: {scene_name}, seed {config.seed}")
                timing["overview_s"] = time.perf_counter() - t0
            _write_json(tmp / TIMING_FILE, timing)
            (tmp / "PLAYBACK.md").write_text(
                _playback(traj.duration, wall, fmts, counts), encoding="utf-8"
            )
            from roslan.io.readme import outdir_readme

            readme = outdir_readme(tmp, root_camera(config.sensors))
            (tmp / "README.md").write_text(readme, encoding="utf-8")
            _write_json(tmp / RUN_FILE, run)  # last: its presence marks a complete folder
            _finalize(tmp, outdir, overwrite)
            progress.stop()
    except BaseException:
        if pool is not None:
            pool.kill()  # before removing tmp: the children write into it
        if plot is not None:
            plot.kill()
        for st in streams:  # sensors stop their own writer threads (before removing tmp)
            close = getattr(st.gen, "close", None)
            if close is not None:
                with contextlib.suppress(BaseException):
                    close()
        progress.stop()
        if writers is not None:
            writers.abort()
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return run


def _print_profile(per: dict[str, dict[str, Any]], writers_s: float) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title="time per component (s)")
    for col in ("component", "messages", "generator", "build", "close", "total"):
        table.add_column(col, justify="left" if col == "component" else "right")
    for name, p in per.items():
        total = p["generator_s"] + p["build_s"] + p["close_s"]
        table.add_row(
            name,
            str(p["messages"]),
            f"{p['generator_s']:.3f}",
            f"{p['build_s']:.3f}",
            f"{p['close_s']:.3f}",
            f"{total:.3f}",
        )
    table.add_row("bag writers", "", "", "", "", f"{writers_s:.3f}")
    Console(stderr=True).print(table)


def _tagged(order: int, stream: Iterable[Message]) -> Iterator[MergeItem]:
    for msg in stream:
        yield msg.t_ns, order, msg


def _pump(
    streams: Sequence[Iterable[MergeItem]],
    writers: MultiBagWriter,
    start_ns: int,
    progress: _Progress,
    profile: bool,
    owners: dict[str, str],
) -> tuple[float, dict[str, float]]:
    """Merge all streams by ``(t_ns, order)`` and write every message; returns writer and
    build seconds."""
    merged = (item[2] for item in heapq.merge(*streams, key=MERGE_KEY))
    every = 2048
    n = 0
    write_s = 0.0
    build_s: dict[str, float] = {}
    if not profile:
        for msg in merged:
            writers.write(msg.topic, start_ns + msg.t_ns, msg.build)
            n += 1
            if n % every == 0:
                progress.update(msg.t_ns * 1e-9)
        return write_s, build_s
    perf = time.perf_counter
    for msg in merged:
        t0 = perf()
        datas = writers.build(msg.topic, msg.build)
        t1 = perf()
        writers.write_data(msg.topic, start_ns + msg.t_ns, datas)
        t2 = perf()
        owner = owners[msg.topic]
        build_s[owner] = build_s.get(owner, 0.0) + (t1 - t0)
        write_s += t2 - t1
        n += 1
        if n % every == 0:
            progress.update(msg.t_ns * 1e-9)
    return write_s, build_s
