"""Tasks of a batch: one validated config each, named after its output folder.

Each task is one simulation, pure given its config (seed included), writing
``OUT/<task>/`` (a ``roslan simulate`` OUTDIR). Its :func:`config_fingerprint` (of the validated
config, as ``run.json`` records it) tells whether a finished folder holds the same run.
"""

from __future__ import annotations

import copy
import hashlib
import json
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from roslan.batch.sweep import Sweep, expand_sweep
from roslan.config.base import UnitWarning, validate_model
from roslan.errors import ConfigError, RoslanError

__all__ = ["Task", "config_fingerprint", "make_tasks", "sweep_tasks", "validate_config"]


@dataclass
class Task:
    """One simulation of a batch: its folder name, the axis values and the config.

    ``config`` is the full config mapping (base + overrides); ``error`` is the validation
    message when it is invalid (then it is reported, never run).
    """

    name: str
    index: int
    overrides: dict[str, Any]
    config: dict[str, Any]
    base_dir: Path
    error: str | None = None
    fingerprint: str = ""
    config_file: Path | None = None


def config_fingerprint(config: Any) -> str:
    """Short hash of a config mapping (key order does not matter)."""
    text = json.dumps(config, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def validate_config(config: Mapping[str, Any], base_dir: Path, source: str) -> Any:
    """Validate one generated config as ``roslan simulate`` would (SimConfig and the
    trajectory's own checks); ConfigError/RoslanError on failure."""
    from roslan.config.sim import SimConfig
    from roslan.trajectory.spline import make_trajectory

    cfg = validate_model(SimConfig, dict(config), source, context={"base_dir": base_dir})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        make_trajectory(cfg.trajectory, base_dir=base_dir, warn=False)
    return cfg


def make_tasks(
    configs: Sequence[Mapping[str, Any]],
    base_dir: Path,
    *,
    names: Sequence[str] | None = None,
    overrides: Sequence[dict[str, Any]] | None = None,
    source: str = "<sweep>",
    config_file: Path | None = None,
) -> list[Task]:
    """Validate every config up front; invalid ones carry their message in ``error``.

    ``config_file`` (optional) is handed to the simulation as the file the config came
    from (relative paths inside resolve against its folder, which must be ``base_dir``)."""
    tasks = []
    slips: dict[str, list[str]] = {}  # probable unit slips -> the tasks that have them
    for i, config in enumerate(configs):
        name = names[i] if names is not None else f"{i:04d}"
        task = Task(
            name=name,
            index=i,
            overrides=dict(overrides[i]) if overrides is not None else {},
            config=copy.deepcopy(dict(config)),
            base_dir=Path(base_dir).resolve(),
            config_file=config_file,
        )
        where = f"{source}: task {name}"
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", UnitWarning)
                cfg = validate_config(config, task.base_dir, where)
            for w in caught:
                text = str(w.message).removeprefix(f"{where}: ")
                slips.setdefault(text, []).append(name)
            task.fingerprint = config_fingerprint(cfg.model_dump(mode="json"))
        except RoslanError as err:
            task.error = str(err)
        tasks.append(task)
    for text, names_ in slips.items():  # one line per slip, not one per task
        which = f"task {names_[0]}" if len(names_) == 1 else f"{len(names_)} tasks"
        warnings.warn(f"{source} ({which}): {text}", UnitWarning, stacklevel=2)
    if len({t.name for t in tasks}) != len(tasks):
        msg = f"{source}: task folder names are not unique"
        raise ConfigError(msg)
    return tasks


def sweep_tasks(sweep: Sweep) -> list[Task]:
    """The tasks of a parsed sweep, named by its folder-name template."""
    names = [sweep.name.format(index=i) for i in range(len(sweep.points))]
    return make_tasks(
        expand_sweep(sweep),
        sweep.base_dir,
        names=names,
        overrides=sweep.points,
        source=sweep.source,
        config_file=sweep.config_file,
    )
