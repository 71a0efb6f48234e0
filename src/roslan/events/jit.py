"""numba compilation for roslan's kernels: compiled once per machine, GIL released.

``cache=True`` stores the machine code beside the module (``__pycache__``) or, when that
folder is read-only (a system-wide install), in numba's per-user cache directory; where
neither can be written numba refuses ``cache=True`` at decoration time, and the kernel is
compiled in every process instead (~1 s once) rather than failing the import.
``nogil=True`` lets a kernel run beside other Python threads (rendering, file writing).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numba

__all__ = ["kernel"]


def kernel(fn: Callable[..., Any]) -> Any:
    """``numba.njit(cache=True, nogil=True)``, without the cache where none is writable."""
    try:
        return numba.njit(cache=True, nogil=True)(fn)
    except RuntimeError:  # pragma: no cover - no writable cache location at all
        return numba.njit(cache=False, nogil=True)(fn)
