"""Planning a run: every check that can fail, done before anything is written.

:func:`make_plan` validates a config for one OUTDIR and returns a :class:`RunPlan`: the
trajectory, the bag formats, every sensor constructed from its config, the ground truth
with the /tf_static tree, who publishes each topic, and which sensors run in worker
processes. It refuses (with an error that names the key or sensor) an existing OUTDIR
without ``overwrite``, resource limits, a sensor that needs a scene without one, a full
disk, clashing names, frames or topics. :func:`load_checked_scene` then loads the scene
and refuses a path on which the vehicle or a sensor enters its geometry.

:func:`check_run` is both steps without writing anything: the verdict of every
``--dry-run`` (``simulate``, ``batch``, ``dataset``), the same checks, in the same order
and with the same messages, as :func:`~roslan.pipeline.run.run_simulation`.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from roslan.config.sim import SimConfig
from roslan.errors import ConfigError, SensorError
from roslan.io.bag import BagTopic
from roslan.limits import preflight as check_limits
from roslan.pipeline.context import Context
from roslan.pipeline.estimate import check_free_space, estimate_run
from roslan.pipeline.namespace import check_namespace
from roslan.pipeline.threads import sensor_threads
from roslan.pipeline.worker import plan_helpers, plan_workers, resolve_workers
from roslan.render.backends import SceneBackends
from roslan.rundir.extrinsics import static_transforms
from roslan.rundir.folder import check_outdir
from roslan.sensors.base import Sensor
from roslan.sensors.clock import Clock
from roslan.sensors.ground_truth import GroundTruth
from roslan.sensors.registry import sensor_class
from roslan.trajectory.base import Trajectory
from roslan.trajectory.config import TrajectoryConfig
from roslan.trajectory.spline import make_trajectory
from roslan.vehicle import base_link_trajectory

if TYPE_CHECKING:
    from roslan.scene.model import Scene

__all__ = [
    "BAG_FORMATS",
    "CheckedScene",
    "RunPlan",
    "check_labelled_scene",
    "check_run",
    "load_checked_scene",
    "make_plan",
    "preflight",
    "with_scene_goal",
]

BAG_FORMATS = ("ros1", "ros2")


@dataclass
class RunPlan:
    """Everything a run needs, validated."""

    config: SimConfig
    outdir: Path | None
    """The OUTDIR written, or None: a run that records nothing (a closed-loop episode
    without ``record``)."""
    config_path: Path | None
    base_dir: Path | None
    """Folder that relative paths of the config (scene, trajectory file) are resolved in."""
    source: str
    """How errors name the config: its path, or ``<config>``."""
    formats: tuple[str, ...]
    traj: Trajectory
    sensors: list[Sensor]
    ground_truth: GroundTruth
    owners: dict[str, str]
    """Topic -> the component publishing it (``ground_truth`` or a sensor name)."""
    bag_topics: list[BagTopic]
    """Every bag connection, in a fixed order: ground truth, then sensors in config order."""
    groups: list[list[int]]
    """Sensor indices per worker process (empty: every sensor runs in this process)."""
    render_helpers: dict[str, int] = field(default_factory=dict)
    """Render helper processes per event camera name
    (:func:`~roslan.pipeline.worker.plan_helpers`)."""
    sensor_threads: int = 1
    """Threads of each frame/scan sensor for its per-instant work
    (:func:`~roslan.pipeline.threads.sensor_threads`)."""

    def context(
        self,
        trajectory: Trajectory,
        files: Path | None,
        scene: Scene | None,
        *,
        clock: Clock | None = None,
        backends: SceneBackends | None = None,
    ) -> Context:
        """The sensors' context of this run (``simulate``'s and a closed-loop episode's
        alike): dataset files into the folder ``files`` (None: a run that records no
        files). A stepped run (``clock``, closed loop) runs each sensor on one thread and
        starts no render helpers (they look ahead). ``backends``: the scene's renderer and
        caster, owned by the caller (default: the context makes its own on first use)."""
        config = self.config
        stepped = clock is not None
        return Context(
            trajectory,
            files,
            seed=config.seed,
            start_time_ns=config.output.start_time,
            sensors=config.sensors,
            scene_spec=config.scene,
            base_dir=self.base_dir,
            scene=scene,
            sensor_threads=1 if stepped else self.sensor_threads,
            render_helpers=None if stepped else self.render_helpers,
            clock=clock,
            backends=backends,
        )


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
    if config.output.labels and config.scene is None:
        msg = (
            "output.labels = true: labels need a scene with classes but the config has "
            "none; add e.g. 'scene: warehouse' or set output.labels: false"
        )
        raise ConfigError(msg)


def check_labelled_scene(config: SimConfig, scene: Scene) -> None:
    """Refuse ``output.labels: true`` on a scene none of whose objects has a class."""
    if config.output.labels and not any(o.labels is not None for o in scene.objects):
        msg = (
            f"output.labels = true: scene {config.scene!r} has no classes (no object gives "
            "'class' or 'parts'); give its objects a 'class' (docs/guide/scenes.md, "
            '"Classes and instances") or set output.labels: false'
        )
        raise ConfigError(msg)


def _formats(config: SimConfig, formats: Sequence[str] | None) -> tuple[str, ...]:
    fmts = tuple(formats) if formats is not None else tuple(config.output.formats)
    for f in fmts:
        if f not in BAG_FORMATS:
            msg = f"bag format {f!r}: allowed 'ros1', 'ros2'"
            raise ConfigError(msg)
    return tuple(dict.fromkeys(fmts))


def _sensors(config: SimConfig) -> list[Sensor]:
    sensors: list[Sensor] = []
    for i, sc in enumerate(config.sensors):
        try:
            sensors.append(sensor_class(sc.type)(sc))
        except ValueError as err:
            msg = f"sensors[{i}] ({sc.name}): {err}"
            raise SensorError(msg) from err
    return sensors


def _topics(gt: GroundTruth, sensors: Sequence[Sensor]) -> tuple[dict[str, str], list[BagTopic]]:
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
    return owners, bag_topics


def with_scene_goal(config: SimConfig, base_dir: Path | None) -> SimConfig:
    """``config`` landing on its scene's marker or perch when it gives no goal
    (:func:`roslan.scene.goal.goal_from_scene`: a note, or a warning for a scene without
    one); unchanged (the same object) otherwise. run.json then records the goal flown."""
    if config.scene is None:
        return config
    from roslan.scene.goal import goal_from_scene

    trajectory = goal_from_scene(config.trajectory, config.scene, base_dir=base_dir)
    if trajectory is config.trajectory:
        return config
    return config.model_copy(update={"trajectory": trajectory})


def make_plan(
    config: SimConfig,
    outdir: Path | None,
    *,
    overwrite: bool = False,
    formats: Sequence[str] | None = None,
    config_path: Path | None = None,
    workers: int | str | None = None,
) -> RunPlan:
    """Validate ``config`` for a run into ``outdir`` (see the module docstring); without
    an OUTDIR (None: nothing recorded) there are no bags and no folder or disk checks."""
    fmts = _formats(config, formats)
    base_dir = config_path.parent.resolve() if config_path is not None else None
    if outdir is None:
        fmts = ()
    else:
        check_outdir(outdir, overwrite)
    config = with_scene_goal(config, base_dir)
    traj = make_trajectory(config.trajectory, base_dir=base_dir)
    source = str(config_path) if config_path is not None else "<config>"
    check_limits(config, traj.duration, fmts, source)
    preflight(config, traj)
    if outdir is not None:
        est = estimate_run(config, fmts, duration=traj.duration)
        check_free_space(outdir, est.bytes, "this run")
    sensors = _sensors(config)
    check_namespace(sensors, source)
    gt = GroundTruth(
        config.output.ground_truth_rate,
        static_transforms(sensors),
        scene=config.scene is not None,
        objects=config.output.labels and config.scene is not None,
    )
    owners, bag_topics = _topics(gt, sensors)
    n_workers = resolve_workers(
        config.output.workers if workers is None else workers, config.sensors
    )
    # (children need an interpreter to start and a POSIX fd to talk through)
    posix = bool(sys.executable) and os.name == "posix"
    groups = plan_workers(config.sensors, n_workers) if posix else []
    helpers = plan_helpers(config.sensors, n_workers) if posix else {}
    # the sensor workers and this process (not the render helpers: `auto` leaves them the
    # other half of the CPUs, and on a GPU machine they mostly wait for their renders)
    threads = sensor_threads(len(groups) + 1)
    return RunPlan(
        config=config,
        outdir=outdir,
        config_path=config_path,
        base_dir=base_dir,
        source=source,
        formats=fmts,
        traj=traj,
        sensors=sensors,
        ground_truth=gt,
        owners=owners,
        bag_topics=bag_topics,
        groups=groups,
        sensor_threads=threads,
        render_helpers=helpers,
    )


@dataclass
class CheckedScene:
    """The scene of a run and base_link's trajectory in it (the goal moved so that the
    vehicle's contact point, not base_link, meets the surface)."""

    scene: Scene | None
    traj_config: TrajectoryConfig
    traj: Trajectory
    backends: SceneBackends | None = None
    """The scene's renderer and caster, owned by the run (the clearance check's caster)."""


