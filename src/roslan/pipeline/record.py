"""The OUTDIR sink of a run: what a recorded run attaches and an unrecorded one does not.

A :class:`Recorder` is the file side of one run, the same for ``simulate``
(:mod:`roslan.pipeline.run`) and a recorded closed-loop episode
(:mod:`roslan.pipeline.live`): the hidden ``.OUTDIR.partial-*`` folder that the sensors'
dataset files go to (:attr:`files`, handed to the sensors through their context), the
ROS 1 / ROS 2 bag writers, the scene export and ``trajectory.png`` beside the streaming,
then the run-level files (calibration, extrinsics, timing, overview, PLAYBACK.md,
README.md, ``run.json`` last) and the atomic rename into OUTDIR; or, on any failure,
nothing left behind (:meth:`abort`). A run without an OUTDIR attaches no recorder: its
sensors get no file sink (``ctx.files is None``) and write nothing at all.
"""

from __future__ import annotations

import contextlib
import shutil
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from roslan.io.background import BackgroundSink
from roslan.io.bag import BAG_NAMES, MultiBagWriter
from roslan.io.files import DatasetFolder
from roslan.io.messages import Flavor
from roslan.pipeline.report import BackgroundPlot, Progress, playback_text, print_profile
from roslan.pipeline.worker import WorkerPool, sensor_stats
from roslan.rundir.calibration import root_camera, write_calibration
from roslan.rundir.extrinsics import write_extrinsics
from roslan.rundir.folder import finalize, make_temp, run_files
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

if TYPE_CHECKING:
    from roslan.pipeline.engine import SensorEngine
    from roslan.pipeline.plan import RunPlan
    from roslan.scene.model import Scene
    from roslan.sensors.base import Message
    from roslan.trajectory.base import Trajectory

__all__ = ["Recorder", "RunOptions"]


@dataclass(frozen=True)
class RunOptions:
    """How to run (none of it changes an output byte, except ``overview``)."""

    overwrite: bool = False
    quiet: bool = False
    allow_collision: bool = False
    profile: bool = False
    overview: bool = True


def _warm_up_plots() -> None:
    """:func:`roslan.plots.overview.warm_up`, on a thread: a failure here is only a lost
    head start (``write_overview`` reports any real problem)."""
    with contextlib.suppress(Exception):
        from roslan.plots.overview import warm_up

        warm_up()


