"""Shared pieces of every config model and the YAML loader.

Models are strict: unknown keys are rejected, numbers must be finite. Errors
are turned into one :class:`~roslan.errors.ConfigError` whose message lists,
for every problem, ``file: key.path = value: what is allowed``.
"""

from __future__ import annotations

import difflib
import math
import re
import reprlib
import types
import typing
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal, TypeVar, Union, get_args, get_origin

import numpy as np
from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    model_validator,
)

from roslan.config.units import RADIANS, unit_slips
from roslan.errors import ConfigError

__all__ = [
    "Angle",
    "Angles3",
    "FiniteFloat",
    "ModelFor",
    "Pose",
    "StrictModel",
    "UnitWarning",
    "Vec3",
    "allowed_keys",
    "allowed_range",
    "did_you_mean",
    "format_validation_error",
    "load_yaml",
    "load_yaml_model",
    "numeric_bounds",
    "short_repr",
    "validate_model",
]

M = TypeVar("M", bound=BaseModel)


def _finite(v: float) -> float:
    if not math.isfinite(v):
        msg = "must be a finite number (not NaN or inf)"
        raise ValueError(msg)
    return v


FiniteFloat = Annotated[float, AfterValidator(_finite)]
"""A float that is neither NaN nor infinite."""

MAX_COORD = 1e6
"""Largest absolute value of a Vec3 component (a position in metres: 1000 km)."""
Coord = Annotated[FiniteFloat, Field(ge=-MAX_COORD, le=MAX_COORD)]
Vec3 = tuple[Coord, Coord, Coord]
"""Three finite floats within +-1e6, e.g. a position in metres or roll/pitch/yaw in radians."""
Angles3 = Annotated[Vec3, RADIANS]
"""Three angles in radians (roll, pitch, yaw): beyond +-2 pi is warned as a unit slip."""
Angle = Annotated[FiniteFloat, RADIANS]
"""An angle in radians: beyond +-2 pi is warned as a unit slip."""


def _leaves(ann: Any) -> list[Any]:
    """The plain types an annotation accepts (Annotated, Optional and unions unwrapped)."""
    origin = get_origin(ann)
    if origin is Annotated:
        return _leaves(get_args(ann)[0])
    if origin is Union or origin is types.UnionType:
        return [leaf for a in get_args(ann) for leaf in _leaves(a)]
    return [ann]


def _wrong_scalar(ann: Any, value: Any) -> str | None:
    """Why ``value`` must not be coerced to ``ann`` (true/false or text for a number), or None."""
    leaves = [a for a in _leaves(ann) if a is not type(None)]
    if any(a is Any for a in leaves):
        return None
    if isinstance(value, bool):
        for a in leaves:
            if a is bool or (
                get_origin(a) is Literal and any(isinstance(x, bool) for x in get_args(a))
            ):
                return None
        if any(a in (int, float) for a in leaves):
            return "must be a number, not true/false"
        return None
    if isinstance(value, str) and leaves and all(a in (int, float) for a in leaves):
        return "must be a number, not text"
    if isinstance(value, list | tuple):
        for a in leaves:
            if get_origin(a) is tuple:
                args = [x for x in get_args(a) if x is not Ellipsis]
                for i, item in enumerate(value):
                    why = _wrong_scalar(args[min(i, len(args) - 1)], item) if args else None
                    if why:
                        return f"item {i} {why}"
    return None


class StrictModel(BaseModel):
    """Base of every config model: unknown keys are errors, models are frozen; a number
    is never read from true/false or from text (``start_time: true`` is an error)."""

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)

    @model_validator(mode="before")
    @classmethod
    def _strict_scalars(cls, data: Any) -> Any:
        if isinstance(data, Mapping):
            for key, value in data.items():
                field = cls.model_fields.get(key) if isinstance(key, str) else None
                if field is None:
                    continue
                why = _wrong_scalar(field.annotation, value)
                if why:
                    msg = f"{key} = {short_repr(value)}: {why}"
                    raise ValueError(msg)
        return data


