"""Parameter sweeps: many simulations from one base config, run on a Dask cluster.

A sweep file (YAML) holds a base config and a list of axis blocks::

    base: landing.yaml            # a SimConfig file (relative to the sweep file) or inline
    axes:                         # blocks combine as a cartesian product, in this order
      - grid:                     # cartesian product of its keys
          scene: [warehouse, refinery]
          trajectory.kappa.x: {start: 0.3, stop: 0.9, num: 4}   # inclusive linspace
      - zip:                      # zipped: equal-length lists, element i together
          trajectory.approach.speed: [3.0, 4.0, 5.0]
          seed: [1, 2, 3]
      - sample:                   # n samples (Latin hypercube or plain uniform)
          n: 8
          method: lhs             # lhs | random
          seed: 0
          ranges:
            trajectory.kappa.y: [0.3, 0.9]       # float in [lo, hi)
            seed: [0, 1000]                      # two ints: integer in [lo, hi]
            sensors.imu.rate: {low: 100, high: 1000, log: true}
            scene: {choices: [warehouse, refinery]}

Keys are dotted paths into the config (``trajectory.kappa.x``); a sensor is picked by
its ``name`` or list index (``sensors.imu.rate``, ``sensors.0.rate``); an integer part
indexes a list given in the base (``trajectory.initial.position.2``). Every path is
checked against the config schema when the sweep is loaded, and every generated config
is validated before anything runs: an invalid one is reported for its task only.

Each task is one :func:`roslan.simulate.run_simulation` call, pure given its config
(seed included), writing ``OUT/<task>/`` (a ``roslan simulate`` OUTDIR). A task whose
``run.json`` says complete (same config) is skipped, so a batch can be resumed.
"""

from __future__ import annotations

import contextlib
import copy
import hashlib
import itertools
import json
import logging
import math
import os
import shutil
import time
import traceback
import types
import typing
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel

from roslan.config.base import load_yaml, validate_model
from roslan.errors import ConfigError, RoslanError

__all__ = [
    "BatchReport",
    "Runner",
    "Sweep",
    "Task",
    "TaskResult",
    "expand_sweep",
    "load_sweep",
    "make_tasks",
    "parse_sweep",
    "run_tasks",
    "set_dotted",
]

Runner = Callable[[Any, Path, bool, "Path | None"], Mapping[str, Any]]
"""``runner(config: SimConfig, outdir, overwrite, config_path) -> run.json dict``; the
default calls :func:`roslan.simulate.run_simulation` with ``quiet=True``."""

_AXIS_KINDS = ("grid", "zip", "sample")
_SAMPLE_KEYS = ("n", "method", "seed", "ranges")
_SWEEP_KEYS = ("base", "axes", "name")


# --------------------------------------------------------------------------- sweep model
@dataclass(frozen=True)
class Sweep:
    """A parsed sweep file.

    Attributes:
        base: the base config mapping (not validated on its own: axes may complete it).
        base_dir: folder relative paths inside configs resolve against.
        points: one mapping ``dotted key -> value`` per task, in task order.
        source: the sweep file (for messages) or ``<sweep>``.
        name: folder-name template, formatted with ``index``.
        config_file: the file the base config came from (the base file, else the sweep
            file; recorded in run.json and used for relative paths), None if inline.
    """

    base: dict[str, Any]
    base_dir: Path
    points: list[dict[str, Any]]
    source: str = "<sweep>"
    name: str = "{index:04d}"
    config_file: Path | None = None


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


# --------------------------------------------------------------------------- dotted paths
def _split(path: str) -> list[str | int]:
    parts: list[str | int] = []
    for p in path.split("."):
        if p == "":
            msg = f"key {path!r}: empty part in the dotted path"
            raise ValueError(msg)
        parts.append(int(p) if p.lstrip("-").isdigit() else p)
    return parts


