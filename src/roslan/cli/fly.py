"""``roslan fly [CONFIG] --policy NAME -o OUTDIR [--seed S]``: fly a closed-loop episode
and write it as ``simulate`` writes a run, plus ``episode.json``."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from roslan.cli.common import seed_arg

__all__ = ["register"]

POLICY_NAMES = ("constant-descent", "tau-events", "tau-state")


class FlyProgress:
    """``roslan fly``'s progress on stderr, as ``simulate`` shows its own: the setup
    phase, then the simulated time, the control steps and the events so far, with the
    real-time factor (a live line on a terminal; one line per phase otherwise; nothing
    when quiet)."""

    def __init__(self, quiet: bool) -> None:
        from roslan.pipeline.report import Progress

        self._progress = Progress(quiet)
        self._bar: Any = None
        self._task: Any = None
        self.steps = 0
        self.events = 0
        self.t = 0.0
        self._wall0 = 0.0
        self._progress.phase("building the scene and the sensors, first reset")

    def step(self, obs: dict[str, Any], info: dict[str, Any]) -> None:
        """``fly``'s ``on_step``: the reset's observation, then one call per step."""
        del obs
        if self._wall0 == 0.0:  # the reset's
            self._wall0 = time.perf_counter()
            self._start()
        else:
            self.steps += 1
        self.events += len(info["events"])
        self.t = t = float(info["t"])
        if self._bar is not None:
            wall = time.perf_counter() - self._wall0
            rtf = f"RTF {wall / t:.2f}" if t > 0 else ""
            self._bar.update(self._task, t=t, steps=self.steps, events=f"{self.events:,}", rtf=rtf)

    def _start(self) -> None:
        prog = self._progress
        prog.stop()
        if prog.quiet:
            return
        if not prog.tty:
            print("roslan: flying the episode...", file=sys.stderr, flush=True)
            return
        from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

        self._bar = Progress(
            SpinnerColumn(),
            TextColumn("flying {task.fields[t]:.2f} s simulated, {task.fields[steps]} steps,"),
            TextColumn("{task.fields[events]} events {task.fields[rtf]}"),
            TimeElapsedColumn(),
            console=prog._console,
        )
        self._task = self._bar.add_task("fly", total=None, t=0.0, steps=0, events="0", rtf="")
        self._bar.start()

    def stop(self) -> None:
        """End the display (a line with the totals when not on a terminal)."""
        self._progress.stop()
        if self._bar is not None:
            self._bar.stop()
            self._bar = None
        elif self._wall0 and not self._progress.quiet:
            print(
                f"roslan: flew {self.t:.2f} s simulated, {self.steps} steps, "
                f"{self.events:,} events",
                file=sys.stderr,
                flush=True,
            )


def _fly(args: argparse.Namespace) -> int:
    from roslan.env.episode import fly
    from roslan.errors import ConfigError

    progress = FlyProgress(args.quiet)
    try:
        ep = fly(
            args.config,
            args.policy,
            seed=args.seed if args.seed is not None else 0,
            record=args.outdir,
            overwrite=args.overwrite,
            on_step=progress.step,
        )
    except ConfigError as err:
        path = args.config
        if path is not None and not str(err).startswith(str(path)):
            raise type(err)(f"{path}: {err}") from None
        raise
    finally:
        progress.stop()
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
    p.add_argument(
        "--quiet", action="store_true", help="print nothing (no progress: phases, steps, events)"
    )
    p.set_defaults(func=_fly)
