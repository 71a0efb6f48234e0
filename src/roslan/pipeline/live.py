"""The incremental run driver: a closed-loop episode writes the same OUTDIR as ``simulate``.

:func:`open_run` plans a run like :func:`~roslan.pipeline.run.run_simulation` (the same
checks, the same folder, bags, manifest, overview, layouts and README code: a
:class:`LiveRun` is the simulate run's ``_Run`` driven step by step) on a trajectory that
grows (:class:`~roslan.trajectory.base.GrowingTrajectory`, e.g. the environment's vehicle
dynamics):

* :meth:`LiveRun.advance` runs every sensor up to the step's end on a growing
  :class:`~roslan.sensors.clock.Clock` (:class:`~roslan.pipeline.engine.SensorEngine`),
  writes the step's messages to the bags as they come and returns the step's
  :class:`~roslan.pipeline.engine.StepOutput` (messages and taps);
* :meth:`LiveRun.finish` fixes the end: the sensors' last messages, their dataset files,
  the trajectory files, any extra files (the environment's ``episode.json``), then the
  other run files (``README.md`` describes the extra files too) and ``run.json``, and the
  atomic rename into OUTDIR;
* :meth:`LiveRun.abort` removes everything (no half-written OUTDIR, ever).

Without an OUTDIR (``outdir=None``: an environment that does not record) the same engine
runs with no bag writers, its dataset files going to a temporary folder removed at the end.
Every sensor runs in this process (no worker processes, no render helpers: they look
ahead).
"""

from __future__ import annotations

import contextlib
import shutil
import tempfile
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from roslan.config.sim import SimConfig
from roslan.io.background import BackgroundSink
from roslan.io.bag import MultiBagWriter
from roslan.pipeline.context import Context
from roslan.pipeline.engine import SensorEngine, StepOutput
from roslan.pipeline.plan import RunPlan, make_plan
from roslan.pipeline.report import BackgroundPlot
from roslan.pipeline.run import RunOptions, _Run
from roslan.rundir.folder import clean_stale, finalize, make_temp, outdir_lock
from roslan.rundir.manifest import RunManifest
from roslan.sensors.clock import Clock
from roslan.trajectory.base import Trajectory

if TYPE_CHECKING:
    from roslan.scene.model import Scene

__all__ = ["LiveRun", "open_run"]


def open_run(
    config: SimConfig,
    outdir: Path | None,
    trajectory: Trajectory,
    options: RunOptions | None = None,
    *,
    scene: Scene | None = None,
    formats: Sequence[str] | None = None,
    config_path: Path | None = None,
    align: bool = True,
) -> LiveRun:
    """Start a run of ``config``'s sensors on the growing ``trajectory``.

    Args:
        config: validated simulation config (its ``trajectory`` only sets the limits
            checks; the run follows ``trajectory``).
        outdir: the OUTDIR to write (atomically, at :meth:`LiveRun.finish`), or None: no
            bags, no OUTDIR.
        trajectory: the vehicle's trajectory, readable up to each step's end
            (a :class:`~roslan.trajectory.base.GrowingTrajectory`); its ``duration`` etc.
            are read only after :meth:`LiveRun.finish` fixed the end.
        options: ``overwrite``, ``quiet``, ``overview`` (``allow_collision`` and
            ``profile`` are not used: the caller owns collisions).
        scene: the scene already loaded by the caller (else loaded from the config).
        formats: bag flavours (default ``config.output.formats``).
        config_path: the YAML file the config came from (relative paths, run.json).
        align: the event camera samples every step's end exactly (its events then
            cover each step up to its end).
    Raises:
        ConfigError, OutputError: as :func:`~roslan.pipeline.run.run_simulation`, before
            anything is written.
    """
    opts = options or RunOptions(quiet=True)
    wall0 = time.perf_counter()
    stack = contextlib.ExitStack()
    try:
        if outdir is not None:
            outdir = Path(outdir).absolute()
            stack.enter_context(outdir_lock(outdir))
            clean_stale(outdir)
            plan_dir = outdir
        else:
            plan_dir = Path(tempfile.gettempdir()) / "roslan-unrecorded"
        plan = make_plan(
            config,
            plan_dir,
            overwrite=opts.overwrite or outdir is None,
            formats=formats if outdir is not None else (),
            config_path=config_path,
            workers=0,
        )
        run = LiveRun(plan, opts, wall0, trajectory, scene, outdir, stack, align)
    except BaseException:
        stack.close()
        raise
    return run


