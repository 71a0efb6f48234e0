"""Vectorized text formatting shared by every dataset text file.

Times are integer nanoseconds (int64) and are printed as seconds with exactly nine
decimals, computed from the integers (``'%d.%09d'``), so no float rounding ever
moves a stamp. Numeric columns are formatted a chunk at a time with one C-level
``%`` operation per chunk, so sensors can stream millions of rows with bounded
memory by calling :func:`write_columns` repeatedly on the same handle.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import IO, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from roslan.errors import OutputError

__all__ = ["CHUNK_ROWS", "format_columns", "format_seconds", "write_columns"]

CHUNK_ROWS = 65536
"""Rows formatted per ``%`` operation (bounds the temporary strings to a few MB)."""

_NS = 1_000_000_000


def _split_ns(t_ns: ArrayLike) -> tuple[list[str], list[int], list[int]]:
    t = np.asarray(t_ns)
    if t.dtype.kind not in "iu":
        msg = f"times must be integer nanoseconds, got dtype {t.dtype}"
        raise TypeError(msg)
    t = t.astype(np.int64, copy=False).ravel()
    neg = t < 0
    a = np.abs(t)
    sign = np.where(neg, "-", "").tolist()
    return sign, (a // _NS).tolist(), (a % _NS).tolist()


def format_seconds(t_ns: ArrayLike) -> NDArray[np.str_]:
    """Integer nanoseconds -> seconds strings with nine decimals, exactly.

    Args:
        t_ns: (N,) int64 nanoseconds (negative values get a leading ``-``).
    Returns:
        (N,) array of str, e.g. ``1500000000 -> '1.500000000'``.
    """
    sign, sec, frac = _split_ns(t_ns)
    n = len(sec)
    if n == 0:
        return np.array([], dtype=str)
    text = ("%s%d.%09d\n" * n) % tuple(
        itertools.chain.from_iterable(zip(sign, sec, frac, strict=True))
    )
    return np.array(text[:-1].split("\n"))


def _column_values(col: ArrayLike, n: int, index: int) -> list[Any]:
    a = np.asarray(col)
    if a.shape != (n,):
        msg = f"column {index} has shape {a.shape}, expected ({n},) like the times"
        raise ValueError(msg)
    if a.dtype.kind == "f":
        # + 0.0 turns -0.0 into 0.0 so a zero never prints as "-0"
        values: list[Any] = (a.astype(np.float64, copy=False) + 0.0).tolist()
    elif a.dtype.kind == "b":
        values = a.astype(np.int64).tolist()
    else:
        values = a.tolist()
    return values


def format_columns(
    t_ns: ArrayLike | None,
    *columns: ArrayLike,
    fmt: str | Sequence[str] = "%.9g",
    sep: str = " ",
    allow_nonfinite: bool = False,
) -> str:
    """Rows ``t c1 c2 ...`` as one string (each row ends with a newline).

    Args:
        t_ns: (N,) int64 nanoseconds printed by :func:`format_seconds` rules, or None
            for no time column.
        columns: (N,) numeric arrays (float, int or bool).
        fmt: one ``%``-format for every column, or one per column (``"%d"`` for ints).
        sep: column separator (``" "`` for TUM/ECD files, ``","`` for CSV).
        allow_nonfinite: unless True, a NaN or inf in a float column is an OutputError
            (roslan never presents NaN as data).
    """
    fmts = [fmt] * len(columns) if isinstance(fmt, str) else list(fmt)
    if len(fmts) != len(columns):
        msg = f"{len(fmts)} formats for {len(columns)} columns"
        raise ValueError(msg)
    if t_ns is not None:
        n = int(np.asarray(t_ns).size)
    elif columns:
        n = int(np.asarray(columns[0]).shape[0])
    else:
        return ""
    if not allow_nonfinite:
        for i, col in enumerate(columns):
            a = np.asarray(col)
            if a.dtype.kind == "f" and not np.isfinite(a).all():
                msg = f"column {i} holds NaN or inf values; refusing to write them as data"
                raise OutputError(msg)
    lists: list[list[Any]] = []
    parts: list[str] = []
    if t_ns is not None:
        sign, sec, frac = _split_ns(t_ns)
        lists += [sign, sec, frac]
        parts.append("%s%d.%09d")
    for i, col in enumerate(columns):
        lists.append(_column_values(col, n, i))
        parts.append(fmts[i])
    row = sep.join(parts) + "\n"
    out = []
    for start in range(0, n, CHUNK_ROWS):
        stop = min(n, start + CHUNK_ROWS)
        chunk = [lst[start:stop] for lst in lists]
        out.append(
            (row * (stop - start)) % tuple(itertools.chain.from_iterable(zip(*chunk, strict=True)))
        )
    return "".join(out)


def write_columns(
    fh: IO[str],
    t_ns: ArrayLike | None,
    *columns: ArrayLike,
    fmt: str | Sequence[str] = "%.9g",
    sep: str = " ",
    allow_nonfinite: bool = False,
) -> int:
    """Append rows ``t c1 c2 ...`` to an open text file; returns the number of rows.

    Same arguments as :func:`format_columns`. Call it once per chunk to stream a long
    table: memory stays bounded by the chunk the caller passes in (formatting works
    on :data:`CHUNK_ROWS` rows at a time).
    """
    if t_ns is not None:
        n = int(np.asarray(t_ns).size)
    elif columns:
        n = int(np.asarray(columns[0]).shape[0])
    else:
        return 0
    for start in range(0, n, CHUNK_ROWS):
        stop = min(n, start + CHUNK_ROWS)
        sl = slice(start, stop)
        fh.write(
            format_columns(
                None if t_ns is None else np.asarray(t_ns).ravel()[sl],
                *(np.asarray(c)[sl] for c in columns),
                fmt=fmt,
                sep=sep,
                allow_nonfinite=allow_nonfinite,
            )
        )
    return n
