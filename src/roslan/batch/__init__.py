"""Many simulations at once: parameter sweeps and the paper's dataset."""

from __future__ import annotations

from roslan.batch.paper import build_dataset, dataset_plan, default_sensor_suite
from roslan.batch.runner import (
    BatchReport,
    Runner,
    Sweep,
    Task,
    TaskResult,
    expand_sweep,
    iter_errors,
    latin_hypercube,
    load_sweep,
    make_tasks,
    parse_sweep,
    print_summary,
    run_tasks,
    set_dotted,
    sweep_tasks,
    validate_config,
)

__all__ = [
    "BatchReport",
    "Runner",
    "Sweep",
    "Task",
    "TaskResult",
    "build_dataset",
    "dataset_plan",
    "default_sensor_suite",
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
]