class Recorder:
    """The OUTDIR sink of one run (module docstring).

    Args:
        plan: the run's plan (its ``outdir`` is the folder written).
        options: the run's options (``overwrite``, ``quiet``, ``profile``, ``overview``).
        wall0: ``time.perf_counter()`` at the run's start (timing.json).
        progress: the run's progress display.
    """

    def __init__(
        self, plan: RunPlan, options: RunOptions, wall0: float, progress: Progress
    ) -> None:
        assert plan.outdir is not None
        self.plan = plan
        self.outdir: Path = plan.outdir
        self.opts = options
        self.config = plan.config
        self.wall0 = wall0
        self.progress = progress
        self.tmp: Path | None = None  # the hidden partial folder, made by open_folder
        self.writers: MultiBagWriter | None = None
        self.plot: BackgroundPlot | None = None
        self.export: BackgroundSink | None = None  # the scene export's thread
        self.warm: threading.Thread | None = None  # overview.png's warm-up thread
        self.engine: SensorEngine | None = None  # the engine whose sensors write here
        self.pool: WorkerPool | None = None  # the worker processes writing here
        self.ticks: dict[str, float] = {}
        self.write_s = 0.0
        self.bag_cpu_s = 0.0
        self.compress_cpu_s = 0.0
        self.build_s: dict[str, float] = {}
        self.close_s: dict[str, float] = {}

    # ------------------------------------------------------------------ the folder
    def open_folder(self) -> DatasetFolder:
        """Make the hidden partial folder; the sink the sensors' dataset files go to."""
        self.tmp = make_temp(self.outdir)
        return DatasetFolder(self.tmp)

    @property
    def folder(self) -> Path:
        assert self.tmp is not None
        return self.tmp

    def write_trajectory(self, traj: Trajectory) -> None:
        """The trajectory files and ``trajectory.png`` (drawn beside the streaming)."""
        from roslan.trajectory.export import write_trajectory_files

        rate = self.config.output.ground_truth_rate
        write_trajectory_files(traj, self.folder, ground_truth_rate=rate)
        self.plot = BackgroundPlot(traj, self.folder)

    def export_scene(self, scene: Scene | None) -> None:
        """The scene's export, on a thread of its own (after the plot's fork)."""
        if scene is None:
            return
        import roslan.scene as scene_mod

        if self.config.output.labels:
            from roslan.pipeline.labels import write_label_tables

            write_label_tables(self.folder, scene)

        self.export = BackgroundSink("scene-export", backlog=1)
        self.export.submit(scene_mod.export_scene, scene, self.folder / "scene")

    def open_bags(self) -> MultiBagWriter:
        """The bag writers of the plan's formats and topics."""
        out, plan = self.config.output, self.plan
        self.writers = MultiBagWriter(
            self.folder, plan.formats, plan.bag_topics, out.compression, out.ros2_compression
        )
        return self.writers

    def write(self, messages: Sequence[Message], start_time_ns: int) -> None:
        """Write released messages to the bags (closed loop: one step's)."""
        writers = self.writers
        assert writers is not None
        for msg in messages:
            writers.write(msg.topic, start_time_ns + msg.t_ns, msg.build)

    def warm_up_overview(self) -> None:
        """Pay matplotlib's first-draw costs beside the streaming (with ``overview``)."""
        if self.opts.overview:
            # a daemon: an interrupted run (Ctrl-C, SIGTERM) exits without waiting for
            # matplotlib's imports, which take seconds on a loaded machine; a finished run
            # joins it in close()
            self.warm = threading.Thread(
                target=_warm_up_plots, name="overview-warm-up", daemon=True
            )
            self.warm.start()

    # ------------------------------------------------------------------ the end
    def close(self) -> dict[str, int]:
        """Close workers, the plot, the sensors and the bags; the messages per topic."""
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

    def write_run_files(self, counts: dict[str, int], traj: Trajectory) -> RunManifest:
        """Every run-level file, ``run.json`` last (its presence marks a whole folder)."""
        plan, tmp = self.plan, self.folder
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
            duration_s=traj.duration,
            touchdown_s=traj.T,
            bags={f: BAG_NAMES[Flavor(f)] for f in plan.formats},
            topics=topics,
            sensors=[s.config.name for s in plan.sensors],
            renderer=_image_formation(self.config.sensors),
        )
        wall = time.perf_counter() - self.wall0
        timing = self._timing(wall, traj.duration)
        if self.opts.overview:
            from roslan.plots.overview import overview_title, write_overview

            self.progress.phase("drawing overview.png")
            t0 = time.perf_counter()
            write_overview(tmp, title=overview_title(self.config.scene, self.config.seed))
            timing["overview_s"] = time.perf_counter() - t0
        write_json(tmp / TIMING_FILE, timing)
        (tmp / "PLAYBACK.md").write_text(
            playback_text(
                traj.duration,
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

    def write_extra(self, extra_files: dict[str, bytes]) -> None:
        """Files of the caller (the environment's ``episode.json``): name -> content."""
        folder = DatasetFolder(self.folder)
        for name, data in extra_files.items():
            folder.path(name).write_bytes(data)

    def finalize(self) -> None:
        """The atomic rename into OUTDIR (replacing an old one only now)."""
        finalize(self.folder, self.outdir, self.opts.overwrite)
        self.progress.stop()

    def _timing(self, wall: float, duration: float) -> Timing:
        plan, ticks = self.plan, self.ticks
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
        streams = self.engine.streams if self.engine is not None else []
        local = {
            st.name: {
                "generator_s": st.seconds,
                "build_s": self.build_s.get(st.name, 0.0),
                "close_s": self.close_s.get(st.name, 0.0),
                "messages": st.count,
                **sensor_stats(by_name.get(st.name)),
            }
            for st in streams
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

    def abort(self) -> None:
        """Stop everything writing into the folder, then remove it (idempotent)."""
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
        if self.tmp is not None:
            shutil.rmtree(self.tmp, ignore_errors=True)


def _image_formation(sensors: Any) -> dict[str, Any] | None:
    """run.json's record of the renderer, for a run with a camera-type sensor (they all
    have the ``supersampling`` key); None otherwise (no OpenGL context is made)."""
    if not any(hasattr(s, "supersampling") for s in sensors):
        return None
    from roslan.render.gl import image_formation
    from roslan.sensors.cameras.row_exposure import RENDER_SAMPLES

    record = image_formation()
    record["exposed_rows"] = (
        "frame and stereo cameras with an exposure or readout time: each row integrates its "
        "own exposure window, warped along the exact per-pixel motion from renders at "
        f"{RENDER_SAMPLES} MSAA samples (msaa_samples above is the renderer's default)"
    )
    return record
