"""What a finished ``roslan simulate`` folder says about its run: ``run.json`` (written last
by the simulation pipeline, :mod:`roslan.pipeline.run`, with ``"complete": true``) and the event
files. The one place that reads them for batches and the dataset index."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

__all__ = ["read_run_json", "run_duration", "run_events", "run_messages"]


def read_run_json(folder: Path) -> dict[str, Any] | None:
    """``folder/run.json`` if it exists, parses and says ``"complete": true``; else None."""
    try:
        data = json.loads((folder / "run.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if isinstance(data, dict) and data.get("complete") is True:
        return data
    return None


def run_duration(info: Mapping[str, Any]) -> float | None:
    """Trajectory duration (s) from run.json (``trajectory_duration_s``), None if absent."""
    v = info.get("trajectory_duration_s")
    if isinstance(v, int | float) and not isinstance(v, bool):
        return float(v)
    return None


def run_messages(info: Mapping[str, Any]) -> int | None:
    """Total bag messages from run.json (``messages_total``), None if absent."""
    total = info.get("messages_total")
    if isinstance(total, int) and not isinstance(total, bool):
        return total
    return None


def run_events(folder: Path) -> int:
    """Events the run wrote: rows of the first ``events.h5`` under ``folder``, else lines
    of the first ``events.txt``, else 0 (run.json does not count events)."""
    h5 = sorted(folder.rglob("events.h5"))
    if h5:
        import h5py

        with h5py.File(h5[0], "r") as f:
            return int(f["events/t"].shape[0])
    txt = sorted(folder.rglob("events.txt"))
    if txt:
        count = 0
        with txt[0].open("rb") as fh:
            for block in iter(lambda: fh.read(1 << 22), b""):
                count += block.count(b"\n")
        return count
    return 0
