"""One simulation run: plan -> folder -> merge -> manifest.

:func:`run_simulation` holds OUTDIR's lock for the whole run and goes through four steps:

1. **Plan** (:func:`~roslan.pipeline.plan.make_plan`): every check that can fail before
   anything is written (trajectory, limits, sensors, names, topics, free space, OUTDIR);
   then the scene is loaded and the path's clearance checked (unless ``allow_collision``;
   :func:`~roslan.pipeline.plan.load_checked_scene`). ``--dry-run`` makes the same
   checks through :func:`~roslan.pipeline.plan.check_run`, writing nothing.
2. **Folder**: everything is written into a hidden sibling ``.<OUTDIR>.partial-XXXX``
   (:mod:`roslan.rundir.folder`): trajectory files, the scene export (on a thread of its
   own, beside the streaming), then
3. **Merge** (:mod:`roslan.pipeline.merge`): every component's lazy message generator
   through one stamp merge into the ROS 1 and/or ROS 2 writers, each bag written by its
   own thread with its chunks compressed in a pool (:mod:`roslan.io.bag_threads`). Memory
   is bounded by what each sensor holds for its current chunk, not by the trajectory
   length. Render-heavy sensors may run in worker processes (:mod:`roslan.pipeline.worker`)
   that send ready wire bytes through bounded queues; the merge order and every output
   byte are the same whatever the number of workers.
4. **Manifest**: sensors close (dataset files), the bags close, then the run-level files
   are written (``calib/extrinsics.yaml``, ``timing.json``, ``overview.png``,
   ``PLAYBACK.md``, ``README.md``) and finally ``run.json`` (:mod:`roslan.rundir.manifest`)
   with ``"complete": true``; the folder is renamed to OUTDIR (replacing an old OUTDIR
   only now, on success).

Any exception, Ctrl-C or SIGTERM removes the temporary folder; a SIGKILL leaves only the
hidden ``.partial`` folder, never an OUTDIR. Same config + seed => byte-identical files,
except ``timing.json`` and ``PLAYBACK.md``, which report this run's measured speed.
"""

from __future__ import annotations

import contextlib
import shutil
import signal
import threading
import time
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Any

from roslan.config.sim import SimConfig
from roslan.io.background import BackgroundSink
from roslan.io.bag import BAG_NAMES, MultiBagWriter
from roslan.io.messages import Flavor
from roslan.pipeline.context import Context
from roslan.pipeline.engine import SensorEngine
from roslan.pipeline.merge import CheckedStream, MergeItem, pump
from roslan.pipeline.plan import RunPlan, load_checked_scene, make_plan
from roslan.pipeline.report import BackgroundPlot, Progress, playback_text, print_profile
from roslan.pipeline.worker import WorkerJob, WorkerPool, sensor_stats, worker_nice
from roslan.rundir.calibration import root_camera, write_calibration
from roslan.rundir.extrinsics import write_extrinsics
from roslan.rundir.folder import clean_stale, finalize, make_temp, outdir_lock, run_files
from roslan.rundir.layouts import write_layouts
from roslan.rundir.manifest import (
    RUN_FILE,
    TIMING_FILE,
    RunManifest,
    Timing,
    TopicEntry,
    make_manifest,
    write_json,
)
from roslan.rundir.readme import flow_notes, outdir_readme
from roslan.sensors.registry import sensor_spec
from roslan.trajectory.base import Trajectory

if TYPE_CHECKING:
    from roslan.scene.model import Scene

__all__ = ["RunOptions", "run_simulation"]


