"""``roslan export FORMAT OUTDIR``: a run's outputs in another dataset's layout."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

__all__ = ["register"]


def _semantickitti(args: argparse.Namespace) -> int:
    from roslan.rundir.semantickitti import export_semantickitti

    dest = export_semantickitti(
        Path(args.outdir), args.output, lidar=args.lidar, overwrite=args.overwrite
    )
    print(f"wrote {dest}")
    return 0


def register(subparsers: Any) -> None:
    """Add ``roslan export ...`` to the top-level parser."""
    from roslan.rundir import semantickitti

    p = subparsers.add_parser("export", help="a run's outputs in another dataset's layout")
    sub = p.add_subparsers(dest="export_command", metavar="FORMAT")
    k = sub.add_parser(
        "semantickitti",
        help="a labelled LiDAR's scans as SemanticKITTI velodyne/*.bin + labels/*.label",
        description=semantickitti.__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    k.add_argument("outdir", metavar="OUTDIR", help="a roslan simulate run with output.labels")
    k.add_argument(
        "-o",
        "--output",
        type=Path,
        default=None,
        metavar="DEST",
        help="folder to write (default OUTDIR/semantickitti)",
    )
    k.add_argument(
        "--lidar", default=None, metavar="NAME", help="the LiDAR (default: the only labelled one)"
    )
    k.add_argument(
        "--overwrite", action="store_true", help="replace DEST if it is an earlier export"
    )
    k.set_defaults(func=_semantickitti)
    p.set_defaults(func=lambda _args: (p.print_help(), 2)[1])
