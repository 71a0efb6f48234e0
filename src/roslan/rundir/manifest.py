"""The typed manifest of a run folder: ``run.json`` and ``timing.json``.

``run.json`` is written last by a run (its presence, with ``"complete": true``, marks a
complete folder) and is deterministic: same config and seed, same bytes. ``timing.json``
holds this run's wall-clock figures, the only numbers that differ between identical runs.
:class:`RunManifest` and :class:`Timing` are the one description of both files, used by
the pipeline that writes them and by every reader (plots, batch, dataset index).
"""

from __future__ import annotations

import datetime as _dt
import json
import platform
from collections.abc import Mapping, Sequence
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any, NotRequired, TypedDict, cast

from roslan import __version__

__all__ = [
    "DEPENDENCIES",
    "RUN_FILE",
    "TIMING_FILE",
    "RunManifest",
    "Timing",
    "TopicEntry",
    "make_manifest",
    "read_manifest",
    "run_duration",
    "run_messages",
    "versions",
    "write_json",
]

RUN_FILE = "run.json"
TIMING_FILE = "timing.json"
DEPENDENCIES = ("numpy", "scipy", "pydantic", "rosbags", "PyYAML", "trimesh", "moderngl", "embreex")
"""Packages whose versions run.json records."""


class TopicEntry(TypedDict):
    """One topic of the bags in run.json."""

    type: str
    messages: int
    publisher: str
    """The component that wrote it: ``ground_truth`` or a sensor name."""


class RunManifest(TypedDict):
    """``run.json``: what was run, with which software, and what the bags hold."""

    complete: bool
    roslan_version: str
    config_file: str | None
    seed: int
    start_time_ns: int
    start_time_utc: str
    time_offset_note: str
    trajectory_duration_s: float
    touchdown_time_s: float
    formats: list[str]
    bags: dict[str, str]
    """Bag flavour -> file or folder name in OUTDIR."""
    topics: dict[str, TopicEntry]
    messages_total: int
    sensors: list[str]
    versions: dict[str, str]
    timing: str
    config: dict[str, Any]
    """The resolved config (every default filled in): rerunning it reproduces the run."""
    renderer: NotRequired[dict[str, Any]]
    """The OpenGL implementation that rendered the camera images (``gl_renderer``,
    ``gl_version``, ``gl_vendor``) and the anti-aliasing and texture-filtering settings
    (:func:`roslan.render.gl.image_formation`); only in runs with a camera-type sensor."""
    files: NotRequired[list[str]]
    """Every file the run wrote (run.json included), sorted POSIX paths relative to
    OUTDIR: ``--overwrite`` replaces a folder only when it holds nothing else."""


class Timing(TypedDict):
    """``timing.json``: this run's wall-clock figures. The real-time factor is wall time /
    trajectory time (<= 1: faster than real time), the one measure of speed roslan
    reports (progress bar, PLAYBACK.md, docs)."""

    wall_time_s: float
    setup_s: float
    stream_start_s: float
    """Seconds from the run's start to the first streamed message (after the set-up)."""
    stream_s: float
    real_time_factor: float
    stream_real_time_factor: float
    workers: int
    worker_sensors: list[list[str]]
    sensor_threads: NotRequired[int]
    """Threads of each frame/scan sensor for its per-instant work."""
    render_helpers: NotRequired[dict[str, int]]
    """Render helper processes per event camera (time-parallel chains)."""
    profile: NotRequired[dict[str, Any]]
    """Per-component seconds (``--profile``)."""
    overview_s: NotRequired[float]


def versions() -> dict[str, str]:
    """roslan, Python and :data:`DEPENDENCIES` versions."""
    out = {"roslan": __version__, "python": platform.python_version()}
    for dep in DEPENDENCIES:
        try:
            out[dep] = version(dep)
        except PackageNotFoundError:
            out[dep] = "not installed"
    return out


def make_manifest(
    *,
    config: Any,
    config_path: Path | None,
    duration_s: float,
    touchdown_s: float,
    bags: Mapping[str, str],
    topics: Mapping[str, TopicEntry],
    sensors: Sequence[str],
    renderer: Mapping[str, Any] | None = None,
) -> RunManifest:
    """The run.json content of a finished run of ``config`` (a SimConfig); ``renderer``:
    the image formation record of a run with cameras (:data:`RunManifest.renderer`)."""
    start_ns = int(config.output.start_time)
    manifest: RunManifest = {
        "complete": True,
        "roslan_version": __version__,
        "config_file": str(config_path) if config_path is not None else None,
        "seed": config.seed,
        "start_time_ns": start_ns,
        "start_time_utc": _dt.datetime.fromtimestamp(start_ns / 1e9, tz=_dt.UTC).isoformat(),
        "time_offset_note": "bag stamps = start_time_ns + trajectory time; text files use "
        "seconds since the trajectory start",
        "trajectory_duration_s": duration_s,
        "touchdown_time_s": touchdown_s,
        "formats": list(bags),
        "bags": dict(bags),
        "topics": dict(topics),
        "messages_total": sum(t["messages"] for t in topics.values()),
        "sensors": list(sensors),
        "versions": versions(),
        "timing": f"{TIMING_FILE} (wall-clock figures; the only files that differ between "
        "identical runs are timing.json and PLAYBACK.md)",
        "config": config.model_dump(mode="json"),
    }
    if renderer is not None:
        manifest["renderer"] = dict(renderer)
    return manifest


def write_json(path: Path, data: Mapping[str, Any]) -> None:
    """``data`` as indented JSON (keys in insertion order) plus a final newline."""
    path.write_text(json.dumps(data, indent=2, sort_keys=False) + "\n", encoding="utf-8")


def read_manifest(folder: Path) -> RunManifest | None:
    """``folder/run.json`` if it exists, parses and says ``"complete": true``; else None
    (a folder still being written, or not a roslan run)."""
    try:
        data = json.loads((folder / RUN_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if isinstance(data, dict) and data.get("complete") is True:
        return cast("RunManifest", data)
    return None


def run_messages(info: Mapping[str, Any]) -> int | None:
    """Total bag messages of a manifest (None when the file does not say)."""
    total = info.get("messages_total")
    return total if isinstance(total, int) and not isinstance(total, bool) else None


def run_duration(info: Mapping[str, Any]) -> float | None:
    """Trajectory duration in seconds of a manifest (None when the file does not say)."""
    value = info.get("trajectory_duration_s")
    return float(value) if isinstance(value, int | float) and not isinstance(value, bool) else None
