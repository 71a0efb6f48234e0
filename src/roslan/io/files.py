"""Atomic file writes: a reader never sees a half-written file under its final name.

Write to a temporary file in the destination folder, flush, then ``os.replace`` it
onto the final name (atomic on POSIX within one file system). On any exception the
temporary file is removed and the destination is left as it was.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any, Literal, overload

import numpy as np

__all__ = [
    "NPZ_DEFLATE_LEVEL",
    "DatasetFolder",
    "atomic_write",
    "atomic_write_bytes",
    "atomic_write_text",
    "current_umask",
    "save_npz",
]


class DatasetFolder:
    """The file sink of a recorded run: where its sensors' dataset files go.

    A run that records attaches one (its hidden partial OUTDIR folder); a run that does
    not attaches none, and its sensors then write no file at all.
    """

    def __init__(self, root: Path) -> None:
        self.root = Path(root)

    def path(self, relpath: str) -> Path:
        """``root / relpath`` with its parent folders made; ValueError for a path that
        is absolute or leaves the folder (``..``)."""
        rel = Path(relpath)
        if rel.is_absolute() or ".." in rel.parts:
            msg = f"dataset path {relpath!r} must be relative and stay inside the output folder"
            raise ValueError(msg)
        p = self.root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        return p


def current_umask() -> int:
    """The process umask (read without changing it for longer than the call)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


@overload
def atomic_write(
    path: str | Path,
    mode: Literal["w"] = "w",
    *,
    encoding: str = "utf-8",
    newline: str | None = "\n",
) -> contextlib.AbstractContextManager[IO[str]]: ...
@overload
def atomic_write(
    path: str | Path, mode: Literal["wb"], *, encoding: str = "utf-8", newline: str | None = "\n"
) -> contextlib.AbstractContextManager[IO[bytes]]: ...
def atomic_write(
    path: str | Path, mode: str = "w", *, encoding: str = "utf-8", newline: str | None = "\n"
) -> contextlib.AbstractContextManager[IO[str]] | contextlib.AbstractContextManager[IO[bytes]]:
    """Context manager yielding a file handle whose content appears at ``path`` only
    when the ``with`` block completes without error.

    Args:
        path: final file name; its parent folder must exist.
        mode: ``"w"`` (text, ``encoding``, ``newline``) or ``"wb"`` (binary).
    Example:
        >>> with atomic_write(outdir / "table.txt") as fh:  # doctest: +SKIP
        ...     fh.write("t x\\n")
    """
    if mode not in ("w", "wb"):
        msg = f"atomic_write mode must be 'w' or 'wb', got {mode!r}"
        raise ValueError(msg)
    return _atomic(Path(path), mode, encoding, newline)


@contextlib.contextmanager
def _atomic(path: Path, mode: str, encoding: str, newline: str | None) -> Iterator[IO[Any]]:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        if mode == "wb":
            fh: IO[Any] = os.fdopen(fd, "wb")
        else:
            fh = os.fdopen(fd, "w", encoding=encoding, newline=newline)
        with fh:
            yield fh
        # mkstemp creates 0600 files; give the result the usual permissions (umask applied)
        os.chmod(tmp, 0o666 & ~current_umask())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def atomic_write_text(path: str | Path, text: str, *, encoding: str = "utf-8") -> None:
    """Write ``text`` to ``path`` atomically."""
    with atomic_write(path, "w", encoding=encoding) as fh:
        fh.write(text)


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_write(path, "wb") as fh:
        fh.write(data)


NPZ_DEFLATE_LEVEL = 1
"""Deflate level of the ``.npz`` dataset files. NumPy's ``savez_compressed`` uses 6; on the
default job's LiDAR scans level 1 is within 1.5 % of its size for a third less CPU
(noisy float32 coordinates barely compress further; docs/performance.md)."""


def save_npz(fh: IO[bytes], arrays: dict[str, Any], level: int = NPZ_DEFLATE_LEVEL) -> None:
    """``np.savez_compressed(fh, **arrays)`` at deflate ``level``: the same zip layout (one
    ``NAME.npy`` member per array, in the order given, fixed 1980 timestamps, zip64), read
    by ``np.load`` as any ``.npz``. A callable value is called for its array when its
    member is written (one array of a large file in memory at a time)."""
    import zipfile

    with zipfile.ZipFile(fh, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=level) as zf:
        for name, value in arrays.items():
            if callable(value):  # made when its member is written (one array in memory)
                value = value()
            with zf.open(f"{name}.npy", "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.asanyarray(value), allow_pickle=False)
            del value
