"""What a run reports: progress, the profile table, trajectory.png and PLAYBACK.md.

Nothing here changes an output byte that run.json describes: PLAYBACK.md and the
profile carry this run's wall-clock figures (as timing.json does), and trajectory.png is
drawn from the closed-form trajectory, in a forked child while the sensors stream.
"""

from __future__ import annotations

import multiprocessing
import multiprocessing.process
import shutil
import signal
import sys
import threading
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from roslan.errors import OutputError
from roslan.trajectory.base import Trajectory

__all__ = ["BackgroundPlot", "Progress", "playback_text", "print_profile"]

PLOT_TIMEOUT_S = 300.0
"""Longest wait for the background trajectory plot before rendering it in-process."""


class Progress:
    """Progress from the first second (stderr; nothing when quiet).

    Setup phases (loading the scene, building the BVH, preparing sensors, writing the
    overview) show a spinner on a terminal and one line each otherwise; the simulation
    itself is a bar with trajectory seconds done, the real-time factor and the time left.
    """

    def __init__(self, quiet: bool) -> None:
        self.total = 0.0
        self._bar: Any = None
        self._task: Any = None
        self._status: Any = None
        self._console: Any = None
        self._t0 = time.perf_counter()
        self.quiet = quiet
        if quiet:
            return
        from rich.console import Console

        self._console = Console(stderr=True)

    @property
    def tty(self) -> bool:
        return self._console is not None and bool(self._console.is_terminal)

    def phase(self, text: str) -> None:
        """Start a named setup phase (ends at the next phase, the bar or :meth:`stop`)."""
        if self._console is None:
            return
        self._end_status()
        if self.tty:
            self._status = self._console.status(f"{text}...")
            self._status.start()
        else:
            print(f"roslan: {text}...", file=sys.stderr, flush=True)

    def start(self, total_s: float) -> None:
        """The simulation bar over ``total_s`` seconds of trajectory."""
        self.total = total_s
        self._t0 = time.perf_counter()
        if self._console is None:
            return
        self._end_status()
        if not self.tty:
            print(f"roslan: simulating {total_s:.2f} s of trajectory...", file=sys.stderr)
            return
        from rich.progress import (
            BarColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        # compact columns: at 80 columns the bar shrinks, and the time left stays
        self._bar = Progress(
            TextColumn("simulating"),
            BarColumn(bar_width=None),
            TextColumn("{task.completed:.2f}/{task.total:.2f} s"),
            TextColumn("{task.fields[rtf]}"),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
            TextColumn("left"),
            console=self._console,
        )
        self._task = self._bar.add_task("sim", total=total_s, rtf="")
        self._bar.start()

    def update(self, t_s: float) -> None:
        if self._bar is None:
            return
        wall = time.perf_counter() - self._t0
        rtf = f"RTF {wall / t_s:.2f}" if t_s > 0 else ""  # real-time factor
        self._bar.update(self._task, completed=min(t_s, self.total), rtf=rtf)

    def _end_status(self) -> None:
        if self._status is not None:
            self._status.stop()
            self._status = None
        if self._bar is not None:
            self._bar.stop()
            self._bar = None

    def stop(self) -> None:
        self._end_status()


def _draw_trajectory(traj: Trajectory, folder: Path) -> None:
    from roslan.plots.landing import write_trajectory_plot

    write_trajectory_plot(traj, folder / "trajectory.png")


def _plot_child(traj: Trajectory, folder: Path) -> None:
    # the parent handles Ctrl-C / SIGTERM and terminates this child: die quietly
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    _draw_trajectory(traj, folder)


class BackgroundPlot:
    """Renders trajectory.png (about a second of matplotlib) in a forked child process while
    the parent streams the sensors, so the one-off plot overlaps the simulation on a second
    core. Where ``fork`` is not safe (non-Linux, or other Python threads running) it renders
    in-process at :meth:`finish`."""

    def __init__(self, traj: Trajectory, tmp: Path) -> None:
        self.tmp = tmp
        self.folder = tmp / ".plot"
        self.proc: multiprocessing.process.BaseProcess | None = None
        self.folder.mkdir()
        self.traj = traj
        # fork only from a single-threaded process (a fork while another Python thread holds
        # a lock can deadlock the child); otherwise render in-process at finish()
        if sys.platform.startswith("linux") and threading.active_count() == 1:
            mp = multiprocessing.get_context("fork")
            self.proc = mp.Process(target=_plot_child, args=(traj, self.folder), daemon=True)
            self.proc.start()

    def finish(self) -> None:
        """Wait for the child; move its trajectory.png into place (OutputError if it failed)."""
        if self.proc is None:
            _draw_trajectory(self.traj, self.folder)
        else:
            self.proc.join(PLOT_TIMEOUT_S)
            if self.proc.is_alive():  # pragma: no cover - a stuck child: render here instead
                self.kill()
                _draw_trajectory(self.traj, self.folder)
            elif self.proc.exitcode != 0:
                msg = f"rendering trajectory.png failed (child exit code {self.proc.exitcode})"
                raise OutputError(msg)
        png = self.folder / "trajectory.png"
        if png.exists():
            png.replace(self.tmp / "trajectory.png")
        shutil.rmtree(self.folder, ignore_errors=True)

    def kill(self) -> None:
        if self.proc is not None and self.proc.is_alive():
            self.proc.terminate()
            self.proc.join(5)


def playback_text(
    duration_s: float,
    wall_s: float,
    formats: Sequence[str],
    topics: dict[str, int],
    types: Mapping[str, str] | None = None,
) -> str:
    """PLAYBACK.md: how to play this run's bags at its pace, what ROS 2 playback needs
    (the MCAP storage plugin; a ``dvs_msgs`` package for the event topics, which
    ``types``, topic -> message type, names) and the topics."""
    events = sorted(t for t, ty in (types or {}).items() if ty.startswith("dvs_msgs/"))
    rtf = wall_s / duration_s if duration_s > 0 else float("inf")
    pace = 1.0 / rtf if rtf > 0 else float("inf")  # the play rate of this run's pace
    lines = [
        "# Playing this landing",
        "",
        f"Trajectory: {duration_s:.3f} s; this simulation took {wall_s:.3f} s of wall time "
        f"(real-time factor = wall time / trajectory time = {rtf:.2f}; playing at its pace "
        f"is rate 1 / {rtf:.2f} = {pace:.2f}).",
        "",
    ]
    if "ros1" in formats:
        lines += [
            "## ROS 1",
            "",
            "```bash",
            "rosbag info landing.bag",
            "rosparam set use_sim_time true   # stamps = start_time + trajectory time",
            "rosbag play --clock landing.bag             # real time",
            f"rosbag play --clock landing.bag -r {pace:.2f}   # at the pace this simulation ran",
            "rviz -d landing.rviz                        # the layout of this run's topics",
            "```",
            "",
        ]
        if events:
            lines += [
                "`rosbag play` needs no message packages; a node subscribing to "
                f"{_ticked(events)} (`dvs_msgs/EventArray`) needs rpg_dvs_ros' `dvs_msgs`.",
                "",
            ]
    if "ros2" in formats:
        lines += [
            "## ROS 2",
            "",
            "```bash",
            "ros2 bag info landing_ros2",
            "ros2 bag play landing_ros2 --clock",
            f"ros2 bag play landing_ros2 --clock -r {pace:.2f}",
            "```",
            "",
            "Needs the MCAP storage plugin: `sudo apt install ros-<distro>-rosbag2-storage-mcap`"
            " (Humble; from Iron on it comes with rosbag2). metadata.yaml says "
            "`storage_identifier: mcap`, so no `--storage` option is needed.",
            "",
        ]
        if events:
            lines += [
                f"The event topics ({_ticked(events)}) hold `dvs_msgs/msg/EventArray` "
                "(rpg_dvs_ros' messages): "
                "`ros2 bag play` skips them, with a warning, unless a ROS 2 `dvs_msgs` package "
                "is built in your workspace (sourced before playing) with these two messages:",
                "",
                "```",
                "# dvs_msgs/msg/Event.msg",
                "uint16 x",
                "uint16 y",
                "builtin_interfaces/Time ts",
                "bool polarity",
                "# dvs_msgs/msg/EventArray.msg",
                "std_msgs/Header header",
                "uint32 height",
                "uint32 width",
                "Event[] events",
                "```",
                "",
            ]
    bags = [f"`{b}`" for f, b in (("ros2", "landing_ros2/landing_ros2.mcap"),
                                      ("ros1", "landing.bag")) if f in formats]  # fmt: skip
    lines += [
        "## Foxglove",
        "",
        f"Open Foxglove -> *Open local file* -> {' or '.join(bags)}, then *Layouts -> "
        "Import from file* -> `landing.foxglove.json`: a 3D panel (fixed frame `world`; "
        "/tf and /tf_static give `world -> base_link -> sensors`) with the scene, the "
        "trajectory (`/ground_truth/pose`) and the clouds and scans, an Image panel per "
        "camera and a plot of the IMU and range topics.",
        "",
        "## Topics",
        "",
        "| topic | messages |",
        "|---|---|",
        *(f"| `{t}` | {n} |" for t, n in topics.items()),
        "",
    ]
    return "\n".join(lines)


def print_profile(per: dict[str, dict[str, Any]], writers_s: float) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title="time per component (s)")
    for col in ("component", "messages", "generator", "build", "close", "total"):
        table.add_column(col, justify="left" if col == "component" else "right")
    for name, p in per.items():
        total = p["generator_s"] + p["build_s"] + p["close_s"]
        table.add_row(
            name,
            str(p["messages"]),
            f"{p['generator_s']:.3f}",
            f"{p['build_s']:.3f}",
            f"{p['close_s']:.3f}",
            f"{total:.3f}",
        )
    table.add_row("bag writers", "", "", "", "", f"{writers_s:.3f}")
    Console(stderr=True).print(table)


def _ticked(names: Sequence[str]) -> str:
    return ", ".join(f"`{n}`" for n in names)
