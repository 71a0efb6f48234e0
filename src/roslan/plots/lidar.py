"""``roslan plot lidar``: one LiDAR scan as a coloured point cloud, in perspective and
from above (the paper's Fig. 5b/d).

Points are drawn in the sensor frame as recorded (``lidar/<name>/NNNNNN.npz``, each
point at its own firing instant, not de-skewed), coloured by laser ring, height
(z in the sensor frame), intensity or range.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from roslan.errors import PlotError
from roslan.plots.style import figure, save_figure, style
from roslan.rundir.readers import LidarScan, LidarSequence, find_lidar

__all__ = ["COLOR_BY", "choose_scan", "plot_lidar", "scan_values"]

F64 = NDArray[np.float64]
COMMAND = "roslan plot lidar"
COLOR_BY = ("ring", "height", "intensity", "range")
MAX_POINTS_3D = 60_000
"""Perspective panel: a deterministic subsample keeps matplotlib's 3-D scatter fast."""


def choose_scan(
    outdir: Path, command: str, sensor: str | None = None, index: int | None = None
) -> tuple[LidarSequence, int]:
    """The LiDAR (by name, default the first) and scan index (default: the middle scan)."""
    seqs = find_lidar(outdir, command)
    if sensor is None:
        seq = seqs[0]
    else:
        match = [s for s in seqs if s.name == sensor]
        if not match:
            names = ", ".join(s.name for s in seqs)
            msg = f"{command}: {outdir} has no LiDAR named {sensor!r}; it has: {names}"
            raise PlotError(msg)
        seq = match[0]
    n = len(seq)
    if index is None:
        index = n // 2
    if not -n <= index < n:
        msg = f"{command}: --scan {index}: {seq.name} has {n} scans (0..{n - 1})"
        raise PlotError(msg)
    return seq, index % n


def scan_values(scan: LidarScan, color_by: str) -> tuple[F64, str]:
    """(M,) colour values and their colorbar label; ``ring`` falls back to height (for a
    scan without rings, or a solid-state LiDAR's single one)."""
    if color_by == "ring" and scan.ring is not None and np.unique(scan.ring).size > 1:
        return scan.ring.astype(np.float64), "ring (laser, 0 = lowest)"
    if color_by == "intensity" and scan.intensity is not None:
        return scan.intensity, "intensity"
    if color_by == "range":
        return np.linalg.norm(scan.xyz, axis=1), "range [m]"
    return scan.xyz[:, 2], "height z (sensor frame) [m]"


def _extent(xyz: F64) -> float:
    """Half-width (m) of the square centred on the sensor that holds every point
    horizontally (no return is cut off, however far), at least 1 m."""
    return float(max(np.abs(xyz[:, :2]).max(initial=0.0) * 1.03, 1.0))


def plot_lidar(
    outdir: Path,
    out: Path | None = None,
    *,
    sensor: str | None = None,
    scan: int | None = None,
    color_by: str = "ring",
) -> Path:
    """Draw one scan of the run in ``outdir``; returns the PNG path (default
    ``OUTDIR/plots/lidar_<name>.png``)."""
    if color_by not in COLOR_BY:
        msg = f"{COMMAND}: --color {color_by!r}; allowed: {', '.join(COLOR_BY)}"
        raise PlotError(msg)
    outdir = Path(outdir)
    seq, i = choose_scan(outdir, COMMAND, sensor, scan)
    sc = seq.read(i)
    if sc.xyz.shape[0] == 0:
        msg = f"{COMMAND}: {seq.paths[i]} holds no returns; choose another --scan"
        raise PlotError(msg)
    values, vlabel = scan_values(sc, color_by)
    out = Path(out) if out is not None else outdir / "plots" / f"lidar_{seq.name}.png"
    cmap = "turbo"
    vmin, vmax = float(np.percentile(values, 1)), float(np.percentile(values, 99))
    if vmax <= vmin:
        vmax = vmin + 1.0
    ext = _extent(sc.xyz)
    # far returns first, so nearer points are drawn over them
    order = np.argsort(values, kind="stable")
    xyz, val = sc.xyz[order], values[order]
    with style():
        fig = figure(12.0, 5.6)
        # the colourbar in its own column: it never covers an axes
        grid = fig.add_gridspec(1, 3, width_ratios=(1.0, 1.0, 0.035))
        ax3 = fig.add_subplot(grid[0, 0], projection="3d")
        ax2 = fig.add_subplot(grid[0, 1])
        cax = fig.add_subplot(grid[0, 2])
        keep = np.linspace(0, xyz.shape[0] - 1, min(xyz.shape[0], MAX_POINTS_3D)).astype(int)
        ax3.scatter(
            xyz[keep, 0],
            xyz[keep, 1],
            xyz[keep, 2],
            c=val[keep],
            cmap=cmap,
            vmin=vmin,
            vmax=vmax,
            s=1.0,
            linewidths=0,
            depthshade=False,
        )
        ax3.set_proj_type("persp", focal_length=0.35)
        zlo, zhi = float(xyz[:, 2].min()), float(xyz[:, 2].max())  # every point inside
        ax3.set_xlim(-ext, ext)
        ax3.set_ylim(-ext, ext)
        ax3.set_zlim(zlo, max(zhi, zlo + 0.1))
        ax3.set_box_aspect((1.0, 1.0, max(0.3, min(1.0, (zhi - zlo) / (2 * ext)))))
        ax3.view_init(elev=28, azim=-150)
        ax3.scatter(0, 0, 0, color="k", marker="^", s=40, depthshade=False, label="sensor")
        ax3.set_xlabel("x [m]")
        ax3.set_ylabel("y [m]")
        ax3.zaxis.set_rotate_label(False)  # upright, not mirrored by the view angle
        ax3.set_zlabel("z [m]", rotation=90)
        from matplotlib.ticker import MaxNLocator

        ax3.zaxis.set_major_locator(MaxNLocator(4))
        ax3.legend(loc="upper left", fontsize=7)
        ax3.set_title("Perspective view (sensor frame)", y=1.0, pad=-4)
        sc2 = ax2.scatter(
            xyz[:, 0],
            xyz[:, 1],
            c=val,
            cmap=cmap,
            vmin=vmin,
            vmax=vmax,
            s=0.8,
            linewidths=0,
            rasterized=True,
        )
        ax2.plot(0, 0, "k^", ms=7, label="sensor (x forward)")
        ax2.set_xlim(-ext, ext)
        ax2.set_ylim(-ext, ext)
        ax2.set_aspect("equal", adjustable="box")
        ax2.set_xlabel("x (forward) [m]")
        ax2.set_ylabel("y (left) [m]")
        ax2.legend(loc="upper right", fontsize=7)
        t = sc.t_ns * 1e-9
        ax2.set_title("Bird's-eye view (sensor frame)")
        fig.suptitle(
            f"LiDAR '{seq.name}' scan {i} of 0..{len(seq) - 1} ({seq.paths[i].name}), "
            f"t = {t:.3f} s, "
            f"{sc.xyz.shape[0]:,} returns",
            fontsize=10,
        )
        cb = fig.colorbar(sc2, cax=cax)
        cb.set_label(vlabel)
        return save_figure(fig, out, tight=True)
