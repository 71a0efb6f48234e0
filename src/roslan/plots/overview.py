"""``overview.png``: one small figure of a whole run - the trajectory, one camera frame,
one event frame and one LiDAR scan - written by ``roslan simulate`` at the end of every
run (:func:`write_overview`) and by ``roslan plot overview``.

Only what the run has is drawn: the trajectory, then the camera frame, the event frame and
the LiDAR scan of the sensors it has, then - up to four panels - the IMU's accelerometer
and gyroscope and the position gaps against time (one row for two or three panels, 2 x 2
for four). A camera panel that shows an event camera's grayscale frames says so; an input
that exists but cannot be read is reported in its panel instead of failing the run.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from roslan.errors import PlotError
from roslan.plots.media import RunMedia, render_events
from roslan.plots.style import AXIS_COLORS, GAP_COLORS, MEASURED_ALPHA, figure, save_figure, style
from roslan.rundir.readers import ImuData, load_imu, load_run, resolved_config

__all__ = [
    "EVENT_WINDOW_NS",
    "OVERVIEW_SCAN_POINTS",
    "overview_figure",
    "overview_title",
    "warm_up",
    "write_overview",
]

COMMAND = "roslan plot overview"
EVENT_WINDOW_NS = 20_000_000
"""Event frame accumulation window (20 ms)."""
OVERVIEW_SCAN_POINTS = 300_000
"""Most LiDAR returns the overview's scan panel draws (every k-th of a denser scan)."""


def _placeholder(ax: Any, title: str, text: str) -> None:
    ax.set_title(title)
    ax.text(
        0.5,
        0.5,
        text,
        ha="center",
        va="center",
        fontsize=10,
        color="0.35",
        transform=ax.transAxes,
        wrap=True,
    )
    ax.set_xticks([])
    ax.set_yticks([])
    ax.grid(False)
    for spine in ax.spines.values():
        spine.set_visible(True)
        spine.set_color("0.8")


def _image(ax: Any, img: np.ndarray, title: str) -> None:
    ax.imshow(img, interpolation="nearest")
    ax.set_title(title)
    ax.set_xlabel("u [px]")
    ax.set_ylabel("v [px]")
    ax.grid(False)


def _trajectory_panel(ax: Any, media: RunMedia, t_ns: int, shown: str | None) -> None:
    """The path in F; a red dot marks instant ``t_ns`` of the ``shown`` media (none: no
    dot)."""
    s = media.traj
    if s is None:
        _placeholder(ax, "Trajectory (frame F)", "no trajectory.csv")
        return
    d = s.dense
    land = d.t <= s.touchdown + 1e-12
    p = d.gaps[land, :3]
    ax.plot(p[:, 0], p[:, 1], p[:, 2], color="tab:blue", linewidth=2.0, label="path")
    ax.plot(
        p[:, 0],
        p[:, 1],
        np.zeros_like(p[:, 2]),
        color="0.6",
        linewidth=1.0,
        linestyle="--",
        label="ground track",
    )
    # line markers: 3-D scatter would fade them with depth (the legend shows them solid)
    ax.plot(*([v] for v in p[0]), "o", color="k", ms=5, label="start", zorder=4)
    ax.plot([0], [0], [0], "*", color="gold", mec="k", ms=10, label="goal")
    if shown is not None:
        now = np.array([np.interp(t_ns * 1e-9, d.t, d.gaps[:, i]) for i in range(3)])
        ax.plot(
            *([v] for v in now),
            "o",
            color="tab:red",
            ms=5,
            label=f"t = {t_ns * 1e-9:.2f} s ({shown} shown)",
        )
    ax.set_xlabel("x_F [m]")
    ax.set_ylabel("y_F [m]")
    ax.set_zlabel("z_F [m]")
    lo, hi = np.minimum(p.min(axis=0), 0.0), np.maximum(p.max(axis=0), 0.0)
    span = float(np.max(hi - lo))
    mid = (hi + lo) / 2.0
    half = np.maximum(hi - lo, 0.35 * span) / 2.0
    ax.set_xlim(mid[0] - half[0], mid[0] + half[0])
    ax.set_ylim(mid[1] - half[1], mid[1] + half[1])
    ax.set_zlim(0.0, 2.0 * half[2])
    ax.set_box_aspect(tuple(2.0 * half))
    from matplotlib.ticker import MaxNLocator

    # a short axis gets few ticks, so their labels do not overlap
    for axis, extent in zip((ax.xaxis, ax.yaxis, ax.zaxis), 2.0 * half, strict=True):
        axis.set_major_locator(MaxNLocator(max(2, min(6, round(6 * extent / span)))))
    ax.view_init(elev=20, azim=-60)
    ax.legend(loc="upper right", fontsize=6)  # the start is usually upper left
    ax.set_title(f"Trajectory (frame F), touchdown T = {s.touchdown:.2f} s")


