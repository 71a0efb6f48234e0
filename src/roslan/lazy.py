"""Package attributes imported on first use (PEP 562): a package lists where each public
name lives, and importing one light module of it does not load the heavy ones."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_getattr"]


def lazy_getattr(package: str, where: Mapping[str, str]) -> Callable[[str], Any]:
    """The module ``__getattr__`` of ``package``: ``name`` from ``package.<where[name]>``."""

    def __getattr__(name: str) -> Any:
        try:
            module = where[name]
        except KeyError:
            msg = f"module {package!r} has no attribute {name!r}"
            raise AttributeError(msg) from None
        return getattr(importlib.import_module(f"{package}.{module}"), name)

    return __getattr__
