"""The output-folder contract of one run (OUTDIR): its typed manifest (run.json,
timing.json), its atomic life cycle (lock, hidden partial folder, final rename), the
run-level files written once per run (extrinsics, README) and the readers of its files."""

from __future__ import annotations

from roslan.rundir.folder import check_outdir, clean_stale, finalize, make_temp, outdir_lock
from roslan.rundir.manifest import (
    RUN_FILE,
    TIMING_FILE,
    RunManifest,
    Timing,
    TopicEntry,
    make_manifest,
    read_manifest,
    run_duration,
    run_messages,
    write_json,
)

__all__ = [
    "RUN_FILE",
    "TIMING_FILE",
    "RunManifest",
    "Timing",
    "TopicEntry",
    "check_outdir",
    "clean_stale",
    "finalize",
    "make_manifest",
    "make_temp",
    "outdir_lock",
    "read_manifest",
    "run_duration",
    "run_messages",
    "write_json",
]
