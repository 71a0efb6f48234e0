"""The paper's dataset (ROS-LAN, Section 5) in one call: six landings per scene.

Per scene, six tau-theory landings with ``k = 0.5`` (constant deceleration on the
height gap), final approach angle ``pi/6`` (the start seen from the goal at 30 deg
elevation), initial speed in 3-5 m/s and six (kappa_x, kappa_y) pairs, the trajectory
table sampled every 0.1 s, landing on the scene's marker (``Scene.goal_position`` /
``goal_rpy``). The paper does not list its kappas; ours (:data:`PAPER_TRAJECTORIES`)
keep ``k * kappa <= 0.45 < 0.5`` (zero final rate, bounded deceleration on every
coupled gap) and span early lateral closure (kappa 0.4: the robot is over the goal
early and drops nearly vertically) to late closure (kappa 0.9: an almost straight
glide), with unequal pairs that curve the path sideways, like the paper's Fig. 3:

====  =======  =======  =========  ===========
 #    kappa_x  kappa_y  speed m/s  heading deg
====  =======  =======  =========  ===========
 1    0.40     0.40     3.0        -27
 2    0.90     0.90     3.4         27
 3    0.40     0.90     3.8         45
 4    0.90     0.40     4.2        -45
 5    0.65     0.50     4.6          9
 6    0.50     0.65     5.0         -9
====  =======  =======  =========  ===========

The start lies :data:`APPROACH_DISTANCE` m from the goal; ``heading`` (in the goal
frame, from +x towards +y) is the horizontal direction of flight, and the robot starts
yawed along it (the yaw gap closes to the goal's yaw). If a scene object blocks a
path (``roslan.scene.check_clearance``), its heading is turned in 15 deg steps
(+15, -15, +30, ...) until it is clear; ``index.csv`` records the heading used.
Simulation ``i`` of scene ``j`` uses seed ``SeedSequence([seed, j, i])``.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from roslan.batch.report import BatchReport
from roslan.batch.runner import Runner, run_tasks
from roslan.batch.tasks import make_tasks
from roslan.errors import ConfigError
from roslan.io.files import atomic_write_text
from roslan.plots.dataset import plot_trajectories
from roslan.rundir.events import count_events
from roslan.rundir.manifest import read_manifest, run_duration, run_messages

__all__ = [
    "APPROACH_ANGLE",
    "APPROACH_DISTANCE",
    "PAPER_K",
    "PAPER_SCENES",
    "PAPER_TRAJECTORIES",
    "DatasetRun",
    "build_dataset",
    "dataset_plan",
    "default_sensor_suite",
    "iter_dataset_plan",
    "write_index",
]

PAPER_K = 0.5
"""tau-dot of the height gap: k = 0.5 closes it with constant deceleration."""
APPROACH_ANGLE = math.pi / 6
"""Final approach (elevation) angle, rad."""
APPROACH_DISTANCE = 8.0
"""Straight-line start distance from the goal, m (start 4 m above it, 6.9 m away)."""
SAMPLE_DT = 0.1
"""Trajectory table step, s (the paper's Delta t)."""
PAPER_SCENES = ("warehouse", "refinery")

PAPER_TRAJECTORIES: tuple[tuple[float, float, float, float], ...] = (
    # (kappa_x, kappa_y, speed m/s, heading deg)
    (0.40, 0.40, 3.0, -27.0),
    (0.90, 0.90, 3.4, 27.0),
    (0.40, 0.90, 3.8, 45.0),
    (0.90, 0.40, 4.2, -45.0),
    (0.65, 0.50, 4.6, 9.0),
    (0.50, 0.65, 5.0, -9.0),
)
"""The six landings of every scene (see the module docstring)."""

_HEADING_STEPS_DEG = (15, -15, 30, -30, 45, -45, 60, -60, 75, -75, 90, -90)


def default_sensor_suite() -> list[dict[str, Any]]:
    """The paper's sensors: frame camera (640x480 grayscale, 30 Hz; as in the default
    job), event camera (DAVIS346,
    realistic pixel, APS frames at 25 Hz), sonar (straight down), IMU (1 kHz) and a
    Velodyne HDL-32E (10 Hz); ground truth is always written by the pipeline. The
    cameras look forward, pitched 20 deg down towards the landing spot."""
    down20 = [0.0, math.radians(20.0), 0.0]
    return [
        {
            "type": "camera",
            "name": "camera",
            "rate": 30.0,
            "topic": "/camera",
            "encoding": "mono8",
            "pose": {"position": [0.12, 0.0, 0.0], "rpy": down20},
        },
        {
            "type": "event_camera",
            "name": "dvs",
            "rate": 25.0,
            "topic": "/dvs",
            "sensor": "davis346",
            "pose": {"position": [0.12, 0.03, 0.0], "rpy": down20},
        },
        {
            "type": "sonar",
            "name": "sonar",
            "rate": 20.0,
            "topic": "/sonar",
            "axis": [0.0, 0.0, -1.0],
            "pose": {"position": [0.0, 0.0, -0.05], "rpy": [0.0, 0.0, 0.0]},
        },
        {"type": "imu", "name": "imu", "rate": 1000.0, "topic": "/imu"},
        {
            "type": "lidar",
            "name": "velodyne",
            "rate": 10.0,
            "topic": "/velodyne_points",
            "preset": "hdl32e",
            "pose": {"position": [0.0, 0.0, 0.1], "rpy": [0.0, 0.0, 0.0]},
        },
    ]


@dataclass
class DatasetRun:
    """One simulation of the dataset plan."""

    folder: str
    scene: str
    number: int
    kappa_x: float
    kappa_y: float
    speed: float
    heading: float
    """rad, in the goal frame."""
    distance: float
    seed: int
    config: dict[str, Any] = field(repr=False)

    @property
    def k(self) -> float:
        return float(self.config["trajectory"]["k"])


def _trajectory_block(
    kx: float, ky: float, speed: float, heading: float, distance: float, goal: Mapping[str, Any]
) -> dict[str, Any]:
    return {
        "k": PAPER_K,
        "kappa": {"x": kx, "y": ky},
        "approach": {
            "distance": distance,
            "angle": APPROACH_ANGLE,
            "heading": heading,
            "speed": speed,
        },
        "initial": {"rpy": [0.0, 0.0, heading]},
        "goal": dict(goal),
        "sample_dt": SAMPLE_DT,
    }


def _touchdown(block: Mapping[str, Any]) -> float:
    from roslan.trajectory.config import TrajectoryConfig
    from roslan.trajectory.generator import TauTrajectory

    return float(TauTrajectory(TrajectoryConfig.model_validate(block), warn=False).T)


def _load(name: str, seed: int) -> Any:
    try:
        from roslan.scene import load_scene
    except ImportError:  # scenes not installed in this build
        return None
    return load_scene(name, seed=seed)


def _scene_goal(name: str) -> dict[str, Any]:
    """The scene's landing marker as a ``goal`` block (the origin if scenes are unavailable)."""
    scene = _load(name, 0)
    if scene is None:
        return {"position": [0.0, 0.0, 0.0], "rpy": [0.0, 0.0, 0.0]}
    goal = {
        "position": [float(v) for v in scene.goal_position],
        "rpy": [float(v) for v in scene.goal_rpy],
    }
    return goal


def _clear(scene: Any, block: Mapping[str, Any], sensors: Sequence[Mapping[str, Any]]) -> bool:
    """Whether the landing keeps the default vehicle's body and every sensor (origin,
    camera near planes) out of the scene, as ``roslan simulate`` checks it."""
    if scene is None:
        return True
    try:
        from roslan.scene import check_clearance
    except ImportError:
        return True
    from roslan.config.sim import SimConfig
    from roslan.trajectory.generator import TauTrajectory
    from roslan.vehicle import base_link_trajectory

    cfg = SimConfig.model_validate({"trajectory": dict(block), "sensors": list(sensors)})
    traj = TauTrajectory(base_link_trajectory(cfg.trajectory, cfg.vehicle, scene), warn=False)
    from roslan.render.raycast import get_raycaster

    caster = get_raycaster(scene)  # the beam sensors' caster
    return (
        check_clearance(scene, traj, caster=caster, vehicle=cfg.vehicle, sensors=cfg.sensors)
        is None
    )


def dataset_plan(
    scenes: Sequence[str] = PAPER_SCENES,
    *,
    seed: int = 0,
    sensors: Sequence[Mapping[str, Any]] | None = None,
    duration: float | None = None,
    formats: Sequence[str] | None = None,
    check_clearance: bool = True,
    labels: bool = True,
) -> list[DatasetRun]:
    """The dataset's simulations, in order (scene by scene, trajectories 1..6); the
    arguments are :func:`iter_dataset_plan`'s."""
    return list(
        iter_dataset_plan(
            scenes, seed=seed, sensors=sensors, duration=duration, formats=formats,
            check_clearance=check_clearance, labels=labels,
        )
    )  # fmt: skip


def iter_dataset_plan(
    scenes: Sequence[str] = PAPER_SCENES,
    *,
    seed: int = 0,
    sensors: Sequence[Mapping[str, Any]] | None = None,
    duration: float | None = None,
    formats: Sequence[str] | None = None,
    check_clearance: bool = True,
    labels: bool = True,
) -> Iterator[DatasetRun]:
    """The dataset's simulations one at a time, in order (scene by scene, trajectories
    1..6): a caller that checks each one as it comes finds its scene still loaded.

    Args:
        scenes: built-in scene names or scene YAML paths.
        seed: dataset seed; each simulation's seed derives from it (module docstring).
        sensors: replaces :func:`default_sensor_suite` (e.g. a reduced suite for tests).
        duration: touchdown time (s) of every landing, reached by scaling its start
            distance (speeds, angle and kappas kept); None: :data:`APPROACH_DISTANCE`.
        formats: bag formats (``ros1``, ``ros2``); None: the config default (both).
        check_clearance: turn a blocked heading until the path is clear in the scene as
            the simulation will build it (with its own seed).
        labels: ``output.labels: true`` in every simulation (``--no-labels``: False).
    """
    if not scenes:
        msg = "--scenes: give at least one scene"
        raise ConfigError(msg)
    if len(set(scenes)) != len(scenes):
        msg = f"--scenes = {list(scenes)}: scenes must not repeat"
        raise ConfigError(msg)
    if seed < 0:
        msg = f"--seed = {seed}: must be >= 0"
        raise ConfigError(msg)
    if duration is not None and not (math.isfinite(duration) and duration > 0):
        msg = f"--duration = {duration}: must be a finite number of seconds > 0"
        raise ConfigError(msg)
    suite = [dict(s) for s in (sensors if sensors is not None else default_sensor_suite())]
    for j, scene_name in enumerate(scenes):
        goal = _scene_goal(scene_name)
        label = Path(scene_name).stem if scene_name.endswith((".yaml", ".yml")) else scene_name
        for i, (kx, ky, speed, heading_deg) in enumerate(PAPER_TRAJECTORIES):
            assert PAPER_K * max(kx, ky) < 0.5  # bounded deceleration on every gap
            heading = math.radians(heading_deg)
            distance = APPROACH_DISTANCE
            if duration is not None:
                t0 = _touchdown(_trajectory_block(kx, ky, speed, heading, distance, goal))
                distance *= duration / t0
            block = _trajectory_block(kx, ky, speed, heading, distance, goal)
            sim_seed = int(np.random.SeedSequence([seed, j, i]).generate_state(1, np.uint32)[0])
            # the simulation builds its scene with its own seed (clutter moves): check that one
            scene = _load(scene_name, sim_seed) if check_clearance else None
            if check_clearance and not _clear(scene, block, suite):
                for step in _HEADING_STEPS_DEG:
                    h = math.radians(heading_deg + step)
                    candidate = _trajectory_block(kx, ky, speed, h, distance, goal)
                    if _clear(scene, candidate, suite):
                        heading, block = h, candidate
                        break
                else:
                    msg = (
                        f"scene {scene_name!r}: landing {i + 1} (kappa_x {kx}, kappa_y {ky}) "
                        "hits scene objects for every heading tried; use another scene"
                    )
                    raise ConfigError(msg)
            config: dict[str, Any] = {
                "trajectory": block,
                "scene": scene_name,
                "sensors": [dict(s) for s in suite],
                "seed": sim_seed,
            }
            output: dict[str, Any] = {}
            if formats is not None:
                output["formats"] = list(formats)
            if labels:
                output["labels"] = True
            if output:
                config["output"] = output
            yield (
                DatasetRun(
                    folder=f"{label}_{i + 1:02d}",
                    scene=label,
                    number=i + 1,
                    kappa_x=kx,
                    kappa_y=ky,
                    speed=speed,
                    heading=heading,
                    distance=distance,
                    seed=sim_seed,
                    config=config,
                )
            )


# --------------------------------------------------------------------------- outputs
INDEX_COLUMNS = (
    "folder",
    "scene",
    "k",
    "kappa_x",
    "kappa_y",
    "speed_mps",
    "approach_angle_rad",
    "heading_rad",
    "distance_m",
    "seed",
    "duration_s",
    "events",
    "messages",
    "status",
)


def write_index(outdir: Path, runs: Sequence[DatasetRun]) -> Path:
    """``outdir/index.csv``: one row per simulation (parameters + run.json figures)."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(INDEX_COLUMNS)
    for run in runs:
        folder = outdir / run.folder
        info = read_manifest(folder)
        if info is None:
            duration = _touchdown(run.config["trajectory"])
            events: str | int = ""
            messages: str | int | None = ""
            status = "missing"
        else:
            d = run_duration(info)
            duration = d if d is not None else _touchdown(run.config["trajectory"])
            events = count_events(folder)
            messages = run_messages(info)
            status = "complete"
        writer.writerow(
            [
                run.folder,
                run.scene,
                f"{run.k:g}",
                f"{run.kappa_x:g}",
                f"{run.kappa_y:g}",
                f"{run.speed:g}",
                f"{APPROACH_ANGLE:.9f}",
                f"{run.heading:.9f}",
                f"{run.distance:.6f}",
                run.seed,
                f"{duration:.9f}",
                events,
                "" if messages is None else messages,
                status,
            ]
        )
    path = outdir / "index.csv"
    atomic_write_text(path, buf.getvalue())
    return path


def _readme(runs: Sequence[DatasetRun], scenes: Sequence[str], seed: int) -> str:
    lines = [
        "# roslan landing dataset",
        "",
        "Regenerates the dataset of ROS-LAN (Section 5): per scene six tau-theory landings",
        f"with k = {PAPER_K}, final approach angle pi/6, initial speeds 3-5 m/s and six",
        "(kappa_x, kappa_y) pairs; trajectory table sampled every 0.1 s.",
        f"Generated by `roslan dataset` (seed {seed}); scenes: {', '.join(scenes)}.",
        "",
        "## Layout",
        "",
        "- `index.csv`: one row per simulation (folder, scene, k, kappas, speed, approach",
        "  angle, heading, start distance, seed, duration, events, messages, status).",
        "- `trajectories_<scene>.png`: all landings of a scene together (goal frame).",
        "- `batch.json`: status of every simulation of the last `roslan dataset` run.",
        "- `<scene>_NN/`: one `roslan simulate` output folder per landing: `landing.bag`",
        "  (ROS 1), `landing_ros2/` (ROS 2, MCAP), `PLAYBACK.md` (how to play the bags),",
        "  `trajectory.csv` and `groundtruth.txt` (the tau trajectory and TUM ground truth),",
        "  `events.txt` (`t x y p`), `imu.txt`, sensor files, calibration in `calib/`, the",
        "  scene models and their poses, and `run.json` (resolved config, versions, counts).",
        "",
        "Text files use seconds since the trajectory start; bags use absolute stamps.",
        "Rerunning `roslan dataset` with the same options skips completed simulations.",
        "",
        "## Simulations",
        "",
        "| folder | kappa_x | kappa_y | speed (m/s) | heading (deg) | seed |",
        "|---|---|---|---|---|---|",
    ]
    for r in runs:
        lines.append(
            f"| {r.folder} | {r.kappa_x:g} | {r.kappa_y:g} | {r.speed:g} | "
            f"{math.degrees(r.heading):.0f} | {r.seed} |"
        )
    return "\n".join(lines) + "\n"


def build_dataset(
    outdir: str | Path,
    scenes: Sequence[str] = PAPER_SCENES,
    *,
    seed: int = 0,
    workers: int | None = None,
    scheduler: str | None = None,
    retries: int = 2,
    overwrite: bool = False,
    sensors: Sequence[Mapping[str, Any]] | None = None,
    duration: float | None = None,
    formats: Sequence[str] | None = None,
    progress: bool = True,
    runner: Runner | None = None,
    labels: bool = True,
) -> tuple[list[DatasetRun], BatchReport]:
    """Plan, simulate (on Dask, see :func:`roslan.batch.runner.run_tasks`) and index the dataset."""
    out = Path(outdir).resolve()
    runs = dataset_plan(
        scenes, seed=seed, sensors=sensors, duration=duration, formats=formats, labels=labels
    )
    tasks = make_tasks(
        [r.config for r in runs],
        Path.cwd(),
        names=[r.folder for r in runs],
        overrides=[
            {"scene": r.scene, "kappa_x": r.kappa_x, "kappa_y": r.kappa_y, "speed": r.speed}
            for r in runs
        ],
        source="roslan dataset",
    )
    bad = [t for t in tasks if t.error]
    if bad:
        # The plan is ours: an invalid config means a bad --sensors file; say so up front.
        msg = "the dataset configs do not validate:\n" + "\n".join(str(t.error) for t in bad[:3])
        raise ConfigError(msg)
    report = run_tasks(
        tasks,
        out,
        workers=workers,
        scheduler=scheduler,
        retries=retries,
        overwrite=overwrite,
        runner=runner,
        progress=progress,
        meta={"command": "roslan dataset", "scenes": list(scenes), "seed": seed},
    )
    write_index(out, runs)
    for scene in dict.fromkeys(r.scene for r in runs):
        plot_trajectories([r for r in runs if r.scene == scene], out / f"trajectories_{scene}.png")
    (out / "README.md").write_text(_readme(runs, scenes, seed), encoding="utf-8")
    (out / "plan.json").write_text(
        json.dumps(
            [
                {
                    "folder": r.folder,
                    "scene": r.scene,
                    "kappa_x": r.kappa_x,
                    "kappa_y": r.kappa_y,
                    "speed": r.speed,
                    "heading": r.heading,
                    "distance": r.distance,
                    "seed": r.seed,
                    "config": r.config,
                }
                for r in runs
            ],
            indent=2,
        )
        + "\n",
        encoding="utf-8",
    )
    return runs, report
