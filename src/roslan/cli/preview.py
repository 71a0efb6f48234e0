"""``roslan preview OUTDIR``: a synchronized video of a run (:mod:`roslan.plots.preview`)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from roslan.cli.common import add_outdir_command
from roslan.plots import preview
from roslan.rundir.folder import note_derived

__all__ = ["register"]


def _preview(args: argparse.Namespace) -> int:
    info = preview.make_preview(
        Path(args.outdir),
        args.output,
        gif=True if args.gif else None,
        fps=args.fps,
        speed=args.speed,
        window_ms=args.window_ms,
        panel_width=args.panel_width,
        progress=not args.quiet,
    )
    note_derived(Path(args.outdir), [Path(info.path)])  # inside the run: the run's
    print(f"{info.path} ({info.frames} frames, {info.size[0]}x{info.size[1]} at {info.fps:g} fps)")
    return 0


def register(subparsers: Any) -> None:
    """Add the top-level ``preview`` command."""
    p = add_outdir_command(
        subparsers,
        "preview",
        "synchronized video of a run: camera, events, LiDAR, trajectory, time",
        preview.__doc__,
        "video to write (default OUTDIR/preview.mp4, or .gif with --gif)",
    )
    p.add_argument("--gif", action="store_true", help="write an animated GIF (half size, <=12 fps)")
    p.add_argument("--fps", type=float, default=30.0, help="video frames per second (default 30)")
    p.add_argument(
        "--speed",
        type=float,
        default=1.0,
        help="trajectory seconds per video second (default 1: real time)",
    )
    p.add_argument(
        "--window-ms",
        type=float,
        default=20.0,
        help="event accumulation window per frame, ms (default 20)",
    )
    p.add_argument(
        "--panel-width",
        type=int,
        default=480,
        help="width of each of the 4 panels, px (default 480)",
    )
    p.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    p.set_defaults(func=_preview)
