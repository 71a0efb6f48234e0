"""``roslan view OUTDIR``: the run in Rerun (:mod:`roslan.view.recording`)."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

__all__ = ["register"]


def _has_display() -> bool:
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _view(args: argparse.Namespace) -> int:
    from roslan.view.recording import ViewError, build_recording

    outdir = Path(args.outdir)
    save: Path | None = args.save
    if save is None and not _has_display():
        msg = (
            "roslan view: no display here (DISPLAY/WAYLAND_DISPLAY unset) to open the Rerun "
            "viewer; write a file with --save FILE.rrd and open it with `rerun FILE.rrd` "
            "where a display exists"
        )
        raise ViewError(msg)
    if save is not None and save.suffix != ".rrd":
        msg = f"roslan view: --save {save}: the file must end in .rrd"
        raise ViewError(msg)
    tmp = None if save is None else save.with_name(save.name + ".tmp")
    try:
        entities = build_recording(
            outdir, tmp, event_window_ms=args.event_window_ms, spawn=save is None
        )
    except BaseException:
        if tmp is not None:
            tmp.unlink(missing_ok=True)
        raise
    if tmp is not None and save is not None:
        os.replace(tmp, save)
        size = save.stat().st_size / 1e6
        n = len(entities)
        what = f"{n} sensor{'' if n == 1 else 's'}"
        print(f"{save} ({size:.1f} MB; {what}: {', '.join(sorted(entities))})")
    return 0


def register(subparsers: Any) -> None:
    """Add the top-level ``view`` command."""
    from roslan.view import recording

    p: argparse.ArgumentParser = subparsers.add_parser(
        "view",
        help="the run in Rerun: scene, trajectory, every sensor on one timeline",
        description=recording.__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("outdir", metavar="OUTDIR", help="output folder of a roslan simulate run")
    p.add_argument(
        "--save",
        type=Path,
        default=None,
        metavar="FILE.rrd",
        help="only write the recording to this file (no viewer)",
    )
    p.add_argument(
        "--event-window-ms",
        type=float,
        default=10.0,
        help="accumulation window of each event frame, ms (default 10)",
    )
    p.set_defaults(func=_view)
