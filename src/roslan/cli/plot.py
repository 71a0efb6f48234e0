"""``roslan plot FIGURE ...``: argparse and handlers of the figures in :mod:`roslan.plots`.

To add a figure: a function in a :mod:`roslan.plots` module, plus one handler and one
``_register_*`` function here, listed in :data:`FIGURES`.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from roslan.cli.common import add_outdir_command
from roslan.errors import OutputError
from roslan.plots import events, imu, lidar, overview, shutter, tau_family, trajectory
from roslan.rundir.folder import note_derived
from roslan.rundir.readers import find_imu_files, missing_input

__all__ = ["register"]


def _written(args: argparse.Namespace, path: Path) -> None:
    """Say where the figure went; one written inside the run becomes the run's
    (:func:`~roslan.rundir.folder.note_derived`: ``--overwrite`` replaces it)."""
    note_derived(Path(args.outdir), [Path(path)])
    print(path)


def _tau_family(args: argparse.Namespace) -> int:
    out = Path(args.output)
    if not out.parent.is_dir():
        msg = f"{out}: folder {out.parent} does not exist"
        raise OutputError(msg)
    tau_family.plot_tau_family(list(args.k), out)
    print(f"wrote {out}")
    return 0


def _register_tau_family(plot_subparsers: Any) -> None:
    """Add ``tau-family`` to the ``roslan plot`` group."""
    p = plot_subparsers.add_parser(
        "tau-family",
        help="gap closure for several k (paper Fig. 1)",
        description="Gap, rate and acceleration of tau-constant closure for several k.",
    )
    p.add_argument("-o", "--output", required=True, metavar="FILE.png", help="PNG to write")
    p.add_argument(
        "--k",
        type=float,
        nargs="+",
        default=list(tau_family.DEFAULT_KS),
        metavar="K",
        help="tau-dot values, 0 < k <= 1 (default: %(default)s)",
    )
    p.set_defaults(func=_tau_family)


def _events(args: argparse.Namespace) -> int:
    files = events.plot_events(
        Path(args.outdir),
        Path(args.output),
        window=args.window,
        frames=args.frames,
        times=args.times,
    )
    note_derived(Path(args.outdir), files)
    for f in files:
        print(f)
    return 0


def _register_events(plot_subparsers: Any) -> None:
    """Add ``events`` to the ``roslan plot`` group."""
    p = plot_subparsers.add_parser(
        "events",
        help="event frames over the APS image and the event rate (paper Fig. 5a/c)",
        description="Event frames (ON blue, OFF red) over the grayscale image, and the event rate.",
    )
    p.add_argument("outdir", metavar="OUTDIR", help="a roslan simulate output folder")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="folder for the PNGs")
    p.add_argument(
        "--window", type=float, default=0.01, help="seconds of events per frame (default: 0.01)"
    )
    p.add_argument(
        "--frames", type=int, default=6, help="number of frames, evenly spread (default: 6)"
    )
    p.add_argument(
        "--times",
        type=float,
        nargs="+",
        default=None,
        metavar="T",
        help="window starts, s (instead of --frames)",
    )
    p.set_defaults(func=_events)


def _trajectory(args: argparse.Namespace) -> int:
    path = trajectory.plot_trajectory(Path(args.outdir), args.output)
    _written(args, path)
    return 0


def _register_trajectory(sub: Any) -> None:
    """Add ``trajectory`` to the ``roslan plot`` subcommands."""
    p = add_outdir_command(
        sub,
        "trajectory",
        "3-D landing path with velocity vectors and orientation triads; gaps and tau vs time",
        trajectory.__doc__,
        "PNG to write (default OUTDIR/plots/trajectory.png)",
    )
    p.set_defaults(func=_trajectory)


def _lidar(args: argparse.Namespace) -> int:
    path = lidar.plot_lidar(
        Path(args.outdir), args.output, sensor=args.sensor, scan=args.scan, color_by=args.color
    )
    _written(args, path)
    return 0


def _register_lidar(sub: Any) -> None:
    """Add ``lidar`` to the ``roslan plot`` subcommands."""
    p = add_outdir_command(
        sub,
        "lidar",
        "one LiDAR scan as a coloured point cloud (perspective and bird's-eye)",
        lidar.__doc__,
        "PNG to write (default OUTDIR/plots/lidar_<name>.png)",
    )
    p.add_argument(
        "--sensor",
        default=None,
        metavar="NAME",
        help="which LiDAR (folder under OUTDIR/lidar; default: the first)",
    )
    p.add_argument(
        "--scan",
        type=int,
        default=None,
        metavar="INDEX",
        help="scan index, 0-based as the figure's title and the files NNNNNN.npz (0 = the "
        "first; default: the middle scan; negative counts from the end)",
    )
    p.add_argument(
        "--color",
        choices=lidar.COLOR_BY,
        default="ring",
        help="colour points by laser ring (default), height, intensity or range",
    )
    p.set_defaults(func=_lidar)


def _imu(args: argparse.Namespace) -> int:
    outdir = Path(args.outdir)
    imu_file = None
    if args.imu is not None:
        files = {p.stem: p for p in find_imu_files(outdir)}
        key = "imu" if args.imu in files and args.imu == "imu" else f"imu_{args.imu}"
        imu_file = files.get(key) or files.get(args.imu)
        if imu_file is None:
            raise missing_input(imu.COMMAND, outdir, f"IMU file for sensor {args.imu!r}", "imu")
    _written(args, imu.plot_imu(outdir, args.output, imu_file))
    return 0


def _register_imu(sub: Any) -> None:
    """Add ``imu`` to the ``roslan plot`` subcommands."""
    p = add_outdir_command(
        sub,
        "imu",
        "accelerometer and gyroscope samples against the noise-free truth",
        imu.__doc__,
        "PNG to write (default OUTDIR/plots/imu.png)",
    )
    p.add_argument(
        "--imu",
        default=None,
        metavar="NAME",
        help="which IMU of a run with several (default: the first, imu.txt)",
    )
    p.set_defaults(func=_imu)


def _overview(args: argparse.Namespace) -> int:
    _written(args, overview.write_overview(Path(args.outdir), args.output))
    return 0


def _register_overview(sub: Any) -> None:
    """Add ``overview`` to the ``roslan plot`` subcommands."""
    p = add_outdir_command(
        sub,
        "overview",
        "one small figure of a run: trajectory, camera, event frame, LiDAR scan",
        overview.__doc__,
        "PNG to write (default OUTDIR/overview.png)",
    )
    p.set_defaults(func=_overview)


def _shutter(args: argparse.Namespace) -> int:
    _written(args, shutter.plot_shutter(Path(args.outdir), args.output, time=args.time))
    return 0


def _register_shutter(sub: Any) -> None:
    """Add ``shutter`` to the ``roslan plot`` subcommands."""
    p = add_outdir_command(
        sub,
        "shutter",
        "a frame-camera image (blur, rolling shutter) beside the events of its exposure",
        shutter.__doc__,
        "PNG to write (default OUTDIR/plots/shutter.png)",
    )
    p.add_argument(
        "--time",
        type=float,
        default=None,
        metavar="T",
        help="the frame nearest T s (default: the largest pitch rate of the flight)",
    )
    p.set_defaults(func=_shutter)


FIGURES = (
    _register_tau_family,
    _register_events,
    _register_shutter,
    _register_trajectory,
    _register_lidar,
    _register_imu,
    _register_overview,
)
"""The ``roslan plot`` subcommands, in --help order."""


def register(subparsers: Any) -> None:
    """Add the ``plot`` command group to the top-level ``roslan`` subparsers."""
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "plot",
        help="draw a figure (tau-family, ...)",
        description="Draw a figure into a PNG file.",
    )
    plot_sub = parser.add_subparsers(dest="figure", metavar="FIGURE")
    for add in FIGURES:
        add(plot_sub)

    def _no_figure(args: argparse.Namespace) -> int:
        parser.print_help()
        return 2

    parser.set_defaults(func=_no_figure)
