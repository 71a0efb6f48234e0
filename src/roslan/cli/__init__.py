"""The ``roslan`` command line: argparse and handlers only, one module per command.

Each command module defines ``register(subparsers)`` and calls library code; nothing
here holds an algorithm. :func:`main` is the console entry point.
"""

from __future__ import annotations

from roslan.cli.app import build_parser, main

__all__ = ["build_parser", "main"]
