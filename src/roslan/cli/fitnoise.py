"""``roslan fit-noise RECORDING``: the event-camera noise keys reproducing a recording's
background (the algorithm is :mod:`roslan.events.fit`)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

__all__ = ["register"]


def _run(args: argparse.Namespace) -> int:
    from roslan.events.fit import fit_noise
    from roslan.events.recording import read_recording

    rec = read_recording(Path(args.recording), size=tuple(args.size) if args.size else None)
    fit = fit_noise(
        rec,
        quiet_span=tuple(args.quiet_span) if args.quiet_span else None,
        std_max=args.aps_std,
        margin=args.margin,
    )
    print(f"# roslan fit-noise {args.recording}: keys of an event_camera sensor block")
    print(fit.report(), end="")
    return 0


def register(subparsers: Any) -> None:
    """Add ``roslan fit-noise`` to the top-level parser."""
    p = subparsers.add_parser(
        "fit-noise",
        help="fit the event-camera noise keys (leak, shot noise) to a real recording",
        description=(
            "Measure the background events of a recording's static pixels (found from its "
            "APS frames, or every pixel over a --quiet-span) and print the event_camera keys "
            "(YAML) that reproduce them, with the measured figures as comments. Reads "
            ".aedat4 (needs the aedat package) and roslan's events.h5 / events.txt."
        ),
    )
    p.add_argument("recording", metavar="RECORDING", help=".aedat4, events.h5 or events.txt")
    p.add_argument(
        "--quiet-span",
        nargs=2,
        type=float,
        metavar=("T0", "T1"),
        help="a span (s from the first event) in which nothing moves: every pixel is static",
    )
    p.add_argument(
        "--aps-std",
        type=float,
        default=2.0,
        help="static pixels vary by less than this APS std over the frames, DN (default 2)",
    )
    p.add_argument(
        "--margin",
        type=int,
        default=3,
        help="static pixels lie more than this many px from moving ones (default 3)",
    )
    p.add_argument(
        "--size",
        nargs=2,
        type=int,
        metavar=("W", "H"),
        help="sensor size of an events.txt (default: the largest x, y + 1)",
    )
    p.set_defaults(func=_run)
