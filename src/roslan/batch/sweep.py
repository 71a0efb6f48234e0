"""The sweep language: a base config plus axes of values, expanded into one config per task.

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
is validated before anything runs (:mod:`roslan.batch.tasks`): an invalid one is
reported for its task only.
"""

from __future__ import annotations

import copy
import itertools
import math
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel

from roslan.config.base import load_yaml
from roslan.errors import ConfigError

__all__ = [
    "MAX_NAME_BYTES",
    "MAX_TASKS",
    "Sweep",
    "check_dotted",
    "expand_sweep",
    "latin_hypercube",
    "load_sweep",
    "parse_sweep",
    "set_dotted",
]

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
    from roslan.config.base import short_repr

    shown = short_repr(value)
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