@dataclass(frozen=True)
class RunOptions:
    """How to run (none of it changes an output byte, except ``overview``)."""

    overwrite: bool = False
    quiet: bool = False
    allow_collision: bool = False
    profile: bool = False
    overview: bool = True


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
) -> RunManifest:
    """Simulate ``config`` into ``outdir`` atomically; returns the content of run.json.

    Args:
        config: validated simulation config.
        outdir: output folder (must not exist unless ``overwrite``).
        overwrite: replace an existing roslan output folder (only once the new one is complete).
        quiet: no progress bar or profile table.
        formats: bag flavours (``'ros1'``, ``'ros2'``); default ``config.output.formats``.
        allow_collision: skip the scene clearance check.
        profile: record (and print unless quiet) per-sensor time in timing.json.
        config_path: the YAML file the config came from (relative paths, run.json).
        overview: draw ``overview.png`` (trajectory, camera, events, scan) at the end.
        workers: worker processes for the render-heavy sensors (``'auto'``, ``0`` = all
            in this process, ``N``); default ``config.output.workers``. Outputs are
            byte-identical whatever the value; timing.json records the one used.
    Raises:
        ConfigError: invalid sensors/topics/scene, or a path that hits the scene.
        OutputError: OUTDIR exists (without overwrite), is being written by another run,
            or cannot be written.
    """
    wall0 = time.perf_counter()
    outdir = Path(outdir).absolute()
    options = RunOptions(overwrite, quiet, allow_collision, profile, overview)
    with outdir_lock(outdir):
        clean_stale(outdir)
        plan = make_plan(
            config,
            outdir,
            overwrite=overwrite,
            formats=formats,
            config_path=config_path,
            workers=workers,
        )
        return _Run(plan, options, wall0).execute()


def _warm_up_plots() -> None:
    """:func:`roslan.plots.overview.warm_up`, on a thread: a failure here is only a lost
    head start (``write_overview`` reports any real problem)."""
    with contextlib.suppress(Exception):
        from roslan.plots.overview import warm_up

        warm_up()


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


