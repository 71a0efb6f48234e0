"""``roslan dataset`` (the paper's dataset) and ``roslan batch`` (parameter sweeps)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from roslan.errors import ConfigError
from roslan.limits import seed_arg

__all__ = ["register"]


def _cluster_args(p: argparse.ArgumentParser) -> None:
    group = p.add_mutually_exclusive_group()
    group.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="local Dask worker processes, one thread each, on loopback "
        "(default: one per CPU core; 0 = run in this process, no Dask)",
    )
    group.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="address of an existing Dask scheduler (tcp://host:8786); "
        "the output folder must be on a file system its workers share",
    )
    p.add_argument(
        "--retries",
        type=int,
        default=2,
        metavar="N",
        help="extra attempts for a simulation that crashed (default 2); "
        "config errors are deterministic and not retried",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar or summary table")


def _load_sensors(path: str) -> list[dict[str, Any]]:
    from roslan.config.base import load_yaml

    data = load_yaml(path)
    if isinstance(data, dict) and set(data) == {"sensors"}:
        data = data["sensors"]
    if not isinstance(data, list) or not all(isinstance(s, dict) for s in data):
        msg = f"{path}: expected a list of sensor mappings (or a mapping with only 'sensors')"
        raise ConfigError(msg)
    return data


def _formats(value: str | None) -> list[str] | None:
    return {None: None, "ros1": ["ros1"], "ros2": ["ros2"], "both": ["ros1", "ros2"]}[value]


def _dataset(args: argparse.Namespace) -> int:
    from roslan.batch import iter_errors, print_summary
    from roslan.batch.paper import build_dataset

    sensors = _load_sensors(args.sensors) if args.sensors else None
    if args.dry_run:
        return _dataset_dry_run(args, sensors)
    _, report = build_dataset(
        args.output,
        args.scenes,
        seed=args.seed,
        workers=args.workers,
        scheduler=args.scheduler,
        retries=args.retries,
        overwrite=args.overwrite,
        sensors=sensors,
        duration=args.duration,
        formats=_formats(args.format),
        progress=not args.quiet,
    )
    if not args.quiet:
        print_summary(report)
        print(f"dataset index: {Path(args.output) / 'index.csv'}")
    for line in iter_errors(report):
        print(f"error: {line}")
    return 0 if report.ok else 1


def _dataset_dry_run(args: argparse.Namespace, sensors: list[dict[str, Any]] | None) -> int:
    import math

    from roslan.batch import make_tasks
    from roslan.batch.paper import dataset_plan
    from roslan.dryrun import PlanRow, print_plan

    runs = dataset_plan(
        args.scenes, seed=args.seed, sensors=sensors, duration=args.duration,
        formats=_formats(args.format),
    )  # fmt: skip
    tasks = make_tasks(
        [r.config for r in runs], Path.cwd(), names=[r.folder for r in runs],
        overrides=[{} for _ in runs], source="roslan dataset",
    )  # fmt: skip
    rows = [
        PlanRow(
            r.folder,
            {
                "kappa_x": f"{r.kappa_x:g}",
                "kappa_y": f"{r.kappa_y:g}",
                "speed m/s": f"{r.speed:.2f}",
                "heading deg": f"{math.degrees(r.heading):.0f}",
                "distance m": f"{r.distance:.2f}",
                "seed": str(r.seed),
            },
            config=r.config,
            error=t.error,
        )
        for r, t in zip(runs, tasks, strict=True)
    ]
    return print_plan("roslan dataset plan", rows, Path(args.output), args.workers)


def _short(value: Any) -> str:
    """A sweep value for the plan table: floats to 4 significant digits."""
    if isinstance(value, float):
        return f"{value:.4g}"
    text = str(value)
    return text if len(text) <= 24 else text[:21] + "..."


def _batch(args: argparse.Namespace) -> int:
    from roslan.batch import iter_errors, load_sweep, print_summary, run_tasks, sweep_tasks

    sweep = load_sweep(args.sweep)
    tasks = sweep_tasks(sweep)
    if args.dry_run:
        from roslan.dryrun import PlanRow, print_plan

        rows = [
            PlanRow(t.name, {k: _short(v) for k, v in t.overrides.items()}, t.config, t.error)
            for t in tasks
        ]
        return print_plan("roslan batch plan", rows, Path(args.output), args.workers)
    report = run_tasks(
        tasks,
        args.output,
        workers=args.workers,
        scheduler=args.scheduler,
        retries=args.retries,
        overwrite=args.overwrite,
        progress=not args.quiet,
        meta={"command": "roslan batch", "sweep": str(Path(args.sweep).resolve())},
    )
    if not args.quiet:
        print_summary(report)
    for line in iter_errors(report):
        print(f"error: {line}")
    return 0 if report.ok else 1


def register(subparsers: Any) -> None:
    from roslan.batch.paper import PAPER_SCENES

    p = subparsers.add_parser(
        "dataset",
        help="regenerate the paper's dataset (6 landings per scene, full sensor suite)",
        description="The ROS-LAN dataset (paper Section 5): per scene six landings with k = 0.5, "
        "approach angle pi/6, speeds 3-5 m/s and six (kappa_x, kappa_y) pairs; frame camera, "
        "DAVIS346 event camera, sonar, IMU, HDL-32E and ground truth. Writes one `roslan "
        "simulate` folder per landing plus index.csv, README.md and trajectories_<scene>.png.",
    )
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="dataset folder")
    p.add_argument(
        "--scenes",
        nargs="+",
        default=list(PAPER_SCENES),
        metavar="SCENE",
        help="built-in scene names or scene YAML files (default: warehouse refinery)",
    )
    p.add_argument("--seed", type=seed_arg, default=0, help="dataset seed (default 0)")
    p.add_argument("--overwrite", action="store_true", help="rerun completed simulations too")
    p.add_argument(
        "--sensors",
        metavar="YAML",
        help="replace the paper's sensor suite by this list of sensor configs",
    )
    p.add_argument(
        "--duration",
        type=float,
        metavar="S",
        help="touchdown time of every landing (scales the start distance; default: 8 m start)",
    )
    p.add_argument("--format", choices=("ros1", "ros2", "both"), help="bag formats (default both)")
    p.add_argument("--dry-run", action="store_true", help="print the plan, simulate nothing")
    _cluster_args(p)
    p.set_defaults(func=_dataset)

    b = subparsers.add_parser(
        "batch",
        help="run a parameter sweep (grid / zipped lists / LHS samples) on Dask",
        description="Expand SWEEP.yaml (a base config plus grid, zip and sample axes over dotted "
        "config keys) into simulations and run them on a Dask cluster; resumable.",
    )
    b.add_argument("sweep", metavar="SWEEP.yaml")
    b.add_argument("-o", "--output", required=True, metavar="DIR", help="batch folder")
    b.add_argument("--overwrite", action="store_true", help="rerun completed simulations too")
    b.add_argument("--dry-run", action="store_true", help="list the tasks and their validity")
    _cluster_args(b)
    b.set_defaults(func=_batch)