Painter = Callable[[Any], None]
SIZES = {1: (6.0, 5.0), 2: (10.0, 4.4), 3: (15.0, 4.6), 4: (10.0, 7.0)}
"""Figure size (inches) by panel count: one row up to three panels, else 2 x 2."""


def overview_panels(outdir: Path, media: RunMedia, t_ns: int) -> list[tuple[str, Painter]]:
    """The panels to draw, in order, as (kind, painter): ``trajectory``, then ``camera``,
    ``events``, ``lidar`` for the media the run has, then ``accelerometer``,
    ``gyroscope`` (a run with an IMU) and ``gaps`` while fewer than four."""
    media_kinds = [
        ("camera", media.camera, _camera_panel),
        ("events", media.events, _event_panel),
        ("lidar", media.lidar, _lidar_panel),
    ]
    present = [(k, draw) for k, m, draw in media_kinds if m is not None]
    kinds = {k for k, _ in present}
    shown = "frames" if kinds & {"camera", "events"} else "scan" if "lidar" in kinds else None
    panels: list[tuple[str, Painter]] = [
        ("trajectory", lambda ax: _trajectory_panel(ax, media, t_ns, shown))
    ]
    panels += [(k, functools.partial(draw, media=media, t_ns=t_ns)) for k, draw in present]
    for kind, painter in _imu_fillers(outdir, media):
        if len(panels) >= 4:
            break
        panels.append((kind, painter))
    return panels


def overview_figure(outdir: Path, media: RunMedia, title: str) -> Any:
    """The overview as a matplotlib Figure (drawn, not saved)."""
    if media.traj is not None:
        t_ns = round(media.traj.touchdown * 0.5e9)
    else:
        t_ns = media.duration_ns() // 2
    panels = overview_panels(outdir, media, t_ns)
    n = len(panels)
    rows, cols = (2, 2) if n == 4 else (1, n)
    fig = figure(*SIZES[n])
    for i, (kind, paint) in enumerate(panels):
        projection = "3d" if kind == "trajectory" else None
        paint(fig.add_subplot(rows, cols, i + 1, projection=projection))
    fig.suptitle(title, fontsize=11)
    return fig


def overview_title(scene: str | None, seed: int) -> str:
    """The overview's title: the run's scene and seed, never its folder (identical runs
    give identical files, and ``roslan plot overview`` redraws simulate's figure)."""
    return f"roslan run: {scene or 'no scene'}, seed {seed}"


def _run_title(outdir: Path) -> str:
    """:func:`overview_title` of the run.json in ``outdir``, else the folder's name."""
    config = resolved_config(load_run(outdir))
    if config is None:
        return f"roslan run: {outdir.name}"
    scene, seed = config.get("scene"), config.get("seed", 0)
    return overview_title(scene if isinstance(scene, str) else None, int(seed or 0))


def write_overview(outdir: Path, out: Path | None = None, *, title: str | None = None) -> Path:
    """Write ``OUTDIR/overview.png`` (or ``out``) for the run in ``outdir``; returns its path.

    ``title`` defaults to :func:`overview_title` of the run's run.json (the title
    ``roslan simulate`` draws), else to the folder's name.

    Frames are taken at the middle of the landing (half the touchdown time), where
    the robot moves; only the panels of what the run recorded are drawn.
    """
    outdir = Path(outdir)
    if not outdir.is_dir():
        msg = f"{COMMAND}: {outdir} is not a directory (give a roslan simulate OUTDIR)"
        raise PlotError(msg)
    out = Path(out) if out is not None else outdir / "overview.png"
    media = RunMedia.open(outdir, COMMAND)
    try:
        with style():
            fig = overview_figure(outdir, media, title if title is not None else _run_title(outdir))
            return save_figure(fig, out)
    finally:
        media.close()


def warm_up() -> None:
    """Import what :func:`write_overview` needs and draw a tiny figure of the same kinds
    (3-D and image axes, titles) into memory: matplotlib's imports, font cache and text
    layout are then ready, and the real overview takes about half as long (~1 s less on
    the 2-core dev machine). ``roslan simulate`` runs this on a thread while the sensors
    stream, so the time leaves the run's serial tail; nothing else may use matplotlib
    until it returns (it sets the roslan style, global rcParams, while it draws)."""
    import io

    import cv2  # noqa: F401  (the camera and event panels read PNG frames)
    import h5py  # noqa: F401  (events.h5)

    with style():
        fig = figure(2.0, 1.5)
        ax = fig.add_subplot(1, 2, 1, projection="3d")
        ax.set_title("warm-up")
        img = fig.add_subplot(1, 2, 2)
        img.imshow(np.zeros((2, 2)), interpolation="nearest")
        img.set_xlabel("u [px]")
        fig.suptitle("warm-up")
        fig.savefig(io.BytesIO(), format="png")