class Pose(StrictModel):
    """A rigid pose: position (m) and roll/pitch/yaw (rad), R = Rz(yaw) Ry(pitch) Rx(roll)."""

    position: Vec3 = (0.0, 0.0, 0.0)
    rpy: Angles3 = (0.0, 0.0, 0.0)

    def matrix(self) -> np.ndarray:
        """4x4 homogeneous transform ``T_parent_child`` (float64)."""
        from roslan.frames import rpy_to_matrix

        T = np.eye(4)
        T[:3, :3] = rpy_to_matrix(np.asarray(self.rpy, dtype=float))
        T[:3, 3] = self.position
        return T


def _loc(loc: tuple[int | str, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or "<root>"


def did_you_mean(word: Any, allowed: list[str]) -> str:
    """``; did you mean 'x'?`` for the allowed word closest to ``word`` (difflib), or ''."""
    if not isinstance(word, str) or not allowed:
        return ""
    close = difflib.get_close_matches(word, allowed, n=2, cutoff=0.6)
    if not close:
        close = difflib.get_close_matches(word.lower(), [a.lower() for a in allowed], n=1)
        close = [a for a in allowed if a.lower() in close]
    if not close:
        return ""
    return "; did you mean " + " or ".join(repr(c) for c in close) + "?"


@dataclass(frozen=True)
class ModelFor:
    """``Annotated`` metadata of a field whose mappings validate with a model chosen by
    their content (a sensor's config class by its ``type``): ``resolve(mapping)`` returns
    that model or None. Error messages use it to list the keys the right model allows."""

    resolve: Callable[[Mapping[str, Any]], type[BaseModel] | None]


def _model_of(annotation: Any, data: Any) -> type[BaseModel] | None:
    """The pydantic model a field annotation validates ``data`` with (Optional, lists,
    Annotated unwrapped; a mapping under :class:`ModelFor` resolves to its model)."""
    origin = typing.get_origin(annotation)
    if origin is Annotated:
        base, *meta = typing.get_args(annotation)
        for m in meta:
            if isinstance(m, ModelFor) and isinstance(data, Mapping):
                found = m.resolve(data)
                if found is not None:
                    return found
        return _model_of(base, data)
    if origin in (typing.Union, types.UnionType):
        for arg in typing.get_args(annotation):
            found = _model_of(arg, data)
            if found is not None:
                return found
        return None
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    return None


def _element(annotation: Any) -> Any:
    """The element annotation of ``list[X]`` / ``tuple[X, ...]`` (possibly Annotated)."""
    origin = typing.get_origin(annotation)
    if origin is Annotated:
        return _element(typing.get_args(annotation)[0])
    if origin in (typing.Union, types.UnionType):
        for arg in typing.get_args(annotation):
            if arg is not type(None):
                return _element(arg)
    args = typing.get_args(annotation)
    return args[0] if origin in (list, tuple) and args else None


def allowed_keys(model: type[BaseModel], data: Any, loc: tuple[int | str, ...]) -> list[str] | None:
    """The keys the model at ``loc`` (a path into ``data``) accepts, or None if unknown."""
    cur: Any = model
    node: Any = data
    annotation: Any = None
    for part in loc:
        if isinstance(part, int):
            if annotation is None:
                return None
            annotation = _element(annotation)
            node = node[part] if isinstance(node, list | tuple) and part < len(node) else None
            cur = _model_of(annotation, node)
            continue
        if cur is None or part not in cur.model_fields:
            return None
        annotation = cur.model_fields[part].annotation
        node = node.get(part) if isinstance(node, Mapping) else None
        cur = _model_of(annotation, node)
    if cur is None:
        return None
    return list(cur.model_fields)


def _field_at(
    model: type[BaseModel], data: Any, loc: tuple[int | str, ...]
) -> tuple[Any, list[Any]] | None:
    """The annotation and field metadata at ``loc`` (a path into ``data``) of ``model``: a
    field's, or a list or tuple element's (no metadata of its own); None if unknown."""
    cur: type[BaseModel] | None = model
    node: Any = data
    annotation: Any = None
    metadata: list[Any] = []
    for part in loc:
        if isinstance(part, int):
            if annotation is None:
                return None
            annotation, metadata = _element(annotation), []
            node = node[part] if isinstance(node, list | tuple) and part < len(node) else None
            cur = _model_of(annotation, node)
            continue
        if cur is not None and part not in cur.model_fields:  # a tagged union's tag
            cur = _tagged_member(annotation, part)
            continue
        if cur is None:
            return None
        field = cur.model_fields[part]
        annotation, metadata = field.annotation, list(field.metadata)
        node = node.get(part) if isinstance(node, Mapping) else None
        cur = _model_of(annotation, node)
    return (annotation, metadata) if annotation is not None else None


def _tagged_member(annotation: Any, tag: str) -> type[BaseModel] | None:
    """The model of the union ``annotation`` whose Literal field has the value ``tag``
    (pydantic puts a discriminated union's tag in the error location), or None."""
    origin = get_origin(annotation)
    if origin is Annotated:
        return _tagged_member(get_args(annotation)[0], tag)
    if origin is not Union and origin is not types.UnionType:
        return None
    for arg in get_args(annotation):
        member = _model_of(arg, None)
        if member is None:
            continue
        for field in member.model_fields.values():
            if get_origin(field.annotation) is Literal and tag in get_args(field.annotation):
                return member
    return None


Bounds = tuple[tuple[float, bool] | None, tuple[float, bool] | None]
"""(lower, upper) bound of a number, each (value, inclusive) or None."""


def numeric_bounds(annotation: Any, metadata: list[Any] | tuple[Any, ...] = ()) -> Bounds:
    """The lower and upper bounds (``Field(gt=, ge=, lt=, le=)``, annotated-types
    constraints) of a field's ``annotation`` and ``metadata`` (Annotated, Optional
    unwrapped; the first of each side found)."""
    import annotated_types as at
    from pydantic.fields import FieldInfo

    items = list(metadata)

    def visit(ann: Any) -> None:
        origin = get_origin(ann)
        if origin is Annotated:
            base, *meta = get_args(ann)
            items.extend(meta)
            visit(base)
        elif origin is Union or origin is types.UnionType:
            for arg in get_args(ann):
                visit(arg)

    visit(annotation)
    lower: tuple[float, bool] | None = None
    upper: tuple[float, bool] | None = None
    while items:
        m = items.pop(0)
        if isinstance(m, FieldInfo):
            items.extend(m.metadata)
        for attr, incl, is_lower in (("gt", False, True), ("ge", True, True),
                                     ("lt", False, False), ("le", True, False)):  # fmt: skip
            bound = getattr(m, attr, None) if isinstance(m, at.BaseMetadata) else None
            if isinstance(bound, int | float) and not isinstance(bound, bool):
                if is_lower and lower is None:
                    lower = (float(bound), incl)
                elif not is_lower and upper is None:
                    upper = (float(bound), incl)
    return lower, upper


def _num(v: float) -> str:
    return str(int(v)) if v.is_integer() and abs(v) < 1e15 else f"{v:g}"


def allowed_range(name: str, bounds: Bounds) -> str | None:
    """``0 < rate <= 10000`` for a number bounded on both sides, else None."""
    lower, upper = bounds
    if lower is None or upper is None:
        return None
    lo = f"{_num(lower[0])} {'<=' if lower[1] else '<'}"
    hi = f"{'<=' if upper[1] else '<'} {_num(upper[0])}"
    return f"{lo} {name} {hi}"


_BOUND_ERRORS = frozenset({"greater_than", "greater_than_equal", "less_than", "less_than_equal"})

_QUOTED = re.compile(r"'([^']*)'")


def _clean_message(
    err: Mapping[str, Any], allowed: list[str] | None = None, bounds: str | None = None
) -> str:
    msg = str(err.get("msg", ""))
    for prefix in ("Value error, ", "Assertion failed, "):
        if msg.startswith(prefix):
            msg = msg[len(prefix) :]
    if err.get("type") == "extra_forbidden":
        loc = err.get("loc") or ()
        key = loc[-1] if loc else None
        msg = "unknown key" + (did_you_mean(key, allowed or []) or " (not allowed here)")
    elif err.get("type") in ("literal_error", "enum"):
        expected = str((err.get("ctx") or {}).get("expected", ""))
        msg += did_you_mean(err.get("input"), _QUOTED.findall(expected))
    elif bounds is not None:  # a bound error states the whole range, both sides
        msg += f"; allowed: {bounds}"
    return msg


def _range_at(model: type[BaseModel], data: Any, loc: tuple[int | str, ...]) -> str | None:
    """The allowed range of the number at ``loc`` named by its key (``rate``,
    ``position[2]``), or None (unknown field, or bounded on one side only)."""
    found = _field_at(model, data, loc)
    keys = [i for i, p in enumerate(loc) if isinstance(p, str)]
    if found is None or not keys:
        return None
    name = str(loc[keys[-1]]) + "".join(f"[{p}]" for p in loc[keys[-1] + 1 :])
    return allowed_range(name, numeric_bounds(*found))


def format_validation_error(
    exc: ValidationError,
    source: str | Path | None,
    prefix: tuple[int | str, ...] = (),
    *,
    model: type[BaseModel] | None = None,
    data: Any = None,
) -> str:
    """One line per problem: ``source: key.path = value: message``.

    With ``model`` and the validated ``data``, an unknown key names the closest allowed
    one (``unknown key; did you mean 'descent_rate'?``), and a number out of range gives
    the field's whole range when it has two sides (``; allowed: 0 < rate <= 10000``); a
    wrong choice always names the closest allowed one.
    """
    src = f"{source}: " if source is not None else ""
    lines = []
    for err in exc.errors(include_url=False):
        # Tagged unions insert the tag as a location element; keep user-facing keys only.
        loc = tuple(p for p in err["loc"] if not (isinstance(p, str) and p.startswith("function-")))
        allowed = None
        if model is not None and err.get("type") == "extra_forbidden" and loc:
            allowed = allowed_keys(model, data, loc[:-1])
        bounds = None
        if model is not None and err.get("type") in _BOUND_ERRORS and loc:
            bounds = _range_at(model, data, loc)
        full = (*prefix, *loc)
        value = err.get("input")
        # A whole mapping (model-level check) is not worth echoing: its message names the keys.
        hide = err.get("type") == "missing" or isinstance(value, Mapping)
        shown = "" if hide else f" = {short_repr(value)}"
        where = f"{_loc(full)}{shown}: " if full else ""
        lines.append(f"{src}{where}{_clean_message(err, allowed, bounds)}")
    return "\n".join(lines)


_REPR = reprlib.Repr()
_REPR.maxstring = 60
_REPR.maxother = 60
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = _REPR.maxset = 4
_REPR.maxlevel = 2


def short_repr(value: Any) -> str:
    """A bounded repr for error messages (never builds the repr of a whole, possibly huge,
    value)."""
    text = _REPR.repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def load_yaml(path: str | Path) -> Any:
    """Parse a YAML file through :mod:`roslan.io.safe_read` (regular file, size cap, no
    duplicate keys, bounded aliases and nesting); any problem is a ConfigError."""
    from roslan.io.safe_read import parse_yaml, read_text

    return parse_yaml(read_text(path), path)


def validate_model(
    model: type[M],
    data: Any,
    source: str | Path | None = None,
    context: Mapping[str, Any] | None = None,
) -> M:
    """Validate ``data`` against ``model``, raising ConfigError with readable messages."""
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        where = source or "<config>"
        msg = f"{where}: expected a mapping of keys at the top level, got {type(data).__name__}"
        raise ConfigError(msg)
    try:
        validated = model.model_validate(data, context=dict(context or {}))
    except ValidationError as err:
        text = format_validation_error(err, source, model=model, data=data)
        raise ConfigError(text) from None
    where = source or "<config>"
    for slip in unit_slips(validated):
        warnings.warn(f"{where}: {slip}", UnitWarning, stacklevel=2)
    return validated


class UnitWarning(UserWarning):
    """A valid value that is probably in the wrong unit (e.g. degrees for radians)."""


def load_yaml_model(model: type[M], path: str | Path) -> M:
    """Load a YAML file and validate it; relative paths inside resolve against its folder."""
    p = Path(path)
    context = {"base_dir": p.parent.resolve(), "source": p}
    return validate_model(model, load_yaml(p), p, context=context)
