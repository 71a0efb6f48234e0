"""What a batch reports: per-task results, ``batch.json``, the progress bar and the
summary table."""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from roslan.io.files import atomic_write_text

__all__ = [
    "BatchJournal",
    "BatchReport",
    "TaskProgress",
    "TaskResult",
    "iter_errors",
    "print_summary",
]


@dataclass
class TaskResult:
    """Outcome of one task (one row of ``batch.json``)."""

    name: str
    index: int
    status: str
    """``complete`` (run now), ``skipped`` (already complete), ``failed`` (ran, error)
    or ``invalid`` (config rejected before running)."""
    overrides: dict[str, Any] = field(default_factory=dict)
    error: str | None = None
    attempts: int = 0
    wall_s: float | None = None
    duration_s: float | None = None
    messages: int | None = None

    def as_json(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "index": self.index,
            "status": self.status,
            "overrides": self.overrides,
            "error": self.error,
            "attempts": self.attempts,
            "wall_s": self.wall_s,
            "duration_s": self.duration_s,
            "messages": self.messages,
        }


@dataclass
class BatchReport:
    """All results of a batch plus where ``batch.json`` went."""

    outdir: Path
    results: list[TaskResult]
    wall_s: float
    workers: int | str

    def counts(self) -> dict[str, int]:
        out = {s: 0 for s in ("complete", "skipped", "failed", "invalid")}
        for r in self.results:
            out[r.status] = out.get(r.status, 0) + 1
        return out

    @property
    def ok(self) -> bool:
        c = self.counts()
        return c["failed"] == 0 and c["invalid"] == 0


class BatchJournal:
    """``OUTDIR/batch.json``: the command's ``meta``, the counts and every task's result;
    rewritten atomically as tasks finish (at most once a second until the final save)."""

    def __init__(
        self, outdir: Path, results: Mapping[str, TaskResult], meta: Mapping[str, Any] | None
    ) -> None:
        self.path = outdir / "batch.json"
        self.results = results
        self.meta = dict(meta or {})
        self.t0 = time.perf_counter()
        self._last = 0.0

    def ordered(self) -> list[TaskResult]:
        """The results in task order."""
        return sorted(self.results.values(), key=lambda r: r.index)

    def save(self, final: bool = False) -> None:
        now = time.perf_counter()
        if not final and now - self._last < 1.0:
            return
        self._last = now
        ordered = self.ordered()
        counts: dict[str, int] = {}
        for r in ordered:
            counts[r.status] = counts.get(r.status, 0) + 1
        data = {
            **self.meta,
            "finished": final,
            "wall_s": round(now - self.t0, 3),
            "counts": counts,
            "tasks": [r.as_json() for r in ordered],
        }
        atomic_write_text(self.path, json.dumps(data, indent=2, default=str) + "\n")


class TaskProgress:
    """A rich progress bar over tasks (or nothing when disabled); ``with`` gives the
    ``advance(task_name)`` callable."""

    def __init__(self, enabled: bool, total: int) -> None:
        self.enabled = enabled and total > 0
        self.total = total
        self._bar: Any = None
        self._task: Any = None

    def __enter__(self) -> Callable[[str], None]:
        if self.enabled:
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
            )

            self._bar = Progress(
                TextColumn("simulations"),
                BarColumn(),
                MofNCompleteColumn(),
                TimeElapsedColumn(),
                TextColumn("{task.description}"),
                transient=True,
            )
            self._bar.start()
            self._task = self._bar.add_task("", total=self.total)
        return self.advance

    def advance(self, name: str) -> None:
        if self._bar is not None:
            self._bar.update(self._task, advance=1, description=name)

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.stop()


def _short_error(error: str | None) -> str:
    if not error:
        return ""
    line = error.strip().splitlines()[0]
    # drop the "<source>: task NNNN: " prefix the table's first column already says
    _, sep, rest = line.partition(": task ")
    if sep:
        line = rest.partition(": ")[2] or line
    return line if len(line) <= 60 else line[:59] + "…"


def print_summary(report: BatchReport, *, max_rows: int = 50) -> None:
    """A rich table of every task's status (failures first when there are many)."""
    from rich.console import Console
    from rich.table import Table

    # piped output (logs, CI) gets a readable fixed width instead of 80 columns
    console = Console(width=None if sys.stdout.isatty() else 120)
    rows = report.results
    if len(rows) > max_rows:
        bad = [r for r in rows if r.status in ("failed", "invalid")]
        rows = (bad + [r for r in rows if r not in bad])[:max_rows]
    style = {"complete": "green", "skipped": "cyan", "failed": "red", "invalid": "yellow"}
    cells = [
        [
            r.name,
            r.status,
            str(r.attempts or ""),
            f"{r.wall_s:.2f}" if r.wall_s is not None else "",
            f"{r.duration_s:.2f}" if r.duration_s is not None else "",
            str(r.messages) if r.messages is not None else "",
        ]
        for r in rows
    ]
    table = Table(title=f"batch: {report.outdir}")
    for j, col in enumerate(("task", "status", "tries", "wall s", "traj s", "msgs")):
        width = max([len(col)] + [len(c[j]) for c in cells])
        table.add_column(col, no_wrap=True, min_width=width)
    table.add_column("error (full text in batch.json)", no_wrap=True)
    for r, c in zip(rows, cells, strict=True):
        c[1] = f"[{style.get(r.status, '')}]{r.status}[/]"
        table.add_row(*c, _short_error(r.error))
    console.print(table)
    counts = ", ".join(f"{n} {s}" for s, n in report.counts().items() if n)
    more = (
        f" ({len(report.results) - len(rows)} more rows in batch.json)"
        if len(report.results) > len(rows)
        else ""
    )
    w = report.workers
    where = (
        f"scheduler {w}" if isinstance(w, str) else f"{w} local worker(s)" if w else "this process"
    )
    console.print(f"{counts or 'nothing to do'} in {report.wall_s:.1f} s on {where}{more}")
    console.print(f"status of every task: {report.outdir / 'batch.json'}")


def iter_errors(report: BatchReport) -> Iterator[str]:
    """``name: error`` for every failed or invalid task."""
    for r in report.results:
        if r.status in ("failed", "invalid"):
            yield f"{r.name}: {r.error}"