class _Run:
    """The state of one run between its plan and its manifest."""

    def __init__(self, plan: RunPlan, options: RunOptions, wall0: float) -> None:
        self.plan = plan
        self.opts = options
        self.config = plan.config
        self.wall0 = wall0
        self.traj: Trajectory = plan.traj
        self.traj_config = plan.config.trajectory
        self.progress = Progress(options.quiet)
        self.pool: WorkerPool | None = None
        self.scene: Scene | None = None
        self.tmp: Path  # the hidden partial folder, made once the plan and scene hold
        self.ctx: Context  # this process's sensor context, made when the merge starts
        self.writers: MultiBagWriter | None = None
        self.plot: BackgroundPlot | None = None
        self.export: BackgroundSink | None = None  # the scene export's thread
        self.warm: threading.Thread | None = None  # overview.png's warm-up thread
        self.engine: SensorEngine | None = None
        self.streams: list[CheckedStream] = []
        self.ticks: dict[str, float] = {}
        self.write_s = 0.0
        self.bag_cpu_s = 0.0
        self.compress_cpu_s = 0.0
        self.build_s: dict[str, float] = {}
        self.close_s: dict[str, float] = {}

    @property
    def remote(self) -> set[int]:
        """Indices of the sensors that run in worker processes."""
        return self.pool.assigned if self.pool is not None else set()

    def execute(self) -> RunManifest:
        # the worker interpreters start (imports) while this process loads the scene
        if self.plan.groups:
            self.pool = WorkerPool(self.plan.groups, self.config.sensors, self.plan.render_helpers)
        try:
            self._load_scene()
            self.tmp = make_temp(self.plan.outdir)
        except BaseException:
            self.progress.stop()
            if self.pool is not None:
                self.pool.kill()
            raise
        try:
            with _sigterm_as_interrupt():
                self._start()
                self._merge()
                counts = self._close()
                manifest = self._write_run_files(counts)
                finalize(self.tmp, self.plan.outdir, self.opts.overwrite)
                self.progress.stop()
        except BaseException:
            self._abort()
            raise
        return manifest

    # -------------------------------------------------------------------- 1. plan: scene
    def _load_scene(self) -> None:
        checked = load_checked_scene(
            self.plan, allow_collision=self.opts.allow_collision, phase=self.progress.phase
        )
        self.scene, self.traj_config, self.traj = checked.scene, checked.traj_config, checked.traj

    # ------------------------------------------------------------------- 2. folder: start
    def _start(self) -> None:
        from roslan.trajectory.export import write_trajectory_files

        config, plan, tmp = self.config, self.plan, self.tmp
        self.ticks["setup"] = time.perf_counter()
        remote = self.remote
        if self.scene is not None and any(
            sensor_spec(sc.type).backend == "embree"
            for i, sc in enumerate(config.sensors)
            if i not in remote
        ):
            from roslan.render.raycast import get_raycaster

            self.progress.phase("building the scene's BVH (ray casting)")
            get_raycaster(self.scene)
        self.progress.phase("preparing sensors (the first run compiles kernels, then cached)")
        if self.pool is not None:  # the workers render while this process sets up
            self._send_jobs(self.pool)
        write_trajectory_files(self.traj, tmp, ground_truth_rate=config.output.ground_truth_rate)
        self.plot = BackgroundPlot(self.traj, tmp)
        if self.scene is not None:  # written beside the streaming (after the plot's fork)
            import roslan.scene as scene_mod

            self.export = BackgroundSink("scene-export", backlog=1)
            self.export.submit(scene_mod.export_scene, self.scene, tmp / "scene")
        out = config.output
        self.writers = MultiBagWriter(
            tmp, plan.formats, plan.bag_topics, out.compression, out.ros2_compression
        )

    def _send_jobs(self, pool: WorkerPool) -> None:
        config, plan = self.config, self.plan
        nices = dict(zip(pool.groups, worker_nice(pool.groups, config.sensors), strict=True))
        pool.send(
            lambda g: WorkerJob(
                trajectory=self.traj_config,
                outdir=self.tmp,
                seed=config.seed,
                start_time_ns=config.output.start_time,
                sensors=tuple(config.sensors),
                assigned=g,
                classes=tuple(type(plan.sensors[i]) for i in g),
                scene=self.scene,
                scene_spec=config.scene,
                base_dir=plan.base_dir,
                formats=plan.formats,
                profile=self.opts.profile,
                nice=nices[g],
                sensor_threads=plan.sensor_threads,
                render_helpers=tuple(plan.render_helpers.items()),
            )
        )

    def _context(self) -> Context:
        config = self.config
        return Context(
            self.traj,
            self.tmp,
            seed=config.seed,
            start_time_ns=config.output.start_time,
            sensors=config.sensors,
            scene_spec=config.scene,
            base_dir=self.plan.base_dir,
            scene=self.scene,
            sensor_threads=self.plan.sensor_threads,
            render_helpers=self.plan.render_helpers,
        )

    # ------------------------------------------------------------------------- 3. merge
    def _merge(self) -> None:
        plan, profile = self.plan, self.opts.profile
        assert self.writers is not None
        self.ctx = ctx = self._context()
        self.ticks["stream"] = time.perf_counter()
        # one step over the whole trajectory (the clock is fixed: nothing waits); merge
        # order: ground truth 0, sensor i -> i + 1 (ties resolve alike in workers)
        self.engine = SensorEngine(
            ctx, plan.sensors, plan.ground_truth, skip=self.remote, profile=profile
        )
        self.streams = self.engine.streams
        sources: list[Iterable[MergeItem]] = list(self.engine.sources())
        if self.pool is not None:
            sources += self.pool.streams(plan.formats)
        if self.opts.overview:  # matplotlib's first-draw costs, beside the streaming
            self.warm = threading.Thread(target=_warm_up_plots, name="overview-warm-up")
            self.warm.start()
        self.progress.start(self.traj.duration)
        self.write_s, self.build_s = pump(
            sources, self.writers, ctx.start_time_ns, self.progress, profile, plan.owners
        )
        self.progress.update(self.traj.duration)

    # --------------------------------------------------------------------- 4. manifest
    def _close(self) -> dict[str, int]:
        """Close workers, the plot, local sensors and the bags; the messages per topic."""
        assert self.writers is not None
        assert self.plot is not None
        self.progress.phase("closing sensors and bags")
        if self.pool is not None:
            self.pool.finish()
        if self.warm is not None:  # (before anything else draws with matplotlib)
            self.warm.join()
        self.plot.finish()
        if self.export is not None:
            self.export.close()  # raises the export's error, if any
        if self.engine is not None:
            self.close_s = self.engine.close_sensors()
        t0 = time.perf_counter()
        self.writers.close()
        self.write_s += time.perf_counter() - t0
        self.bag_cpu_s = self.writers.thread_cpu_s
        self.compress_cpu_s = self.writers.compress_cpu_s
        counts, self.writers = dict(self.writers.counts), None
        self.ticks["done"] = time.perf_counter()
        return counts

    def _write_run_files(self, counts: dict[str, int]) -> RunManifest:
        plan, tmp = self.plan, self.tmp
        write_calibration(tmp, self.config.sensors)
        write_extrinsics(tmp, plan.sensors, plan.ground_truth.static)
        topics: dict[str, TopicEntry] = {
            t.topic: {
                "type": t.msgtype,
                "messages": counts[t.topic],
                "publisher": plan.owners[t.topic],
            }
            for t in plan.bag_topics
        }
        manifest = make_manifest(
            config=self.config,
            config_path=plan.config_path,
            duration_s=self.traj.duration,
            touchdown_s=self.traj.T,
            bags={f: BAG_NAMES[Flavor(f)] for f in plan.formats},
            topics=topics,
            sensors=[s.config.name for s in plan.sensors],
            renderer=_image_formation(self.config.sensors),
        )
        wall = time.perf_counter() - self.wall0
        timing = self._timing(wall)
        if self.opts.overview:
            from roslan.plots.overview import overview_title, write_overview

            self.progress.phase("drawing overview.png")
            t0 = time.perf_counter()
            write_overview(tmp, title=overview_title(self.config.scene, self.config.seed))
            timing["overview_s"] = time.perf_counter() - t0
        write_json(tmp / TIMING_FILE, timing)
        (tmp / "PLAYBACK.md").write_text(
            playback_text(
                self.traj.duration,
                wall,
                plan.formats,
                counts,
                {t: e["type"] for t, e in topics.items()},
            ),
            encoding="utf-8",
        )
        if plan.formats:
            write_layouts(tmp, {t: e["type"] for t, e in topics.items()}, plan.formats)
        sensors = self.config.sensors
        readme = outdir_readme(tmp, root_camera(sensors), flow_notes(sensors))
        (tmp / "README.md").write_text(readme, encoding="utf-8")
        manifest["files"] = run_files(tmp)  # what --overwrite may replace, nothing else
        write_json(tmp / RUN_FILE, manifest)  # last: its presence marks a complete folder
        return manifest

    def _timing(self, wall: float) -> Timing:
        plan, ticks, duration = self.plan, self.ticks, self.traj.duration
        stream_s = ticks["done"] - ticks["stream"]
        timing: Timing = {
            "wall_time_s": wall,
            "setup_s": ticks["stream"] - ticks["setup"],
            "stream_start_s": ticks["stream"] - self.wall0,
            "stream_s": stream_s,
            # real-time factor = simulation wall time / trajectory time (<= 1: faster
            # than real time)
            "real_time_factor": wall / duration,
            "stream_real_time_factor": stream_s / duration,
            "workers": len(plan.groups),
            "worker_sensors": [[plan.sensors[i].config.name for i in g] for g in plan.groups],
            "sensor_threads": plan.sensor_threads,
            "render_helpers": dict(plan.render_helpers),
        }
        if self.opts.profile:
            timing["profile"] = self._profile()
        return timing

    def _profile(self) -> dict[str, Any]:
        by_name = {s.config.name: s for s in self.plan.sensors}
        local = {
            st.name: {
                "generator_s": st.seconds,
                "build_s": self.build_s.get(st.name, 0.0),
                "close_s": self.close_s.get(st.name, 0.0),
                "messages": st.count,
                **sensor_stats(by_name.get(st.name)),
            }
            for st in self.streams
        }
        # worker figures are the child's own (its wall clock, its build of the bytes)
        away = self.pool.profile() if self.pool is not None else {}
        names = ["ground_truth", *(s.config.name for s in self.plan.sensors)]
        per = {name: away.get(name) or local[name] for name in names}
        out: dict[str, Any] = {
            "sensors": per,
            "writers_s": self.write_s,
            "bag_threads_cpu_s": self.bag_cpu_s,
            "chunk_compression_cpu_s": self.compress_cpu_s,
        }
        if self.pool is not None:
            out["worker_wait"] = self.pool.wait_seconds()
        if not self.opts.quiet:
            self.progress.stop()
            print_profile(per, self.write_s)
        return out

    def _abort(self) -> None:
        if self.pool is not None:
            self.pool.kill()  # before removing tmp: the children write into it
        if self.plot is not None:
            self.plot.kill()
        if self.export is not None:
            self.export.abort()  # its running call ends before the folder is removed
        if self.engine is not None:  # sensors stop their own threads (before removing tmp)
            self.engine.abort()
        self.progress.stop()
        if self.writers is not None:
            self.writers.abort()
        shutil.rmtree(self.tmp, ignore_errors=True)


def _image_formation(sensors: Any) -> dict[str, Any] | None:
    """run.json's record of the renderer, for a run with a camera-type sensor (they all
    have the ``supersampling`` key); None otherwise (no OpenGL context is made)."""
    if not any(hasattr(s, "supersampling") for s in sensors):
        return None
    from roslan.render.gl import image_formation

    return image_formation()
