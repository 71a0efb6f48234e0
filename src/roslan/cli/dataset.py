"""``roslan dataset``: regenerate the paper's dataset (:mod:`roslan.batch.paper`)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from roslan.cli.batch import add_cluster_args
from roslan.cli.common import FORMAT_CHOICES, bag_formats, seed_arg
from roslan.errors import ConfigError

__all__ = ["register"]


def _load_sensors(path: str) -> list[dict[str, Any]]:
    from roslan.config.base import load_yaml

    data = load_yaml(path)
    if isinstance(data, dict) and set(data) == {"sensors"}:
        data = data["sensors"]
    if not isinstance(data, list) or not all(isinstance(s, dict) for s in data):
        msg = f"{path}: expected a list of sensor mappings (or a mapping with only 'sensors')"
        raise ConfigError(msg)
    return data


def _dataset(args: argparse.Namespace) -> int:
    from roslan.batch.paper import build_dataset
    from roslan.batch.report import iter_errors, print_summary

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
        formats=bag_formats(args.format),
        progress=not args.quiet,
        labels=not args.no_labels,
    )
    if not args.quiet:
        print_summary(report)
        print(f"dataset index: {Path(args.output) / 'index.csv'}")
    for line in iter_errors(report):
        print(f"error: {line}")
    return 0 if report.ok else 1


def _dataset_dry_run(args: argparse.Namespace, sensors: list[dict[str, Any]] | None) -> int:
    import math

    from roslan.batch.paper import iter_dataset_plan
    from roslan.batch.runner import dry_check
    from roslan.batch.tasks import make_tasks
    from roslan.cli.dryrun import PlanRow, print_plan

    rows = []
    # each landing checked as soon as it is planned: its scene (built with its seed for
    # the plan's clearance check) is still loaded for the run's checks
    for r in iter_dataset_plan(
        args.scenes, seed=args.seed, sensors=sensors, duration=args.duration,
        formats=bag_formats(args.format), labels=not args.no_labels,
    ):  # fmt: skip
        (task,) = make_tasks(
            [r.config], Path.cwd(), names=[r.folder], overrides=[{}], source="roslan dataset"
        )
        values = {
            "kappa_x": f"{r.kappa_x:g}",
            "kappa_y": f"{r.kappa_y:g}",
            "speed m/s": f"{r.speed:.2f}",
            "heading deg": f"{math.degrees(r.heading):.0f}",
            "distance m": f"{r.distance:.2f}",
            "seed": str(r.seed),
        }
        error = dry_check(task, args.output, args.overwrite)
        rows.append(PlanRow(r.folder, values, config=r.config, error=error))
    return print_plan("roslan dataset plan", rows, Path(args.output), args.workers)


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
    p.add_argument("--format", choices=FORMAT_CHOICES, help="bag formats (default both)")
    p.add_argument(
        "--no-labels",
        action="store_true",
        help="write no ground-truth labels (default: output.labels: true, docs/guide/labels.md)",
    )
    p.add_argument(
        "--dry-run",
        action="store_true",
        help="print the plan with every run's checks, simulate nothing",
    )
    add_cluster_args(p)
    p.set_defaults(func=_dataset)
