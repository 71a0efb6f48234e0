"""The run folder's life cycle: exclusive, written aside, renamed into place when complete.

A run writes into a hidden sibling ``.<OUTDIR>.partial-XXXX`` (:func:`make_temp`) and
renames it to OUTDIR only once every file is written (:func:`finalize`); an old OUTDIR is
replaced only then, and only with ``--overwrite``. A reader therefore never sees a
half-written OUTDIR, and a killed run leaves only a hidden folder.

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
import tempfile
from collections.abc import Iterator
from pathlib import Path

from roslan.errors import OutputError
from roslan.io.files import current_umask
from roslan.rundir.manifest import RUN_FILE

__all__ = ["check_outdir", "clean_stale", "finalize", "make_temp", "outdir_lock"]

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


def check_outdir(outdir: Path, overwrite: bool) -> None:
    """Refuse an existing OUTDIR unless ``overwrite``, and never replace a folder that is
    not a roslan output (non-empty and without run.json), even with ``overwrite``."""
    if outdir.exists() or outdir.is_symlink():
        if not overwrite:
            msg = f"output folder {outdir} exists; pass --overwrite to replace it"
            raise OutputError(msg)
        if not outdir.is_dir():
            msg = f"output path {outdir} exists and is not a folder; refusing to replace it"
            raise OutputError(msg)
        if any(outdir.iterdir()) and not (outdir / RUN_FILE).exists():
            msg = (
                f"output folder {outdir} is not empty and holds no {RUN_FILE} "
                "(not a roslan output); "
                "refusing to replace it even with --overwrite"
            )
            raise OutputError(msg)


def make_temp(outdir: Path) -> Path:
    """A new hidden sibling ``.<OUTDIR>.partial-XXXX`` to write the run into."""
    parent = outdir.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{outdir.name}.partial-", dir=parent))
    except OSError as err:
        msg = f"cannot write output folder {outdir}: {err.strerror or err}"
        raise OutputError(msg) from err
    if not os.access(tmp, os.W_OK | os.X_OK):  # pragma: no cover - mkdtemp made it 0700
        shutil.rmtree(tmp, ignore_errors=True)
        msg = f"cannot write output folder {outdir}: not writable"
        raise OutputError(msg)
    return tmp


def finalize(tmp: Path, outdir: Path, overwrite: bool = True) -> None:
    """Move the finished temporary folder to OUTDIR; an old OUTDIR is removed only now,
    and only with ``overwrite`` (one that appeared during the run is never replaced)."""
    tmp.chmod(0o777 & ~current_umask())  # mkdtemp creates 0700
    old: Path | None = None
    if not overwrite and (outdir.exists() or outdir.is_symlink()):
        msg = (
            f"output folder {outdir} appeared while this run was writing; not replacing it "
            "(pass --overwrite to replace it)"
        )
        raise OutputError(msg)
    if outdir.exists() or outdir.is_symlink():
        old = Path(tempfile.mkdtemp(prefix=f".{outdir.name}.old-", dir=outdir.parent))
        old.rmdir()
        outdir.rename(old)
    try:
        tmp.rename(outdir)
    except OSError as err:
        if old is not None:
            old.rename(outdir)
        msg = f"cannot move the finished output into {outdir}: {err}"
        raise OutputError(msg) from err
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
