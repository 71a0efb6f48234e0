"""``--dry-run`` output of ``roslan simulate``, ``roslan dataset`` and ``roslan batch``: the
plan as a table with each run's estimated disk use and run time, a summary line, and the
exit code (non-zero when any task is invalid)."""

from __future__ import annotations

import os
import shutil
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from roslan.pipeline.estimate import (
    RunEstimate,
    batch_seconds,
    estimate_run,
    format_bytes,
    format_seconds,
)

__all__ = ["PlanRow", "estimate_config", "print_plan", "print_run_estimate"]


@dataclass
class PlanRow:
    """One task of a plan: its name, the values to show, and its config or error."""

    name: str
    values: Mapping[str, str] = field(default_factory=dict)
    config: Any = None
    """A validated :class:`~roslan.config.sim.SimConfig`, a config mapping, or None."""
    error: str | None = None


def estimate_config(config: Any) -> RunEstimate | None:
    """Estimate of a SimConfig or config mapping (None when it does not validate)."""
    from pydantic import ValidationError

    from roslan.config.sim import SimConfig

    try:
        cfg = config if isinstance(config, SimConfig) else SimConfig.model_validate(config)
        return estimate_run(cfg)
    except (ValidationError, ValueError, TypeError):
        return None


def _console() -> Any:
    from rich.console import Console

    return Console(width=None if sys.stdout.isatty() else 140, highlight=False)


def print_plan(
    title: str, rows: Sequence[PlanRow], outdir: Path | None = None, workers: int | None = None
) -> int:
    """Print the plan table and summary line; returns the exit code (1 if any invalid)."""
    from rich.table import Table

    columns: list[str] = []
    for r in rows:
        for c in r.values:
            if c not in columns:
                columns.append(c)
    table = Table(title=title)
    table.add_column("task")
    for c in columns:
        table.add_column(c, justify="right")
    table.add_column("est. disk", justify="right")
    table.add_column("est. time", justify="right")
    table.add_column("status")
    total_b = 0.0
    n_ok = n_bad = 0
    ests: list[RunEstimate] = []
    for r in rows:
        est = None if r.error else estimate_config(r.config)
        if r.error is None and est is not None:
            n_ok += 1
            total_b += est.bytes
            ests.append(est)
            status = "[green]valid[/green]"
        else:
            n_bad += 1
            status = "[red]invalid[/red]: " + (r.error or "config does not validate").replace(
                "\n", "; "
            )
        table.add_row(
            r.name,
            *(r.values.get(c, "") for c in columns),
            format_bytes(est.bytes) if est else "-",
            format_seconds(est.seconds) if est else "-",
            status,
        )
    con = _console()
    con.print(table)
    how = "one after the other" if workers is not None and workers <= 1 else (
        f"{min(workers or (os.cpu_count() or 1), os.cpu_count() or 1)} local workers"
    )  # fmt: skip
    line = (
        f"{n_ok} valid, {n_bad} invalid; estimated {format_bytes(total_b)} of disk and "
        f"{format_seconds(batch_seconds(ests, workers))} of run time in total ({how}, "
        f"on an idle machine with {os.cpu_count() or 1} cores)"
    )
    if outdir is not None:
        line += f"; {format_bytes(_free(outdir))} free at {outdir}"
    con.print(line)
    return 1 if n_bad else 0


def _free(path: Path) -> float:
    probe = Path(path).absolute()
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    return float(shutil.disk_usage(probe).free)


def print_run_estimate(
    config: Any, outdir: Path, formats: tuple[str, ...] | None, *, duration: float | None = None
) -> int:
    """``roslan simulate --dry-run``: the estimate of one run, output by output
    (``duration``: the trajectory's, s, as the checks built it)."""
    from rich.table import Table

    est = estimate_run(config, formats, duration=duration)
    table = Table(title=f"roslan simulate plan: {outdir}")
    table.add_column("output")
    table.add_column("est. disk", justify="right")
    names = {
        "bag_ros1": "landing.bag",
        "bag_ros2": "landing_ros2/",
        "files": "other text files",
        "labels": f"labels ({est.label_files} files)",
    }
    for key, nbytes in sorted(est.parts.items(), key=lambda kv: -kv[1]):
        table.add_row(names.get(key, key), format_bytes(nbytes))
    con = _console()
    con.print(table)
    con.print(
        f"1 valid, 0 invalid; estimated {format_bytes(est.bytes)} of disk and "
        f"{format_seconds(est.seconds)} of run time ({est.assumption()}); "
        f"{format_bytes(_free(outdir))} free at {outdir}"
    )
    return 0
