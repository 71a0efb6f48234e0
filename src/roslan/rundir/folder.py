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
from collections.abc import Iterable, Iterator
from pathlib import Path

from roslan.errors import OutputError
from roslan.io.files import atomic_write, current_umask
from roslan.rundir.manifest import RUN_FILE, read_manifest

__all__ = [
    "DERIVED_FILE",
    "check_outdir",
    "clean_stale",
    "finalize",
    "make_temp",
    "note_derived",
    "outdir_lock",
    "run_files",
    "strangers",
]

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


def _files_below(folder: Path) -> list[str]:
    """Every file (or link, or other non-folder) below ``folder``, as sorted POSIX paths
    relative to it; links to folders are not followed."""
    out = []
    for root, dirs, files in os.walk(folder):
        base = Path(root).relative_to(folder)
        for name in files + [d for d in dirs if (Path(root) / d).is_symlink()]:
            out.append((base / name).as_posix())
    return sorted(out)


def run_files(folder: Path) -> list[str]:
    """The files a run wrote into its finished ``folder`` (run.json included), as run.json
    lists them: sorted POSIX paths relative to OUTDIR."""
    return sorted({*_files_below(folder), RUN_FILE})


DERIVED_FILE = "derived.txt"
"""A finished run's list of the files roslan's own commands later wrote into it
(``roslan plot ... OUTDIR``'s ``plots/``, a preview or recording saved inside it): one
relative path a line. ``--overwrite`` replaces them with the run; nothing else is added."""


def _derived(outdir: Path) -> set[str]:
    try:
        text = (outdir / DERIVED_FILE).read_text(encoding="utf-8")
    except OSError:
        return set()
    return {line for line in text.splitlines() if line}


def note_derived(outdir: Path, paths: Iterable[Path]) -> None:
    """Add the ``paths`` a roslan command wrote inside the finished run ``outdir`` to its
    :data:`DERIVED_FILE` (paths outside it, or a folder that is not a complete run, are
    left alone), so that ``--overwrite`` knows them as the run's."""
    if read_manifest(outdir) is None:
        return
    root = outdir.resolve()
    inside = set()
    for p in paths:
        try:
            inside.add(Path(p).resolve().relative_to(root).as_posix())
        except ValueError:
            continue  # written beside the run
    known = _derived(outdir)
    if inside - known:
        with atomic_write(outdir / DERIVED_FILE, "w") as fh:
            fh.write("".join(f"{name}\n" for name in sorted(known | inside)))


def _listed(names: list[str], more: int) -> str:
    shown = ", ".join(names)
    return shown + (f" (and {more} more)" if more > 0 else "")


def strangers(outdir: Path) -> str | None:
    """Why ``--overwrite`` must not replace ``outdir`` (None when it may): it holds
    another run (a nested run.json), or any file its own run did not write (the
    ``files`` that run's run.json lists), or it is not a roslan run at all."""
    found = _files_below(outdir)
    if not found:
        return None
    nested = [f for f in found if f.endswith(f"/{RUN_FILE}")]
    if nested:
        runs = [str(outdir / Path(f).parent) for f in nested[:3]]
        return f"holds another roslan run in {_listed(runs, len(nested) - 3)}"
    manifest = read_manifest(outdir)
    if manifest is None:
        return f"is not empty and holds no complete {RUN_FILE} (not a roslan output)"
    listed = manifest.get("files")
    if not isinstance(listed, list):
        return (
            f"has a {RUN_FILE} without the list of the files its run wrote (an older "
            "roslan): its files cannot be told from others"
        )
    derived = _derived(outdir) | {DERIVED_FILE} if (outdir / DERIVED_FILE).is_file() else set()
    extra = sorted(set(found) - {str(f) for f in listed} - derived)
    if extra:
        return f"holds files its roslan run did not write: {_listed(extra[:5], len(extra) - 5)}"
    return None


def check_outdir(outdir: Path, overwrite: bool) -> None:
    """Refuse an existing OUTDIR unless ``overwrite``; even with it, replace only a roslan
    run's own files: never a folder that holds another run, a file that run did not
    write (:func:`strangers`), or anything that is not a roslan output."""
    if outdir.exists() or outdir.is_symlink():
        if not overwrite:
            msg = f"output folder {outdir} exists; pass --overwrite to replace it"
            raise OutputError(msg)
        if not outdir.is_dir():
            msg = f"output path {outdir} exists and is not a folder; refusing to replace it"
            raise OutputError(msg)
        why = strangers(outdir)
        if why is not None:
            msg = (
                f"output folder {outdir} {why}; refusing to replace it even with "
                "--overwrite (move those out, delete the folder yourself, or choose "
                "another OUTDIR)"
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
        check_outdir(outdir, overwrite=True)  # nothing foreign arrived during the run
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
