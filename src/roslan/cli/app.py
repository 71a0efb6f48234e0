"""``roslan`` command line. Holds no algorithm: each command module parses its
arguments and calls library code. User errors (:class:`~roslan.errors.RoslanError`)
print one clear message and exit with status 2; no traceback."""

from __future__ import annotations

import argparse
import importlib
import re
import sys
import warnings
from collections.abc import Sequence

from roslan import __version__
from roslan.errors import Note, RoslanError

__all__ = ["main"]

# Each module defines ``register(subparsers)``, adding its command(s) with
# ``parser.set_defaults(func=callable(args) -> int)``.
COMMAND_MODULES: tuple[str, ...] = (
    "roslan.cli.trajectory",
    "roslan.cli.dataset",
    "roslan.cli.batch",
    "roslan.cli.simulate",
    "roslan.cli.fly",
    "roslan.cli.plot",
    "roslan.cli.preview",
    "roslan.cli.scene",
    "roslan.cli.view",
    "roslan.cli.fitnoise",
    "roslan.cli.export",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="roslan",
        description="Multi-sensor simulation of bio-inspired ornithopter landings.",
    )
    parser.add_argument("--version", action="version", version=f"roslan {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    _plain_help(parser)
    return parser


_ROLE = re.compile(r":[a-z]+:`(~?)([^`]+)`")


def plain(text: str) -> str:
    """``text`` without reST markup: Sphinx roles (``:func:`~a.b.f``` -> ``f``,
    ``:mod:`a.b``` -> ``a.b``) and double-backtick literals."""

    def _name(m: re.Match[str]) -> str:
        return m.group(2).rsplit(".", 1)[-1] if m.group(1) else m.group(2)

    return _ROLE.sub(_name, text).replace("``", "")


def _plain_help(parser: argparse.ArgumentParser) -> None:
    """Drop reST markup (Sphinx roles, double backticks) from every command's help texts."""
    if parser.description:
        parser.description = plain(parser.description)
    if parser.epilog:
        parser.epilog = plain(parser.epilog)
    for action in parser._actions:
        if action.help and action.help is not argparse.SUPPRESS:
            action.help = plain(action.help)
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                if choice.help:
                    choice.help = plain(choice.help)
            for sub in dict.fromkeys(action.choices.values()):
                _plain_help(sub)


def _show_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: object = None,
    line: str | None = None,
) -> None:
    kind = "note" if issubclass(category, Note) else "warning"
    print(f"{kind}: {message}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "func", None) is None:
        parser.print_help()
        return 2
    warnings.showwarning = _show_warning
    try:
        return int(args.func(args) or 0)
    except RoslanError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except OSError as err:  # a full disk, a read-only or missing folder, a too long name...
        where = err.filename if err.filename is not None else "output"
        print(f"error: {where}: {err.strerror or err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
