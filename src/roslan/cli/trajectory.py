"""``roslan trajectory CONFIG -o OUTDIR``: sample a landing and write its files."""

from __future__ import annotations

import argparse
import shutil
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from roslan.config.base import format_validation_error, load_yaml
from roslan.errors import ConfigError, OutputError
from roslan.rundir.folder import finalize, make_temp
from roslan.trajectory.base import DEFAULT_GROUND_TRUTH_RATE, Trajectory
from roslan.trajectory.config import TrajectoryConfig
from roslan.trajectory.export import write_trajectory_files
from roslan.trajectory.generator import TauTrajectory, TrajectoryWarning
from roslan.trajectory.vibration import VibratingTrajectory

__all__ = ["register", "write_into"]


def write_into(
    traj: Trajectory,
    outdir: Path,
    *,
    overwrite: bool,
    plot: bool = True,
    ground_truth_rate: float = DEFAULT_GROUND_TRUTH_RATE,
) -> None:
    """Write the trajectory files into ``outdir`` (groundtruth.txt at ``ground_truth_rate``).

    A new ``outdir`` is filled under a temporary name and renamed at the end, so it
    never appears half-written. An existing one is an :class:`OutputError` unless
    ``overwrite`` (then the files are replaced one by one, each atomically).
    """
    out = Path(outdir)
    if out.exists() or out.is_symlink():
        if not overwrite:
            msg = f"{out}: output folder already exists; pass --overwrite to replace its files"
            raise OutputError(msg)
        if not out.is_dir():
            msg = f"{out}: exists and is not a folder"
            raise OutputError(msg)
        _write(traj, out, plot=plot, ground_truth_rate=ground_truth_rate)
        return
    tmp = make_temp(out.absolute())
    try:
        _write(traj, tmp, plot=plot, ground_truth_rate=ground_truth_rate)
        finalize(tmp, out.absolute(), overwrite=False)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _write(traj: Trajectory, folder: Path, *, plot: bool, ground_truth_rate: float) -> None:
    """The trajectory files, and trajectory.png if ``plot``."""
    write_trajectory_files(traj, folder, ground_truth_rate=ground_truth_rate)
    if plot:
        from roslan.plots.landing import write_trajectory_plot

        write_trajectory_plot(traj, folder / "trajectory.png")


def load_trajectory_block(path: Path) -> TrajectoryConfig:
    """The validated ``trajectory:`` block of a simulation YAML; nothing else in the
    file is read (a sensor problem there does not stop a trajectory export)."""
    data = load_yaml(path)
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        msg = f"{path}: expected a mapping of keys at the top level, got {type(data).__name__}"
        raise ConfigError(msg)
    block = data.get("trajectory")
    block = {} if block is None else block
    context = {"base_dir": path.parent.resolve(), "source": path}
    try:
        return TrajectoryConfig.model_validate(block, context=context)
    except ValidationError as err:
        text = format_validation_error(
            err, path, ("trajectory",), model=TrajectoryConfig, data=block
        )
        raise ConfigError(text) from None


def load_ground_truth_rate(path: Path) -> float:
    """``output.ground_truth_rate`` of a simulation YAML (the default 200 Hz without it),
    so that ``roslan trajectory`` writes the groundtruth.txt ``roslan simulate`` would;
    no other output key is read."""
    from roslan.config.sim import OutputConfig

    data = load_yaml(path)
    block = data.get("output") if isinstance(data, Mapping) else None
    if not isinstance(block, Mapping) or "ground_truth_rate" not in block:
        return DEFAULT_GROUND_TRUTH_RATE
    sub = {"ground_truth_rate": block["ground_truth_rate"]}
    try:
        return float(OutputConfig.model_validate(sub).ground_truth_rate)
    except ValidationError as err:
        text = format_validation_error(err, path, ("output",), model=OutputConfig, data=sub)
        raise ConfigError(text) from None


def load_scene_goal(path: Path, trajectory: TrajectoryConfig) -> TrajectoryConfig:
    """``trajectory`` landing on the file's scene's marker or perch when it gives no
    ``goal``, as ``roslan simulate`` flies it (:func:`roslan.scene.goal.goal_from_scene`)."""
    data = load_yaml(path)
    scene = data.get("scene") if isinstance(data, Mapping) else None
    if not isinstance(scene, str):
        return trajectory
    from roslan.errors import SceneError
    from roslan.scene.goal import goal_from_scene

    try:
        return goal_from_scene(trajectory, scene, base_dir=path.parent.resolve())
    except SceneError as err:  # the scene cannot be loaded: name the config naming it
        raise SceneError(f"{path}: {err}") from None


