"""Probable unit slips in a validated config, reported as warnings that name the key.

A field annotated with :data:`RADIANS` holds angles in radians; a value beyond +-2 pi is
valid but almost always degrees typed by mistake (``rpy: [0, 20, 0]`` meaning 20 deg),
so :func:`unit_slips` lists it and :func:`~roslan.config.base.validate_model` warns
(one ``warning:`` line per key). Impossible values (an exposure longer than the frame
period) are refused by the models' own validators instead.
"""

from __future__ import annotations

import math
from typing import Any

from pydantic import BaseModel

__all__ = ["RADIANS", "TURN", "unit_slips"]


class _Radians:
    """``Annotated`` metadata: the field's value (or each of its numbers) is an angle in
    radians."""

    def __repr__(self) -> str:
        return "RADIANS"


RADIANS = _Radians()
TURN = 2.0 * math.pi


def _numbers(value: Any) -> list[float]:
    items = value if isinstance(value, list | tuple) else (value,)
    return [float(v) for v in items if isinstance(v, int | float) and not isinstance(v, bool)]


def _walk(value: Any, key: str) -> list[str]:
    if isinstance(value, BaseModel):
        return unit_slips(value, key)
    if isinstance(value, list | tuple):
        return [s for i, v in enumerate(value) for s in _walk(v, f"{key}[{i}]")]
    return []


def unit_slips(model: BaseModel, prefix: str = "") -> list[str]:
    """``key = value: why`` for every angle of ``model`` (nested models and lists
    included) beyond +-2 pi rad."""
    out: list[str] = []
    for name, field in type(model).model_fields.items():
        value = getattr(model, name, None)
        key = f"{prefix}.{name}" if prefix else name
        if any(m is RADIANS for m in field.metadata):
            nums = _numbers(value)
            if any(abs(v) > TURN for v in nums):
                shown = [f"{v:g}" for v in nums]
                text = shown[0] if not isinstance(value, list | tuple) else f"[{', '.join(shown)}]"
                deg = max(nums, key=abs)
                out.append(
                    f"{key} = {text}: beyond +-2 pi; angles are in radians (if "
                    f"{deg:g} means degrees, write {math.radians(deg):.4g})"
                )
        out += _walk(value, key)
    return out
