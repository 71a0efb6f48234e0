"""``roslan simulate [CONFIG] -o OUTDIR``: run a simulation job into an output folder
(``-o``/``--output`` like every command; ``--outdir`` is kept as an alias)."""

from __future__ import annotations

import argparse
import warnings
from importlib.resources import as_file, files
from pathlib import Path
from typing import Any

from roslan.cli.common import FORMAT_CHOICES, bag_formats, seed_arg
from roslan.config.base import load_yaml_model
from roslan.config.sim import SimConfig
from roslan.errors import ConfigError

__all__ = ["load_config", "register"]

DEFAULT_CONFIG = "default.yaml"


def load_config(path: Path | None) -> tuple[SimConfig, Path | None]:
    """The validated config of ``path``, or of the packaged default job when None."""
    if path is not None:
        config = load_yaml_model(SimConfig, path)
        if not config.model_fields_set:
            msg = (
                f"{path}: empty config (no trajectory, scene or sensors); give at least "
                "'sensors:' or 'scene:', or run without CONFIG for the built-in default job"
            )
            raise ConfigError(msg)
        if not config.sensors and config.scene is None:
            warnings.warn(
                f"{path}: no sensors and no scene: only the ground truth is recorded",
                stacklevel=1,
            )
        return config, path
    with as_file(files("roslan").joinpath("data", DEFAULT_CONFIG)) as p:
        return load_yaml_model(SimConfig, p), None


def _workers(text: str) -> int | str:
    if text == "auto":
        return text
    try:
        n = int(text)
    except ValueError:
        n = -1
    if n < 0:
        msg = f"{text!r}: allowed 'auto', 0 or a positive integer"
        raise argparse.ArgumentTypeError(msg)
    return n


def _simulate(args: argparse.Namespace) -> int:

    config, path = load_config(args.config)
    if args.seed is not None:
        config = config.model_copy(update={"seed": args.seed})
    try:
        return _run(args, config, path)
    except ConfigError as err:
        # every config problem names the file it came from
        if path is not None and not str(err).startswith(str(path)):
            raise type(err)(f"{path}: {err}") from None
        raise


def _run(args: argparse.Namespace, config: SimConfig, path: Path | None) -> int:
    from roslan.pipeline import run_simulation

    formats = bag_formats(args.format)
    if args.dry_run:  # the run's own checks, nothing written, then the estimate
        from roslan.cli.dryrun import print_run_estimate
        from roslan.pipeline import check_run

        plan = check_run(
            config,
            args.outdir,
            overwrite=args.overwrite,
            formats=formats,
            config_path=path,
            allow_collision=args.allow_collision,
            workers=args.workers,
        )
        return print_run_estimate(config, args.outdir, formats, duration=plan.traj.duration)
    run = run_simulation(
        config,
        args.outdir,
        overwrite=args.overwrite,
        quiet=args.quiet,
        formats=formats,
        allow_collision=args.allow_collision,
        profile=args.profile,
        config_path=path,
        overview=not args.no_overview,
        workers=args.workers,
    )
    if not args.quiet:
        print(
            f"wrote {args.outdir}: {run['trajectory_duration_s']:.3f} s of trajectory, "
            f"{run['messages_total']} messages ({', '.join(run['bags'].values())}); see PLAYBACK.md"
        )
    return 0


def register(subparsers: Any) -> None:
    """Add the ``simulate`` command."""
    p = subparsers.add_parser(
        "simulate",
        help="simulate a landing and record bags and dataset files",
        description=(
            "Fly the configured landing, simulate every sensor and write OUTDIR atomically: "
            "landing.bag (ROS 1), landing_ros2/ (ROS 2, MCAP), trajectory.csv, groundtruth.txt, "
            "imu.txt, calib/, PLAYBACK.md, run.json. Without CONFIG, runs the built-in default job."
        ),
    )
    p.add_argument("config", nargs="?", type=Path, default=None, metavar="CONFIG", help="job YAML")
    p.add_argument(
        "-o",
        "--output",
        "--outdir",  # the earlier spelling, kept so that scripts keep working
        dest="outdir",
        type=Path,
        required=True,
        metavar="OUTDIR",
        help="output folder (-o/--output, as in every roslan command; --outdir also works)",
    )
    p.add_argument("--seed", type=seed_arg, default=None, help="override the config's seed (>= 0)")
    p.add_argument("--format", choices=FORMAT_CHOICES, default=None, help="bag format(s)")
    p.add_argument(
        "--overwrite", action="store_true", help="replace an existing OUTDIR (after success)"
    )
    p.add_argument("--quiet", action="store_true", help="no progress output (phases, bar)")
    p.add_argument("--profile", action="store_true", help="print time spent per sensor and writer")
    p.add_argument(
        "--allow-collision",
        action="store_true",
        help="skip the check that the path clears the scene",
    )
    p.add_argument("--no-overview", action="store_true", help="do not draw overview.png at the end")
    p.add_argument(
        "--dry-run",
        action="store_true",
        help="make every check of the run (config, OUTDIR, free space, scene, clearance) "
        "and print the estimated disk use and run time; simulate and write nothing",
    )
    p.add_argument(
        "--workers",
        type=_workers,
        default=None,
        metavar="N",
        help="worker processes for cameras, event cameras and lidars: 'auto' (default: "
        "output.workers), 0 = all in one process, or N; outputs are identical either way",
    )
    p.set_defaults(func=_simulate)
