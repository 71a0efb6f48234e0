"""``roslan plot FIGURE ...``: the command group every figure registers under.

To add a figure, write a module with ``register(plot_subparsers)`` that adds one
subcommand with ``parser.set_defaults(func=callable(args) -> int)``, and add its
name to :data:`PLOT_COMMANDS` (one line).
"""

from __future__ import annotations

import argparse
import importlib
from typing import Any

__all__ = ["PLOT_COMMANDS", "register"]

PLOT_COMMANDS: tuple[str, ...] = (
    "roslan.plots.tau_family",
    "roslan.plots.events",
    "roslan.plots.trajectory",
    "roslan.plots.lidar",
    "roslan.plots.imu",
    "roslan.plots.overview",
)  # fmt: skip


def register(subparsers: Any) -> None:
    """Add the ``plot`` command group to the top-level ``roslan`` subparsers."""
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "plot",
        help="draw a figure (tau-family, ...)",
        description="Draw a figure into a PNG file.",
    )
    plot_sub = parser.add_subparsers(dest="figure", metavar="FIGURE")
    for name in PLOT_COMMANDS:
        importlib.import_module(name).register(plot_sub)

    def _no_figure(args: argparse.Namespace) -> int:
        parser.print_help()
        return 2

    parser.set_defaults(func=_no_figure)