class LiveRun(_Run):
    """A run driven step by step (see the module docstring); made by :func:`open_run`."""

    def __init__(
        self,
        plan: RunPlan,
        options: RunOptions,
        wall0: float,
        trajectory: Trajectory,
        scene: Scene | None,
        outdir: Path | None,
        stack: contextlib.ExitStack,
        align: bool,
    ) -> None:
        super().__init__(plan, options, wall0)
        self.traj = trajectory
        self.outdir = outdir
        self._stack = stack
        self.state = "open"
        try:
            self.scene = scene if scene is not None else self._own_scene()
            if outdir is not None:
                self.tmp = make_temp(outdir)
            else:
                self.tmp = Path(tempfile.mkdtemp(prefix="roslan-live-"))
            self._begin(align)
        except BaseException:
            self.abort()
            raise

    def _own_scene(self) -> Scene | None:
        if self.config.scene is None:
            return None
        import roslan.scene as scene_mod

        return scene_mod.load_scene(
            self.config.scene, base_dir=self.plan.base_dir, seed=self.config.seed
        )

    def _begin(self, align: bool) -> None:
        config, plan = self.config, self.plan
        self.ticks["setup"] = time.perf_counter()
        clock = Clock(0, align=align)
        self.ctx = Context(
            self.traj,
            self.tmp,
            seed=config.seed,
            start_time_ns=config.output.start_time,
            sensors=config.sensors,
            scene_spec=config.scene,
            base_dir=plan.base_dir,
            scene=self.scene,
            sensor_threads=1,
            clock=clock,
        )
        if self.outdir is not None:
            if self.scene is not None:
                import roslan.scene as scene_mod

                self.export = BackgroundSink("scene-export", backlog=1)
                self.export.submit(scene_mod.export_scene, self.scene, self.tmp / "scene")
            out = config.output
            self.writers = MultiBagWriter(
                self.tmp, plan.formats, plan.bag_topics, out.compression, out.ros2_compression
            )
        self.engine = SensorEngine(self.ctx, plan.sensors, plan.ground_truth)
        self.streams = self.engine.streams
        self.engine.enable_taps()
        self.ticks["stream"] = time.perf_counter()

    # ------------------------------------------------------------------ stepping
    def advance(self, horizon_ns: int) -> StepOutput:
        """Run every sensor up to ``horizon_ns`` (trajectory ns, inclusive), write the
        released messages to the bags; the step's messages and taps."""
        self._check_open()
        assert self.engine is not None
        try:
            out = self.engine.advance(horizon_ns)
            self._write(out)
        except BaseException:
            self.abort()
            raise
        return out

    def _write(self, out: StepOutput) -> None:
        writers = self.writers
        if writers is not None:
            start = self.ctx.start_time_ns
            for msg in out.messages:
                writers.write(msg.topic, start + msg.t_ns, msg.build)

    def finish(
        self, end_ns: int, extra_files: Mapping[str, bytes] | None = None
    ) -> tuple[StepOutput, RunManifest | None]:
        """End the run at ``end_ns`` (the trajectory must be finished, its ``duration``
        the end): the last messages and taps, then (with an OUTDIR) every run file plus
        ``extra_files`` (name relative to OUTDIR -> content), and the atomic move into
        OUTDIR. Returns the last step and the content of run.json (None: no OUTDIR)."""
        self._check_open()
        assert self.engine is not None
        try:
            out = self.engine.finish(end_ns, close=False)
            self._write(out)
            manifest = None
            if self.outdir is None:
                self.engine.close_sensors()
                shutil.rmtree(self.tmp, ignore_errors=True)
            else:
                manifest = self._write_outdir(extra_files or {})
            self.state = "finished"
        except BaseException:
            self.abort()
            raise
        self._stack.close()
        return out, manifest

    def _write_outdir(self, extra_files: Mapping[str, bytes]) -> RunManifest:
        from roslan.trajectory.export import write_trajectory_files

        assert self.outdir is not None
        rate = self.config.output.ground_truth_rate
        write_trajectory_files(self.traj, self.tmp, ground_truth_rate=rate)
        self.plot = BackgroundPlot(self.traj, self.tmp)
        counts = self._close()
        for name, data in extra_files.items():  # before README.md and run.json list them
            path = self.ctx.path(name)
            path.write_bytes(data)
        manifest = self._write_run_files(counts)
        finalize(self.tmp, self.outdir, self.opts.overwrite)
        self.progress.stop()
        return manifest

    def abort(self) -> None:
        """Stop everything and remove the partial folder (idempotent)."""
        if self.state == "aborted":
            return
        self.state = "aborted"
        try:
            if hasattr(self, "tmp"):
                self._abort()
        finally:
            self._stack.close()

    def _check_open(self) -> None:
        if self.state != "open":
            msg = f"this run is {self.state}"
            raise RuntimeError(msg)