def load_checked_scene(
    plan: RunPlan, *, allow_collision: bool = False, phase: Callable[[str], None] | None = None
) -> CheckedScene:
    """Load the plan's scene and check the path's clearance (unless ``allow_collision``).

    Raises:
        SceneError: the scene cannot be loaded.
        ConfigError: the vehicle or a sensor enters the scene's geometry on the way.
    """
    config = plan.config
    say = phase or (lambda text: None)
    scene: Scene | None = None
    if config.scene is not None:
        import roslan.scene as scene_mod

        say(f"loading scene {config.scene!r}")
        scene = scene_mod.load_scene(config.scene, base_dir=plan.base_dir, seed=config.seed)
        check_labelled_scene(config, scene)
    # the goal is where the vehicle's contact point meets the surface: base_link's
    # trajectory ends above it (roslan.vehicle); only the goal moves, not the timing
    traj_config = base_link_trajectory(config.trajectory, config.vehicle, scene)
    traj = plan.traj
    if traj_config is not config.trajectory:
        traj = make_trajectory(traj_config, base_dir=plan.base_dir, warn=False)
    backends = SceneBackends(scene) if scene is not None else None
    checked = CheckedScene(scene, traj_config, traj, backends)
    if scene is None or backends is None or allow_collision:
        return checked
    from roslan.scene.clearance import check_clearance

    say("checking the path's clearance")
    hit = check_clearance(
        scene, traj, caster=backends.caster(), vehicle=config.vehicle, sensors=config.sensors
    )
    if hit is not None:
        msg = (
            f"scene {config.scene!r}: {hit}; change the trajectory, the sensor "
            "mounts or the vehicle block, or pass --allow-collision"
        )
        raise ConfigError(msg)
    return checked


def check_run(
    config: SimConfig,
    outdir: Path,
    *,
    overwrite: bool = False,
    formats: Sequence[str] | None = None,
    config_path: Path | None = None,
    allow_collision: bool = False,
    workers: int | str | None = None,
) -> RunPlan:
    """Every check :func:`~roslan.pipeline.run.run_simulation` makes before it writes,
    writing nothing (``--dry-run``): :func:`make_plan`, then :func:`load_checked_scene`.
    Raises what the run would raise, with the same message."""
    plan = make_plan(
        config,
        Path(outdir).absolute(),
        overwrite=overwrite,
        formats=formats,
        config_path=config_path,
        workers=workers,
    )
    load_checked_scene(plan, allow_collision=allow_collision)
    return plan
