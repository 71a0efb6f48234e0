"""Exclusive output folders: one run at a time writes a given OUTDIR.

A run holds a POSIX record lock (``fcntl.lockf``: owned by the process, not inherited by
forked helpers) on ``.<OUTDIR>.lock`` next to OUTDIR from its first check to its final
rename. The kernel drops the lock when its process dies (SIGKILL included), so a hidden
``.<OUTDIR>.partial-*`` or ``.<OUTDIR>.old-*`` folder found while holding the lock belongs
to a dead run and is removed.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from collections.abc import Iterator
from pathlib import Path

from roslan.errors import OutputError

__all__ = ["clean_stale", "outdir_lock"]

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: no locking
    fcntl = None  # type: ignore[assignment]


def _lock_path(outdir: Path) -> Path:
    return outdir.parent / f".{outdir.name}.lock"


@contextlib.contextmanager
def outdir_lock(outdir: Path) -> Iterator[None]:
    """Hold the lock of ``outdir`` (OutputError if another live run holds it)."""
    path = _lock_path(outdir)
    if fcntl is None:  # pragma: no cover
        yield
        return
    try:
        outdir.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        msg = f"cannot write output folder {outdir}: {err.strerror or err}"
        raise OutputError(msg) from None
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as err:
            msg = f"cannot write output folder {outdir}: {path}: {err.strerror or err}"
            raise OutputError(msg) from None
        try:
            fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            msg = (
                f"output folder {outdir} is being written by another roslan run "
                f"(lock {path.name}); wait for it to finish or choose another OUTDIR"
            )
            raise OutputError(msg) from None
        # the file may have been unlinked by its previous holder between open and flock
        try:
            same = os.stat(path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        yield
    finally:
        with contextlib.suppress(OSError):
            path.unlink()  # while still holding it: the next run creates a fresh one
        os.close(fd)


def clean_stale(outdir: Path) -> None:
    """Remove partial/old folders of dead runs into ``outdir`` (call with the lock held)."""
    parent = outdir.parent
    if not parent.is_dir():
        return
    for pattern in (f".{outdir.name}.partial-*", f".{outdir.name}.old-*"):
        for debris in parent.glob(pattern):
            if debris.is_dir() and not debris.is_symlink():
                shutil.rmtree(debris, ignore_errors=True)