def _model_in(annotation: Any) -> type[BaseModel] | None:
    """The pydantic model inside an annotation (``Model``, ``Model | None``), else None."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    origin = typing.get_origin(annotation)
    if origin in (typing.Union, types.UnionType):
        models = [m for a in typing.get_args(annotation) if (m := _model_in(a)) is not None]
        return models[0] if len(models) == 1 else None
    if origin is typing.Annotated:
        return _model_in(typing.get_args(annotation)[0])
    return None


def _sensor_index(sensors: Any, part: str | int, path: str) -> int:
    if not isinstance(sensors, list):
        msg = f"key {path!r}: the base config has no 'sensors' list to index into"
        raise ValueError(msg)
    names = [s.get("name") if isinstance(s, Mapping) else None for s in sensors]
    if isinstance(part, int):
        if not 0 <= part < len(sensors):
            msg = f"key {path!r}: sensor index {part} out of range; the base has {len(sensors)}"
            raise ValueError(msg)
        return part
    if part not in names:
        allowed = ", ".join(repr(n) for n in names if n) or "none"
        msg = f"key {path!r}: no sensor named {part!r} in the base config; allowed: {allowed}"
        raise ValueError(msg)
    return names.index(part)


def check_dotted(path: str, base: Mapping[str, Any]) -> None:
    """Raise ValueError (naming the bad part and the allowed keys) unless ``path`` names a
    config key of :class:`~roslan.config.sim.SimConfig` reachable from ``base``."""
    from roslan.config.sim import SimConfig
    from roslan.sensors.registry import config_class

    parts = _split(path)
    model: type[BaseModel] | None = SimConfig
    data: Any = base
    walked: list[str] = []
    i = 0
    while i < len(parts):
        part = parts[i]
        where = ".".join(walked) or "the config root"
        if model is not None:
            fields = model.model_fields
            if not isinstance(part, str) or part not in fields:
                allowed = ", ".join(fields)
                msg = f"key {path!r}: {part!r} is not a key of {where}; allowed: {allowed}"
                raise ValueError(msg)
            walked.append(part)
            data = data.get(part) if isinstance(data, Mapping) else None
            if model is SimConfig and part == "sensors" and i + 1 < len(parts):
                idx = _sensor_index(data, parts[i + 1], path)
                sensor = data[idx]
                try:
                    model = config_class(str(sensor.get("type")))
                except ValueError as err:
                    msg = f"key {path!r}: sensors[{idx}]: {err}"
                    raise ValueError(msg) from None
                data = sensor
                walked.append(str(parts[i + 1]))
                i += 2
                continue
            model = _model_in(fields[part].annotation)
        else:
            # Below the schema: only list indices into values present in the base.
            if not isinstance(part, int):
                msg = (
                    f"key {path!r}: {where} is a value, not a mapping; "
                    f"{part!r} cannot be set inside it"
                )
                raise ValueError(msg)
            if not isinstance(data, list) or not -len(data) <= part < len(data):
                msg = (
                    f"key {path!r}: index {part} needs {where} given as a list in the base "
                    "config, long enough"
                )
                raise ValueError(msg)
            walked.append(str(part))
            data = data[part]
        i += 1


def set_dotted(config: dict[str, Any], path: str, value: Any) -> None:
    """Set ``config[a][b]... = value`` for ``path = 'a.b...'`` in place, creating missing
    mappings; sensors are addressed by name or index, other lists by index."""
    parts = _split(path)
    node: Any = config
    for j, part in enumerate(parts[:-1]):
        if j == 1 and parts[0] == "sensors" and isinstance(node, list):
            node = node[_sensor_index(node, part, path)]
            continue
        if isinstance(node, list) and isinstance(part, int):
            node = node[part]
            continue
        nxt = node.get(part)
        if nxt is None:
            nxt = {}
            node[part] = nxt
        elif isinstance(nxt, tuple):
            nxt = list(nxt)
            node[part] = nxt
        node = nxt
    last = parts[-1]
    if isinstance(node, list):
        idx = _sensor_index(node, last, path) if parts[0] == "sensors" and len(parts) == 2 else last
        node[int(idx)] = value
    else:
        node[last] = value


# --------------------------------------------------------------------------- sweep parsing
MAX_TASKS = 100_000
"""Most tasks one sweep may expand to."""
MAX_NAME_BYTES = 200
"""Longest task folder name (bytes): room for the hidden ``.NAME.partial-XXXXXXXX`` sibling
within the 255-byte file-name limit of common file systems."""


def _err(source: str, where: str, value: Any, allowed: str) -> ConfigError:
    from roslan.config.base import _short

    shown = _short(value)
    if len(shown) > 80:
        shown = shown[:77] + "..."
    return ConfigError(f"{source}: {where} = {shown}: {allowed}")


def _number(v: Any) -> bool:
    if not isinstance(v, int | float) or isinstance(v, bool):
        return False
    try:
        return math.isfinite(float(v))
    except OverflowError:  # an integer beyond the float range
        return False


def _plain(v: Any) -> Any:
    """numpy scalars -> Python scalars (for YAML/JSON and pydantic)."""
    if isinstance(v, np.generic):
        return v.item()
    return v


def _grid_values(source: str, where: str, spec: Any) -> list[Any]:
    if isinstance(spec, list):
        if not spec:
            raise _err(source, where, spec, "a non-empty list of values")
        return spec
    if isinstance(spec, Mapping):
        if set(spec) != {"start", "stop", "num"}:
            raise _err(source, where, spec, "a list, or {start, stop, num} (inclusive linspace)")
        start, stop, num = spec["start"], spec["stop"], spec["num"]
        if not (_number(start) and _number(stop)):
            raise _err(source, f"{where}.start/stop", (start, stop), "finite numbers")
        if not isinstance(num, int) or isinstance(num, bool) or not 1 <= num <= MAX_TASKS:
            raise _err(source, f"{where}.num", num, f"an integer in [1, {MAX_TASKS}]")
        return [float(v) for v in np.linspace(float(start), float(stop), num)]
    raise _err(source, where, spec, "a list of values, or {start, stop, num}")


@dataclass(frozen=True)
class _Range:
    low: float = 0.0
    high: float = 1.0
    integer: bool = False
    log: bool = False
    choices: tuple[Any, ...] | None = None

    def map(self, u: np.ndarray) -> list[Any]:
        """Map uniforms ``u`` in [0, 1) onto the range (stratification preserved)."""
        if self.choices is not None:
            idx = np.minimum((u * len(self.choices)).astype(np.int64), len(self.choices) - 1)
            return [self.choices[i] for i in idx]
        if self.integer:
            lo, hi = int(self.low), int(self.high)
            v = np.minimum(lo + np.floor(u * (hi - lo + 1)), hi).astype(np.int64)
            return [int(x) for x in v]
        if self.log:
            v = np.exp(np.log(self.low) + u * (np.log(self.high) - np.log(self.low)))
        else:
            v = self.low + u * (self.high - self.low)
        return [float(x) for x in v]


def _range(source: str, where: str, spec: Any) -> _Range:
    if isinstance(spec, Mapping) and "choices" in spec:
        ch = spec["choices"]
        if set(spec) != {"choices"} or not isinstance(ch, list) or not ch:
            raise _err(source, where, spec, "{choices: [a non-empty list]}")
        return _Range(choices=tuple(ch))
    if isinstance(spec, list) and len(spec) == 2:
        lo, hi = spec
        integer = all(isinstance(v, int) and not isinstance(v, bool) for v in spec)
        log = False
    elif isinstance(spec, Mapping) and {"low", "high"} <= set(spec):
        extra = set(spec) - {"low", "high", "log", "integer"}
        if extra:
            raise _err(source, where, spec, "keys low, high, log, integer only")
        lo, hi = spec["low"], spec["high"]
        for flag in ("log", "integer"):
            if not isinstance(spec.get(flag, False), bool):
                raise _err(source, f"{where}.{flag}", spec[flag], "true or false")
        log = bool(spec.get("log", False))
        integer = bool(spec.get("integer", False))
    else:
        raise _err(
            source,
            where,
            spec,
            "[low, high] (two ints: integers, inclusive), {low, high, log, integer} "
            "or {choices: [...]}",
        )
    if not (_number(lo) and _number(hi)) or not lo < hi:
        raise _err(source, where, spec, "finite numbers with low < high")
    if log and lo <= 0:
        raise _err(source, where, spec, "log ranges need low > 0")
    if integer and not (lo >= -(2**63) and hi <= 2**63 - 1):
        raise _err(source, where, spec, "integer ranges must lie within [-2**63, 2**63 - 1]")
    return _Range(low=float(lo), high=float(hi), integer=integer, log=log)


def _sample_points(source: str, where: str, spec: Any) -> list[dict[str, Any]]:
    if not isinstance(spec, Mapping):
        raise _err(source, where, spec, "a mapping with n, method, seed, ranges")
    extra = [k for k in spec if k not in _SAMPLE_KEYS]
    if extra:
        raise _err(
            source,
            f"{where}.{extra[0]}",
            spec[extra[0]],
            f"allowed keys: {', '.join(_SAMPLE_KEYS)}",
        )
    n = spec.get("n")
    if not isinstance(n, int) or isinstance(n, bool) or not 1 <= n <= MAX_TASKS:
        raise _err(source, f"{where}.n", n, f"an integer in [1, {MAX_TASKS}] (number of samples)")
    method = spec.get("method", "lhs")
    if method not in ("lhs", "random"):
        raise _err(source, f"{where}.method", method, "allowed: lhs, random")
    seed = spec.get("seed", 0)
    if not isinstance(seed, int) or isinstance(seed, bool) or not 0 <= seed <= 2**63 - 1:
        raise _err(source, f"{where}.seed", seed, "an integer in [0, 2**63 - 1]")
    ranges = spec.get("ranges")
    if not isinstance(ranges, Mapping) or not ranges:
        raise _err(source, f"{where}.ranges", ranges, "a non-empty mapping: key -> range")
    keys = list(ranges)
    parsed = [_range(source, f"{where}.ranges.{k}", ranges[k]) for k in keys]
    u = latin_hypercube(n, len(keys), seed) if method == "lhs" else _uniform(n, len(keys), seed)
    cols = [r.map(u[:, j]) for j, r in enumerate(parsed)]
    return [{k: cols[j][i] for j, k in enumerate(keys)} for i in range(n)]


def latin_hypercube(n: int, d: int, seed: int) -> np.ndarray:
    """(n, d) Latin-hypercube sample in [0, 1): one point in each of the n strata per axis."""
    from scipy.stats import qmc

    return np.asarray(qmc.LatinHypercube(d=d, rng=np.random.default_rng(seed)).random(n))


def _uniform(n: int, d: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).random((n, d))


def _axis_points(source: str, i: int, block: Any) -> list[dict[str, Any]]:
    where = f"axes[{i}]"
    if not isinstance(block, Mapping) or len(block) != 1 or next(iter(block)) not in _AXIS_KINDS:
        raise _err(
            source, where, block, f"one mapping with exactly one of: {', '.join(_AXIS_KINDS)}"
        )
    kind, spec = next(iter(block.items()))
    where = f"{where}.{kind}"
    if kind == "sample":
        return _sample_points(source, where, spec)
    if not isinstance(spec, Mapping) or not spec:
        raise _err(source, where, spec, "a non-empty mapping: dotted key -> values")
    values = {k: _grid_values(source, f"{where}.{k}", v) for k, v in spec.items()}
    keys = list(values)
    if kind == "grid" and math.prod(len(v) for v in values.values()) > MAX_TASKS:
        size = math.prod(len(v) for v in values.values())
        raise _err(source, where, f"{size} points", f"a sweep has at most {MAX_TASKS} tasks")
    if kind == "grid":
        return [
            dict(zip(keys, combo, strict=True)) for combo in itertools.product(*values.values())
        ]
    lengths = {k: len(v) for k, v in values.items()}
    if len(set(lengths.values())) != 1:
        shown = ", ".join(f"{k} has {n}" for k, n in lengths.items())
        raise _err(source, where, lengths, f"zipped lists must have equal lengths ({shown})")
    return [dict(zip(keys, combo, strict=True)) for combo in zip(*values.values(), strict=True)]


def parse_sweep(
    data: Any,
    source: str = "<sweep>",
    base_dir: Path | None = None,
    sweep_file: Path | None = None,
) -> Sweep:
    """Validate a sweep mapping and expand its axes (see the module docstring)."""
    base_dir = (base_dir or Path.cwd()).resolve()
    config_file = sweep_file.resolve() if sweep_file is not None else None
    if not isinstance(data, Mapping):
        raise _err(source, "<root>", type(data).__name__, "a mapping with keys base, axes, name")
    extra = [k for k in data if k not in _SWEEP_KEYS]
    if extra:
        raise _err(
            source, str(extra[0]), data[extra[0]], f"unknown key; allowed: {', '.join(_SWEEP_KEYS)}"
        )
    raw_base = data.get("base")
    cfg_dir = base_dir
    if raw_base is None:
        base: dict[str, Any] = {}
    elif isinstance(raw_base, str):
        path = Path(raw_base)
        if not path.is_absolute():
            path = base_dir / path
        loaded = load_yaml(path)
        if loaded is not None and not isinstance(loaded, Mapping):
            raise _err(source, "base", raw_base, "a config file holding a mapping")
        base = copy.deepcopy(dict(loaded or {}))
        cfg_dir = path.parent.resolve()
        config_file = path.resolve()
    elif isinstance(raw_base, Mapping):
        base = copy.deepcopy(dict(raw_base))
    else:
        raise _err(source, "base", raw_base, "a config mapping or the path of a config file")
    name = data.get("name", "{index:04d}")
    if not isinstance(name, str):
        raise _err(source, "name", name, "a folder-name template such as '{index:04d}'")
    _check_name_template(source, name, 1)
    axes = data.get("axes", [])
    if not isinstance(axes, list):
        raise _err(source, "axes", axes, "a list of axis blocks (grid, zip or sample)")
    blocks = [_axis_points(source, i, b) for i, b in enumerate(axes)]
    n_tasks = math.prod(len(b) for b in blocks)
    if n_tasks > MAX_TASKS:
        raise _err(source, "axes", f"{n_tasks} tasks", f"a sweep has at most {MAX_TASKS} tasks")
    _check_name_template(source, name, n_tasks)
    seen: dict[str, int] = {}
    for i, pts in enumerate(blocks):
        for key in pts[0] if pts else {}:
            if key in seen:
                raise _err(source, f"axes[{i}]", key, f"key already varied by axes[{seen[key]}]")
            seen[key] = i
            try:
                check_dotted(key, base)
            except ValueError as err:
                raise ConfigError(f"{source}: axes[{i}]: {err}") from None
    points = [
        {k: _plain(v) for d in combo for k, v in d.items()} for combo in itertools.product(*blocks)
    ]
    return Sweep(
        base=base,
        base_dir=cfg_dir,
        points=points,
        source=source,
        name=name,
        config_file=config_file,
    )


def _check_name_template(source: str, name: str, n_tasks: int) -> None:
    """Format ``name`` for the first and last index (as the run will) and check the result is
    a plain folder name that fits the file system; ConfigError naming ``name`` otherwise."""
    import string

    try:
        fields = list(string.Formatter().parse(name))
    except ValueError as err:
        raise _err(source, "name", name, f"a template using only {{index}} ({err})") from None
    for _, key, spec, _ in fields:
        width = "".join(ch for ch in (spec or "") if ch.isdigit()).lstrip("0")
        if key is not None and len(width) > 3:
            raise _err(source, "name", name, "a format width of at most 3 digits")
    for index in {0, max(n_tasks - 1, 0)}:
        try:
            folder = name.format(index=index)
        except (KeyError, IndexError, ValueError, AttributeError, TypeError) as err:
            raise _err(source, "name", name, f"a template using only {{index}} ({err})") from None
        if not folder or "/" in folder or "\0" in folder or folder in (".", ".."):
            raise _err(source, "name", name, "a plain folder name template")
        if len(folder.encode("utf-8", "surrogateescape")) > MAX_NAME_BYTES:
            raise _err(
                source,
                "name",
                name,
                f"folder names of at most {MAX_NAME_BYTES} bytes (index {index} gives "
                f"{len(folder.encode('utf-8', 'surrogateescape'))})",
            )


def load_sweep(path: str | Path) -> Sweep:
    """Read and validate a sweep YAML file; relative paths resolve against its folder."""
    p = Path(path)
    return parse_sweep(load_yaml(p), str(p), p.parent, p)


def expand_sweep(sweep: Sweep) -> list[dict[str, Any]]:
    """The full config mapping of every point (base + overrides), in task order."""
    out = []
    for point in sweep.points:
        cfg = copy.deepcopy(sweep.base)
        for key, value in point.items():
            set_dotted(cfg, key, copy.deepcopy(value))
        out.append(cfg)
    return out


# --------------------------------------------------------------------------- tasks
def _fingerprint(config: Any) -> str:
    text = json.dumps(config, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def validate_config(config: Mapping[str, Any], base_dir: Path, source: str) -> Any:
    """Validate one generated config as ``roslan simulate`` would (SimConfig and the
    trajectory's own checks); ConfigError/RoslanError on failure."""
    import warnings

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
        try:
            cfg = validate_config(config, task.base_dir, f"{source}: task {name}")
            task.fingerprint = _fingerprint(cfg.model_dump(mode="json"))
        except RoslanError as err:
            task.error = str(err)
        tasks.append(task)
    if len({t.name for t in tasks}) != len(tasks):
        msg = f"{source}: task folder names are not unique"
        raise ConfigError(msg)
    return tasks


def sweep_tasks(sweep: Sweep) -> list[Task]:
    names = [sweep.name.format(index=i) for i in range(len(sweep.points))]
    return make_tasks(
        expand_sweep(sweep),
        sweep.base_dir,
        names=names,
        overrides=sweep.points,
        source=sweep.source,
        config_file=sweep.config_file,
    )


# --------------------------------------------------------------------------- execution
def read_run_json(folder: Path) -> dict[str, Any] | None:
    """``folder/run.json`` if it exists, parses and says ``"complete": true``; else None."""
    try:
        data = json.loads((folder / "run.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if isinstance(data, dict) and data.get("complete") is True:
        return data
    return None


def _default_runner(
    config: Any, outdir: Path, overwrite: bool, config_path: Path | None
) -> Mapping[str, Any]:
    from roslan.simulate import run_simulation

    info: Mapping[str, Any] = run_simulation(
        config, outdir, overwrite=overwrite, quiet=True, config_path=config_path
    )
    return info


def _messages(info: Mapping[str, Any]) -> int | None:
    """Total bag messages recorded in run.json (``messages_total`` or the per-topic sum)."""
    total = info.get("messages_total")
    if isinstance(total, int) and not isinstance(total, bool):
        return total
    topics = info.get("topics")
    if isinstance(topics, Mapping):
        counts = [v.get("messages") for v in topics.values() if isinstance(v, Mapping)]
        return sum(c for c in counts if isinstance(c, int))
    return None


def _duration(info: Mapping[str, Any]) -> float | None:
    for key in ("duration", "duration_s", "trajectory_duration", "trajectory_duration_s"):
        v = info.get(key)
        if isinstance(v, int | float) and not isinstance(v, bool):
            return float(v)
    traj = info.get("trajectory")
    if isinstance(traj, Mapping):
        return _duration(traj)
    return None


def _execute(
    config: dict[str, Any],
    base_dir: str,
    outdir: str,
    overwrite: bool,
    runner: Runner | None,
    config_file: str | None = None,
) -> dict[str, Any]:
    """The Dask task: validate, simulate, summarize. Deterministic user errors
    (RoslanError) are returned, not raised, so they are not retried; anything else
    (worker trouble, OSError...) raises and Dask retries it."""
    from roslan.config.sim import SimConfig

    t0 = time.perf_counter()
    marker = _attempts_file(Path(outdir))
    with contextlib.suppress(OSError), marker.open("a", encoding="utf-8") as fh:
        fh.write(f"{os.getpid()}\n")  # one line per attempt, read back by the driver
    try:
        cfg = validate_model(SimConfig, config, "<task>", context={"base_dir": Path(base_dir)})
        cfg_path = Path(config_file) if config_file else None
        info = (runner or _default_runner)(cfg, Path(outdir), overwrite, cfg_path)
    except RoslanError as err:
        return {"status": "failed", "error": f"{type(err).__name__}: {err}"}
    return {
        "status": "complete",
        "wall_s": time.perf_counter() - t0,
        "duration_s": _duration(info),
        "messages": _messages(info),
    }


def _attempts_file(outdir: Path) -> Path:
    return outdir.parent / f".{outdir.name}.attempts"


def _settle(outdir: Path) -> int:
    """Attempts recorded for the task writing ``outdir`` (0 if none); removes the record and
    the partial folders of failed attempts (only when no live run holds OUTDIR's lock)."""
    from roslan.errors import OutputError
    from roslan.pipeline.outdir import clean_stale, outdir_lock

    marker = _attempts_file(outdir)
    try:
        n = len(marker.read_text(encoding="utf-8").splitlines())
        marker.unlink()
    except OSError:
        n = 0
    with contextlib.suppress(OutputError), outdir_lock(outdir):
        clean_stale(outdir)
    return n


def _write_json_atomic(path: Path, data: Any) -> None:
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    tmp.write_text(json.dumps(data, indent=2, default=str) + "\n", encoding="utf-8")
    tmp.replace(path)


def _existing_matches(task: Task, info: Mapping[str, Any]) -> bool:
    """True unless run.json's recorded config (the pipeline's ``model_dump(mode="json")``
    of the validated config, as our fingerprint) differs from the task's."""
    recorded = info.get("config")
    if not isinstance(recorded, Mapping):
        return True
    return _fingerprint(recorded) == task.fingerprint


def _cluster(workers: int | None, scheduler: str | None) -> tuple[Any, Any, int | str]:
    import distributed

    dist: Any = distributed  # untyped constructors: keep mypy strict elsewhere
    Client, LocalCluster = dist.Client, dist.LocalCluster
    if scheduler:
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError) as err:
            msg = f"--scheduler {scheduler}: cannot connect to a Dask scheduler there ({err})"
            raise ConfigError(msg) from None
        return client, None, scheduler
    n = workers if workers is not None else (os.cpu_count() or 1)
    cluster = LocalCluster(
        n_workers=n,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
        silence_logs=logging.CRITICAL,  # task errors are reported per task
    )
    return Client(cluster), cluster, n


def run_tasks(
    tasks: Sequence[Task],
    outdir: str | Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    retries: int = 2,
    overwrite: bool = False,
    runner: Runner | None = None,
    progress: bool = True,
    meta: Mapping[str, Any] | None = None,
) -> BatchReport:
    """Run every valid task once (skipping completed ones), write ``outdir/batch.json``.

    Args:
        workers: local worker processes (one thread each, loopback only); ``0`` runs the
            tasks in this process, one after the other (no Dask).
        scheduler: address of an existing Dask scheduler (``tcp://host:8786``); ``outdir``
            must then be on a file system the workers share.
        retries: extra attempts for a task that raised something other than a roslan
            error (those are deterministic: a task is pure given its config).
        overwrite: rerun tasks even when a complete ``run.json`` exists.
        runner: replaces :func:`roslan.simulate.run_simulation` (tests, custom pipelines).
    """
    out = Path(outdir).resolve()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        msg = f"-o {outdir}: cannot create the output folder: {err}"
        raise ConfigError(msg) from None
    if retries < 0:
        msg = f"--retries = {retries}: must be >= 0"
        raise ConfigError(msg)
    t0 = time.perf_counter()
    results: dict[str, TaskResult] = {}
    todo: list[tuple[Task, bool]] = []
    for task in tasks:
        res = TaskResult(task.name, task.index, "pending", overrides=task.overrides)
        results[task.name] = res
        if task.error is not None:
            res.status, res.error = "invalid", task.error
            continue
        folder = out / task.name
        info = read_run_json(folder)
        if info is not None and not overwrite:
            if _existing_matches(task, info):
                res.status = "skipped"
                res.duration_s, res.messages = _duration(info), _messages(info)
                continue
            res.status = "failed"
            res.error = (
                f"{folder} holds a complete run of a different config; "
                "pass --overwrite to replace it"
            )
            continue
        # A folder without a complete run.json is debris of an interrupted run: replace it.
        todo.append((task, overwrite or folder.exists()))
        # So is a hidden partial folder of a killed simulation (SIGKILL skips its cleanup).
        for debris in out.glob(f".{task.name}.partial-*"):
            shutil.rmtree(debris, ignore_errors=True)

    state = {"last": 0.0}

    def save(final: bool = False) -> None:
        now = time.perf_counter()
        if not final and now - state["last"] < 1.0:
            return
        state["last"] = now
        ordered = sorted(results.values(), key=lambda r: r.index)
        counts: dict[str, int] = {}
        for r in ordered:
            counts[r.status] = counts.get(r.status, 0) + 1
        _write_json_atomic(
            out / "batch.json",
            {
                **dict(meta or {}),
                "finished": final,
                "wall_s": round(now - t0, 3),
                "counts": counts,
                "tasks": [r.as_json() for r in ordered],
            },
        )

    save(final=False)

    def record(task: Task, outcome: Mapping[str, Any] | BaseException, attempts: int) -> None:
        res = results[task.name]
        res.attempts = max(attempts, _settle(out / task.name))
        if isinstance(outcome, BaseException):
            res.status = "failed"
            detail = "".join(traceback.format_exception_only(type(outcome), outcome)).strip()
            res.error = detail or type(outcome).__name__
        else:
            res.status = str(outcome["status"])
            res.error = outcome.get("error")
            res.wall_s = outcome.get("wall_s")
            res.duration_s = outcome.get("duration_s")
            res.messages = outcome.get("messages")
        save()

    n_workers: int | str = 0
    with _progress(progress, len(todo)) as advance:
        if todo and workers == 0 and not scheduler:
            for task, ow in todo:
                outcome: Mapping[str, Any] | BaseException = RuntimeError("not run")
                attempts = 0
                while attempts <= retries:
                    attempts += 1
                    try:
                        outcome = _execute(
                            task.config,
                            str(task.base_dir),
                            str(out / task.name),
                            ow,
                            runner,
                            str(task.config_file) if task.config_file else None,
                        )
                        break
                    except Exception as err:
                        outcome = err
                record(task, outcome, attempts)
                advance(task.name)
        elif todo:
            n_workers = _run_dask(todo, out, workers, scheduler, retries, runner, record, advance)
    save(final=True)
    report = BatchReport(
        out, sorted(results.values(), key=lambda r: r.index), time.perf_counter() - t0, n_workers
    )
    return report


def _run_dask(
    todo: Sequence[tuple[Task, bool]],
    out: Path,
    workers: int | None,
    scheduler: str | None,
    retries: int,
    runner: Runner | None,
    record: Callable[[Task, Mapping[str, Any] | BaseException, int], None],
    advance: Callable[[str], None],
) -> int | str:
    import dask

    if workers is not None and workers < 1:
        msg = f"--workers = {workers}: must be >= 1 (or 0 to run in this process)"
        raise ConfigError(msg)

    with dask.config.set(LOCAL_CLUSTER_CONFIG):
        # held for the cluster's lifetime: the nanny reads it again when it restarts a
        # worker that died
        return _run_on_cluster(todo, out, workers, scheduler, retries, runner, record, advance)


LOCAL_CLUSTER_CONFIG: dict[str, Any] = {
    # A simulation can starve its worker's event loop for minutes on a loaded machine
    # (GIL-holding rendering); the nanny already reports real process deaths, so the
    # scheduler must not also expel "silent" workers and rerun their tasks.
    "distributed.scheduler.worker-ttl": None,
    # A simulation may start helper processes, which daemonic workers cannot.
    "distributed.worker.daemon": False,
}


def _run_on_cluster(
    todo: Sequence[tuple[Task, bool]],
    out: Path,
    workers: int | None,
    scheduler: str | None,
    retries: int,
    runner: Runner | None,
    record: Callable[[Task, Mapping[str, Any] | BaseException, int], None],
    advance: Callable[[str], None],
) -> int | str:
    import distributed

    as_completed: Any = distributed.as_completed
    client, cluster, n = _cluster(min(workers or (os.cpu_count() or 1), len(todo)), scheduler)
    try:
        futures = {}
        for task, ow in todo:
            fut = client.submit(
                _execute,
                task.config,
                str(task.base_dir),
                str(out / task.name),
                ow,
                runner,
                str(task.config_file) if task.config_file else None,
                key=f"roslan-sim-{task.name}-{task.fingerprint}",
                retries=retries,
                pure=False,
            )
            futures[fut] = task
        for fut in as_completed(list(futures)):
            task = futures[fut]
            try:
                outcome: Mapping[str, Any] | BaseException = fut.result()
            except Exception as err:
                outcome = err
            record(task, outcome, 1)
            advance(task.name)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return n


class _progress:
    """A rich progress bar over tasks (or nothing when disabled)."""

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
    import sys

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