def load_vehicle_block(path: Path, trajectory: TrajectoryConfig) -> TrajectoryConfig:
    """``trajectory`` with its goal moved to base_link by the file's ``vehicle:`` block
    (the default vehicle without one), as ``roslan simulate`` flies it. The scene is read
    only when ``vehicle.contact: auto`` must tell a perch (grasp point) from a landing
    (feet) and the two points differ."""
    from roslan.vehicle import VehicleConfig, base_link_trajectory, contact_depends_on_scene

    data = load_yaml(path)
    data = data if isinstance(data, Mapping) else {}
    block = data.get("vehicle")
    block = {} if block is None else block
    try:
        vehicle = VehicleConfig.model_validate(block)
    except ValidationError as err:
        text = format_validation_error(err, path, ("vehicle",), model=VehicleConfig, data=block)
        raise ConfigError(text) from None
    scene = None
    if contact_depends_on_scene(vehicle) and isinstance(data.get("scene"), str):
        from roslan.scene import load_scene

        seed = data.get("seed", 0)
        seed = seed if isinstance(seed, int) and not isinstance(seed, bool) and seed >= 0 else 0
        scene = load_scene(data["scene"], base_dir=path.parent.resolve(), seed=seed)
    return base_link_trajectory(trajectory, vehicle, scene)


def _run(args: argparse.Namespace) -> int:
    from roslan.errors import ConfigError
    from roslan.trajectory.spline import make_trajectory

    if (args.config is None) == (args.from_file is None):
        msg = "give either CONFIG (a simulation YAML) or --from FILE (a TUM pose file)"
        raise ConfigError(msg)
    if args.from_file is not None:
        trajectory = TrajectoryConfig.model_validate({"file": str(args.from_file)})
        base_dir = None
        gt_rate = DEFAULT_GROUND_TRUTH_RATE
    else:
        trajectory = load_trajectory_block(Path(args.config))
        trajectory = load_scene_goal(Path(args.config), trajectory)
        trajectory = load_vehicle_block(Path(args.config), trajectory)
        base_dir = Path(args.config).parent
        gt_rate = load_ground_truth_rate(Path(args.config))
    with warnings.catch_warnings():
        # every hard-landing note reaches the user (one "warning: ..." line each, printed
        # by roslan.cli), even if the same text was shown earlier in this process
        warnings.simplefilter("always", TrajectoryWarning)
        traj = make_trajectory(trajectory, base_dir=base_dir)
    write_into(
        traj,
        Path(args.output),
        overwrite=args.overwrite,
        plot=not args.no_plot,
        ground_truth_rate=gt_rate,
    )
    files = "trajectory.csv, groundtruth.txt, summary.json"
    if not args.no_plot:
        files += ", trajectory.png"
    base = traj.inner if isinstance(traj, VibratingTrajectory) else traj
    if isinstance(base, TauTrajectory):
        head = f"touchdown T = {traj.T:.6f} s, tau(0) = {base.tau0:.6f} s"
    else:
        head = f"duration {traj.T:.6f} s (spline through {trajectory.file})"
    print(f"{head}, {len(traj.table_times())} samples -> {args.output}/ ({files})")
    return 0


def register(subparsers: Any) -> None:
    """Add the ``trajectory`` command to the top-level ``roslan`` subparsers."""
    p = subparsers.add_parser(
        "trajectory",
        help="sample a tau-theory landing into CSV/TUM/JSON/PNG",
        description=(
            "Read the 'trajectory:' block of a simulation YAML and write trajectory.csv "
            "(frame F, every sample_dt), groundtruth.txt (TUM, world, at the YAML's "
            "output.ground_truth_rate, default 200 Hz, as roslan simulate writes it), "
            "summary.json and trajectory.png."
        ),
    )
    p.add_argument("config", type=Path, nargs="?", metavar="CONFIG", help="simulation YAML file")
    p.add_argument(
        "--from",
        dest="from_file",
        type=Path,
        metavar="FILE",
        help="fit a TUM pose file (t x y z qx qy qz qw, world frame) instead of a CONFIG",
    )
    p.add_argument(
        "-o",
        "--output",
        required=True,
        type=Path,
        metavar="OUTDIR",
        help="output folder (created; must not exist unless --overwrite)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace files in an existing OUTDIR")
    p.add_argument("--no-plot", action="store_true", help="skip trajectory.png")
    p.set_defaults(func=_run)
