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
import signal
import threading
import time
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING

from roslan.config.sim import SimConfig
from roslan.pipeline.engine import SensorEngine
from roslan.pipeline.merge import MergeItem, pump
from roslan.pipeline.plan import RunPlan, load_checked_scene, make_plan
from roslan.pipeline.record import Recorder, RunOptions
from roslan.pipeline.report import Progress
from roslan.pipeline.worker import WorkerJob, WorkerPool, worker_nice
from roslan.rundir.folder import clean_stale, outdir_lock
from roslan.rundir.manifest import RunManifest
from roslan.sensors.registry import sensor_spec
from roslan.trajectory.base import Trajectory

if TYPE_CHECKING:
    from roslan.io.files import DatasetFolder
    from roslan.render.backends import SceneBackends
    from roslan.scene.model import Scene

__all__ = ["RunOptions", "run_simulation"]


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
    """The state of one ``simulate`` run between its plan and its manifest: the engine
    and worker processes streaming into the run's :class:`~roslan.pipeline.record.
    Recorder` (the OUTDIR sink)."""

    def __init__(self, plan: RunPlan, options: RunOptions, wall0: float) -> None:
        self.plan = plan
        self.opts = options
        self.config = plan.config
        self.traj: Trajectory = plan.traj
        self.traj_config = plan.config.trajectory
        self.progress = Progress(options.quiet)
        self.rec = Recorder(plan, options, wall0, self.progress)
        self.pool: WorkerPool | None = None
        self.scene: Scene | None = None
        self.backends: SceneBackends | None = None  # the scene's renderer and caster
        self.files: DatasetFolder | None = None  # the partial folder's sink, once made

    @property
    def remote(self) -> set[int]:
        """Indices of the sensors that run in worker processes."""
        return self.pool.assigned if self.pool is not None else set()

    def execute(self) -> RunManifest:
        # the worker interpreters start (imports) while this process loads the scene
        if self.plan.groups:
            self.pool = self.rec.pool = WorkerPool(
                self.plan.groups, self.config.sensors, self.plan.render_helpers
            )
        try:
            self._load_scene()
            self.files = self.rec.open_folder()
        except BaseException:
            self.progress.stop()
            if self.pool is not None:
                self.pool.kill()
            self._release()
            raise
        try:
            with _sigterm_as_interrupt():
                self._start()
                self._merge()
                counts = self.rec.close()
                manifest = self.rec.write_run_files(counts, self.traj)
                self.rec.finalize()
        except BaseException:
            self.rec.abort()
            raise
        finally:
            self._release()
        return manifest

    def _release(self) -> None:
        """The run's scene back ends go with it."""
        if self.backends is not None:
            self.backends.release()

    # -------------------------------------------------------------------- 1. plan: scene
    def _load_scene(self) -> None:
        checked = load_checked_scene(
            self.plan, allow_collision=self.opts.allow_collision, phase=self.progress.phase
        )
        self.scene, self.traj_config, self.traj = checked.scene, checked.traj_config, checked.traj
        self.backends = checked.backends

    # ------------------------------------------------------------------- 2. folder: start
    def _start(self) -> None:
        config, rec = self.config, self.rec
        rec.ticks["setup"] = time.perf_counter()
        remote = self.remote
        if self.backends is not None and any(
            sensor_spec(sc.type).backend == "embree"
            for i, sc in enumerate(config.sensors)
            if i not in remote
        ):
            self.progress.phase("building the scene's BVH (ray casting)")
            self.backends.caster()
        self.progress.phase("preparing sensors (the first run compiles kernels, then cached)")
        if self.pool is not None:  # the workers render while this process sets up
            self._send_jobs(self.pool)
        rec.write_trajectory(self.traj)
        rec.export_scene(self.scene)  # written beside the streaming (after the plot's fork)
        rec.open_bags()

    def _send_jobs(self, pool: WorkerPool) -> None:
        config, plan = self.config, self.plan
        nices = dict(zip(pool.groups, worker_nice(pool.groups, config.sensors), strict=True))
        pool.send(
            lambda g: WorkerJob(
                trajectory=self.traj_config,
                outdir=self.rec.folder,
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

    # ------------------------------------------------------------------------- 3. merge
    def _merge(self) -> None:
        plan, profile, rec = self.plan, self.opts.profile, self.rec
        assert rec.writers is not None
        ctx = plan.context(self.traj, rec.folder, self.scene, backends=self.backends)
        rec.ticks["stream"] = time.perf_counter()
        # one step over the whole trajectory (the clock is fixed: nothing waits); merge
        # order: ground truth 0, sensor i -> i + 1 (ties resolve alike in workers)
        engine = rec.engine = SensorEngine(
            ctx, plan.sensors, plan.ground_truth, skip=self.remote, profile=profile
        )
        sources: list[Iterable[MergeItem]] = list(engine.sources())
        if self.pool is not None:
            sources += self.pool.streams(plan.formats)
        rec.warm_up_overview()  # matplotlib's first-draw costs, beside the streaming
        self.progress.start(self.traj.duration)
        rec.write_s, rec.build_s = pump(
            sources, rec.writers, ctx.start_time_ns, self.progress, profile, plan.owners
        )
        self.progress.update(self.traj.duration)
