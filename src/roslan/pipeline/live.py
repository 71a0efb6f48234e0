"""The incremental run driver: a closed-loop episode writes the same OUTDIR as ``simulate``.

:func:`open_run` plans a run like :func:`~roslan.pipeline.run.run_simulation` (the same
checks, and for a recorded run the same :class:`~roslan.pipeline.record.Recorder`: folder,
bags, manifest, overview, layouts and README code) on a trajectory that grows
(:class:`~roslan.trajectory.base.GrowingTrajectory`, e.g. the environment's vehicle
dynamics):

* :meth:`LiveRun.advance` runs every sensor up to the step's end on a growing
  :class:`~roslan.sensors.clock.Clock` (:class:`~roslan.pipeline.engine.SensorEngine`),
  writes the step's messages to the bags as they come (recorded runs) and returns the
  step's :class:`~roslan.pipeline.engine.StepOutput` (messages and taps);
* :meth:`LiveRun.finish` fixes the end: the sensors' last messages and, with an OUTDIR,
  their dataset files, the trajectory files, then ``run.json`` and the other run files,
  any extra files (the environment's ``episode.json``), and the atomic rename into OUTDIR;
* :meth:`LiveRun.abort` removes everything (no half-written OUTDIR, ever).

Without an OUTDIR (``outdir=None``: an environment that does not record) no recorder is
attached: no bags, no folder, no free-space check, and the sensors get no file sink
(``ctx.files is None``), so they write no file at all (not even a temporary one). Every
sensor runs in this process (no worker processes, no render helpers: they look ahead).
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from roslan.config.sim import SimConfig
from roslan.pipeline.engine import SensorEngine, StepOutput
from roslan.pipeline.plan import RunPlan, make_plan
from roslan.pipeline.record import Recorder, RunOptions
from roslan.pipeline.report import Progress
from roslan.render.backends import SceneBackends
from roslan.rundir.folder import clean_stale, outdir_lock
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
    backends: SceneBackends | None = None,
    formats: Sequence[str] | None = None,
    config_path: Path | None = None,
    align: bool = True,
) -> LiveRun:
    """Start a run of ``config``'s sensors on the growing ``trajectory``.

    Args:
        config: validated simulation config (its ``trajectory`` only sets the limits
            checks; the run follows ``trajectory``).
        outdir: the OUTDIR to write (atomically, at :meth:`LiveRun.finish`), or None: no
            bags, no files, no OUTDIR.
        trajectory: the vehicle's trajectory, readable up to each step's end
            (a :class:`~roslan.trajectory.base.GrowingTrajectory`); its ``duration`` etc.
            are read only after :meth:`LiveRun.finish` fixed the end.
        options: ``overwrite``, ``quiet``, ``overview`` (``allow_collision`` and
            ``profile`` are not used: the caller owns collisions).
        scene: the scene already loaded by the caller (else loaded from the config).
        backends: the renderer and caster of ``scene``, owned by the caller (the
            environment's, shared with its contact checks); default: the run's own,
            released when it ends.
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
        plan = make_plan(
            config,
            outdir,
            overwrite=opts.overwrite,
            formats=formats,
            config_path=config_path,
            workers=0,
        )
        run = LiveRun(plan, opts, wall0, trajectory, scene, backends, stack, align)
    except BaseException:
        stack.close()
        raise
    return run


class LiveRun:
    """A run driven step by step (see the module docstring); made by :func:`open_run`.

    Attributes:
        rec: the OUTDIR sink of a recorded run, None for an unrecorded one.
    """

    def __init__(
        self,
        plan: RunPlan,
        options: RunOptions,
        wall0: float,
        trajectory: Trajectory,
        scene: Scene | None,
        backends: SceneBackends | None,
        stack: contextlib.ExitStack,
        align: bool,
    ) -> None:
        self.plan = plan
        self.config = plan.config
        self.traj = trajectory
        self._stack = stack
        self.state = "open"
        self.engine: SensorEngine | None = None
        self.rec: Recorder | None = None
        if plan.outdir is not None:
            self.rec = Recorder(plan, options, wall0, Progress(options.quiet))
        self.backends = backends
        self._own_backends = backends is None
        try:
            self.scene = scene if scene is not None else self._own_scene()
            if self.backends is None and self.scene is not None:
                self.backends = SceneBackends(self.scene)
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
        rec = self.rec
        folder = None
        if rec is not None:
            folder = rec.open_folder().root
            rec.ticks["setup"] = time.perf_counter()
        self.ctx = self.plan.context(
            self.traj, folder, self.scene, clock=Clock(0, align=align), backends=self.backends
        )
        if rec is not None:
            rec.export_scene(self.scene)
            rec.open_bags()
        self.engine = SensorEngine(self.ctx, self.plan.sensors, self.plan.ground_truth)
        self.engine.enable_taps()
        if rec is not None:
            rec.engine = self.engine
            rec.ticks["stream"] = time.perf_counter()

    # ------------------------------------------------------------------ stepping
    def advance(self, horizon_ns: int) -> StepOutput:
        """Run every sensor up to ``horizon_ns`` (trajectory ns, inclusive), write the
        released messages to the bags (recorded runs); the step's messages and taps."""
        self._check_open()
        assert self.engine is not None
        try:
            out = self.engine.advance(horizon_ns)
            if self.rec is not None:
                self.rec.write(out.messages, self.ctx.start_time_ns)
        except BaseException:
            self.abort()
            raise
        return out

    def finish(
        self, end_ns: int, extra_files: Mapping[str, bytes] | None = None
    ) -> tuple[StepOutput, RunManifest | None]:
        """End the run at ``end_ns`` (the trajectory must be finished, its ``duration``
        the end): the last messages and taps, then (with an OUTDIR) every run file plus
        ``extra_files`` (name relative to OUTDIR -> content), and the atomic move into
        OUTDIR. Returns the last step and the content of run.json (None: no OUTDIR)."""
        self._check_open()
        assert self.engine is not None
        rec = self.rec
        try:
            out = self.engine.finish(end_ns, close=False)
            manifest = None
            if rec is None:
                self.engine.close_sensors()
            else:
                rec.write(out.messages, self.ctx.start_time_ns)
                rec.write_trajectory(self.traj)
                counts = rec.close()
                rec.write_extra(dict(extra_files or {}))  # before README.md and run.json list them
                manifest = rec.write_run_files(counts, self.traj)
                rec.finalize()
            self.state = "finished"
        except BaseException:
            self.abort()
            raise
        self._stack.close()
        self._release()
        return out, manifest

    def _release(self) -> None:
        """Back ends this run made go with it (the caller's stay the caller's)."""
        if self._own_backends and self.backends is not None:
            self.backends.release()

    def abort(self) -> None:
        """Stop everything and remove the partial folder (idempotent)."""
        if self.state == "aborted":
            return
        self.state = "aborted"
        try:
            if self.rec is not None:
                self.rec.abort()  # (its engine's sensors first, then the folder)
            elif self.engine is not None:
                self.engine.abort()
        finally:
            self._stack.close()
            self._release()

    def _check_open(self) -> None:
        if self.state != "open":
            msg = f"this run is {self.state}"
            raise RuntimeError(msg)
