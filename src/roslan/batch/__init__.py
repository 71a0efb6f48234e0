"""Many simulations at once: parameter sweeps and the paper's dataset.

``sweep`` (the sweep language) -> ``tasks`` (one validated config per output folder) ->
``runner`` (in this process or on Dask; resumable) -> ``report`` (``batch.json``, summary).
``paper`` plans and indexes the paper's dataset on top of them. What a finished run folder
says (``run.json``) is read through :mod:`roslan.rundir.manifest`.
"""

from __future__ import annotations

from roslan.batch.paper import (
    PAPER_SCENES,
    DatasetRun,
    build_dataset,
    dataset_plan,
    default_sensor_suite,
    write_index,
)
from roslan.batch.report import BatchReport, TaskResult, iter_errors, print_summary
from roslan.batch.runner import Runner, dry_check, run_tasks
from roslan.batch.sweep import (
    Sweep,
    check_dotted,
    expand_sweep,
    latin_hypercube,
    load_sweep,
    parse_sweep,
    set_dotted,
)
from roslan.batch.tasks import Task, config_fingerprint, make_tasks, sweep_tasks, validate_config

__all__ = [
    "PAPER_SCENES",
    "BatchReport",
    "DatasetRun",
    "Runner",
    "Sweep",
    "Task",
    "TaskResult",
    "build_dataset",
    "check_dotted",
    "config_fingerprint",
    "dataset_plan",
    "default_sensor_suite",
    "dry_check",
    "expand_sweep",
    "iter_errors",
    "latin_hypercube",
    "load_sweep",
    "make_tasks",
    "parse_sweep",
    "print_summary",
    "run_tasks",
    "set_dotted",
    "sweep_tasks",
    "validate_config",
    "write_index",
]