def _imu_fillers(outdir: Path, media: RunMedia) -> list[tuple[str, Painter]]:
    """Panels that fill the figure: the IMU's accelerometer and gyroscope (a run with an
    IMU), the position gaps against time (a run with a trajectory)."""
    out: list[tuple[str, Painter]] = []
    try:
        data = load_imu(outdir, COMMAND)
    except PlotError:
        pass
    else:
        out += [
            ("accelerometer", lambda ax: _imu_panel(ax, data, "accelerometer")),
            ("gyroscope", lambda ax: _imu_panel(ax, data, "gyroscope")),
        ]
    if media.traj is not None:
        out.append(("gaps", lambda ax: _gaps_panel(ax, media)))
    return out


def _imu_panel(ax: Any, data: ImuData, what: str) -> None:
    acc = what == "accelerometer"
    values = data.acc if acc else np.degrees(data.gyro)
    for i in range(3):
        ax.plot(
            data.t,
            values[:, i],
            color=AXIS_COLORS[i],
            alpha=MEASURED_ALPHA + 0.3,
            linewidth=0.8,
            label="xyz"[i],
        )
    ax.set_xlabel("trajectory time t [s]")
    ax.set_ylabel("specific force [m/s²]" if acc else "angular rate [deg/s]")
    ax.legend(loc="best", fontsize=7, ncols=3)
    ax.set_title(f"IMU {what} ({data.path.name}, IMU frame)")


def _gaps_panel(ax: Any, media: RunMedia) -> None:
    s = media.traj
    assert s is not None
    d = s.dense
    for i, name in enumerate(("x", "y", "z")):
        ax.plot(d.t, d.gaps[:, i], color=GAP_COLORS[name], label=f"{name}_F")
    ax.axvline(s.touchdown, color="0.4", linestyle="-.", linewidth=0.9, label="touchdown")
    ax.set_xlabel("trajectory time t [s]")
    ax.set_ylabel("gap to the goal [m]")
    ax.legend(loc="best", fontsize=7)
    ax.set_title("Position gaps (frame F)")


def _camera_panel(ax: Any, media: RunMedia, t_ns: int) -> None:
    if media.camera is None:
        _placeholder(ax, "Camera", "no camera configured")
        return
    try:
        i = media.camera.index_at(t_ns)
        img = media.camera.read(i)
    except PlotError as err:
        _placeholder(ax, "Camera", f"cannot read: {err}")
        return
    t = media.camera.t_ns[i] * 1e-9
    what = "Event camera" if media.camera_is_aps else "Camera"
    frame = " APS frame" if media.camera_is_aps else ""
    _image(ax, img, f"{what} '{media.camera.name}'{frame}, t = {t:.3f} s")


def _event_panel(ax: Any, media: RunMedia, t_ns: int) -> None:
    if media.events is None:
        _placeholder(ax, "Events", "no event camera configured")
        return
    try:
        img, n = render_events(media, t_ns - EVENT_WINDOW_NS, t_ns)
    except PlotError as err:
        _placeholder(ax, "Events", f"cannot read: {err}")
        return
    _image(ax, img, f"Events, {EVENT_WINDOW_NS / 1e6:.0f} ms before t: {n:,} (blue ON, red OFF)")


def _lidar_panel(ax: Any, media: RunMedia, t_ns: int) -> None:
    if media.lidar is None:
        _placeholder(ax, "LiDAR", "no LiDAR configured")
        return
    seq = media.lidar
    try:
        i = seq.index_at(t_ns)
        # every k-th return of a dense scan: the panel cannot show more points (a 12.8 M
        # point scan read whole and drawn took 1.5 GB)
        scan = seq.read(i, max_points=OVERVIEW_SCAN_POINTS)
    except PlotError as err:
        _placeholder(ax, "LiDAR", f"cannot read: {err}")
        return
    xyz = scan.xyz
    if xyz.shape[0] == 0:
        _placeholder(ax, f"LiDAR '{seq.name}'", "scan without returns")
        return
    lo, hi = np.percentile(xyz[:, 2], [2, 98])
    # the square of 98% of the returns' ranges; equal scales by widening the data range to
    # the panel's shape (not by shrinking the axes, which left a blank gap beside it)
    r = float(np.percentile(np.linalg.norm(xyz[:, :2], axis=1), 98)) * 1.05
    xyz = xyz[np.all(np.abs(xyz[:, :2]) <= r, axis=1)]
    order = np.argsort(xyz[:, 2], kind="stable")
    sc = ax.scatter(
        xyz[order, 0],
        xyz[order, 1],
        c=xyz[order, 2],
        cmap="turbo",
        s=0.5,
        linewidths=0,
        vmin=lo,
        vmax=max(hi, lo + 0.1),
        rasterized=True,
    )
    ax.update_datalim([(-r, -r), (r, r)])
    ax.margins(0.0)
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.plot(0, 0, "k^", ms=6)
    ax.set_xlabel("x (forward) [m]")
    ax.set_ylabel("y (left) [m]")
    cb = ax.figure.colorbar(sc, ax=ax, shrink=0.85, pad=0.01)
    cb.set_label("height z (sensor) [m]")
    ax.set_title(f"LiDAR '{seq.name}' bird's-eye, t = {scan.t_ns * 1e-9:.3f} s")
