"""Arguments shared by several commands."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from roslan.limits import MAX_SEED

__all__ = ["FORMAT_CHOICES", "add_outdir_command", "bag_formats", "seed_arg"]

FORMAT_CHOICES = ("ros1", "ros2", "both")
"""``--format`` values: one bag flavour, or both."""


def bag_formats(value: str | None) -> tuple[str, ...] | None:
    """The bag flavours of a ``--format`` value (None: the config's ``output.formats``)."""
    if value is None:
        return None
    return ("ros1", "ros2") if value == "both" else (value,)


def seed_arg(text: str) -> int:
    """argparse ``type=`` for ``--seed``: an integer in [0, 2**63 - 1]."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= MAX_SEED:
        shown = text if len(text) <= 40 else text[:37] + "..."
        msg = f"{shown!r}: must be an integer in [0, 2**63 - 1]"
        raise argparse.ArgumentTypeError(msg)
    return value


def add_outdir_command(
    subparsers: Any, name: str, help_text: str, doc: str | None, output_help: str
) -> argparse.ArgumentParser:
    """A subcommand reading one ``roslan simulate`` OUTDIR, with an optional ``-o`` file."""
    p: argparse.ArgumentParser = subparsers.add_parser(
        name,
        help=help_text,
        description=doc,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("outdir", metavar="OUTDIR", help="output folder of a roslan simulate run")
    p.add_argument("-o", "--output", type=Path, default=None, help=output_help)
    return p
