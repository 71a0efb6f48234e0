"""``roslan fly [CONFIG] --policy NAME -o OUTDIR [--seed S]``: fly a closed-loop episode
and write it as ``simulate`` writes a run, plus ``episode.json``."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from roslan.cli.common import seed_arg

__all__ = ["register"]

POLICY_NAMES = ("constant-descent", "tau-events", "tau-state")


def _fly(args: argparse.Namespace) -> int:
    from roslan.env.episode import fly
    from roslan.errors import ConfigError

    try:
        ep = fly(
            args.config,
            args.policy,
            seed=args.seed if args.seed is not None else 0,
            record=args.outdir,
            overwrite=args.overwrite,
        )
    except ConfigError as err:
        path = args.config
        if path is not None and not str(err).startswith(str(path)):
            raise type(err)(f"{path}: {err}") from None
        raise
    if not args.quiet:
        print(f"wrote {args.outdir}: {json.dumps(ep)}")
    return 0


def register(subparsers: Any) -> None:
    """Add the ``fly`` command."""
    p = subparsers.add_parser(
        "fly",
        help="fly a closed-loop landing with a policy and record it",
        description=(
            "Fly the closed-loop environment (roslan.env.LandingEnv) with a packaged policy "
            "and write OUTDIR atomically: the files `simulate` writes plus episode.json "
            "(policy, seed, success, reason, touchdown speeds, position and heading error). "
            "Without CONFIG, flies the default landing (roslan/Landing-v0)."
        ),
    )
    p.add_argument("config", nargs="?", type=Path, default=None, metavar="CONFIG", help="job YAML")
    p.add_argument(
        "--policy",
        required=True,
        choices=POLICY_NAMES,
        help=(
            "tau-events (event camera, IMU and the start estimate only); tau-state and "
            "constant-descent are oracles by design (they read the true state)"
        ),
    )
    p.add_argument(
        "-o",
        "--output",
        dest="outdir",
        type=Path,
        required=True,
        metavar="OUTDIR",
        help="output folder",
    )
    p.add_argument("--seed", type=seed_arg, default=None, help="the episode's seed (default 0)")
    p.add_argument(
        "--overwrite", action="store_true", help="replace an existing OUTDIR (after success)"
    )
    p.add_argument("--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=_fly)
