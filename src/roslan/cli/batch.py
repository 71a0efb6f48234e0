"""``roslan batch``: run a parameter sweep (:mod:`roslan.batch`)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

__all__ = ["add_cluster_args", "register"]


def add_cluster_args(p: argparse.ArgumentParser) -> None:
    """``--workers`` / ``--scheduler``, ``--retries`` and ``--quiet`` (also used by
    ``roslan dataset``)."""
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
        from roslan.batch import dry_check
        from roslan.cli.dryrun import PlanRow, print_plan

        rows = [
            PlanRow(
                t.name,
                {k: _short(v) for k, v in t.overrides.items()},
                t.config,
                dry_check(t, args.output, args.overwrite),
            )
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
    b = subparsers.add_parser(
        "batch",
        help="run a parameter sweep (grid / zipped lists / LHS samples) on Dask",
        description="Expand SWEEP.yaml (a base config plus grid, zip and sample axes over dotted "
        "config keys) into simulations and run them on a Dask cluster; resumable.",
    )
    b.add_argument("sweep", metavar="SWEEP.yaml")
    b.add_argument("-o", "--output", required=True, metavar="DIR", help="batch folder")
    b.add_argument("--overwrite", action="store_true", help="rerun completed simulations too")
    b.add_argument(
        "--dry-run",
        action="store_true",
        help="list the tasks and their validity (every check of the run), run nothing",
    )
    add_cluster_args(b)
    b.set_defaults(func=_batch)
