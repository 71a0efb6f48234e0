"""Top-view preview of a scene (matplotlib): object outlines, heights, goal and approach zone."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from roslan.errors import OutputError
from roslan.scene.model import Scene
from roslan.trajectory.frames import rpy_to_matrix

__all__ = ["scene_info", "write_preview"]


def scene_info(scene: Scene) -> str:
    """Human-readable summary: objects (triangles, material, bounds), totals, goal."""
    lines = [f"scene {scene.name!r}: {len(scene.objects)} objects, {scene.n_triangles} triangles"]
    lo, hi = scene.bounds
    lines.append(
        f"bounds: x [{lo[0]:.2f}, {hi[0]:.2f}]  y [{lo[1]:.2f}, {hi[1]:.2f}]  "
        f"z [{lo[2]:.2f}, {hi[2]:.2f}] m"
    )
    gp, gr = scene.goal_position, scene.goal_rpy
    lines.append(
        f"goal: position [{gp[0]:.3f} {gp[1]:.3f} {gp[2]:.3f}] m, "
        f"rpy [{gr[0]:.3f} {gr[1]:.3f} {gr[2]:.3f}] rad"
    )
    w = max([len(o.name) for o in scene.objects] + [6])
    lines.append(f"{'object':<{w}}  {'triangles':>9}  {'material':<16} bounds min .. max (m)")
    for o in scene.objects:
        a, b = o.vertices.min(axis=0), o.vertices.max(axis=0)
        tex = "+tex" if o.material.texture is not None else ""
        lines.append(
            f"{o.name:<{w}}  {o.n_triangles:>9}  {o.material.name + tex:<16} "
            f"[{a[0]:.1f} {a[1]:.1f} {a[2]:.1f}] .. [{b[0]:.1f} {b[1]:.1f} {b[2]:.1f}]"
        )
    return "\n".join(lines)


def write_preview(scene: Scene, path: Path, *, dpi: int = 120) -> None:
    """PNG top view: every triangle projected on x-y, coloured by its top height (floors
    and roofs left out), the goal with the goal frame's x axis, and the approach zone.

    Raises:
        OutputError: the file cannot be written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    from roslan.scene.builtin import APPROACH_ZONE

    lo, hi = scene.bounds
    area = max(float((hi[0] - lo[0]) * (hi[1] - lo[1])), 1e-9)
    tris, tops = [], []
    for o in scene.objects:
        v = o.vertices.astype(np.float64)
        a, b = v.min(axis=0), v.max(axis=0)
        # floors, roofs and ground slabs would hide everything: leave them out
        if (b[0] - a[0]) * (b[1] - a[1]) > 0.6 * area and b[2] - a[2] < 1.0:
            continue
        t = v[o.faces]
        tris.append(t[:, :, :2])
        tops.append(t[:, :, 2].max(axis=1))
    fig, ax = plt.subplots(figsize=(9, 7))
    if tris:
        allt = np.concatenate(tris)
        allz = np.concatenate(tops)
        order = np.argsort(allz, kind="stable")  # tall parts drawn last, on top
        pc = PolyCollection(
            list(allt[order]), array=allz[order], cmap="viridis", edgecolors="face", linewidths=0.2
        )
        ax.add_collection(pc)
        fig.colorbar(pc, ax=ax, label="top z of each triangle (m)")
    g = np.asarray(scene.goal_position, dtype=np.float64)
    R = rpy_to_matrix(np.asarray(scene.goal_rpy, dtype=np.float64))
    (x0, x1), (y0, y1) = APPROACH_ZONE
    zone = np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0], [x0, y0, 0]]) @ R.T + g
    ax.plot(zone[:, 0], zone[:, 1], "r--", lw=1, label="approach zone (F)")
    ax.plot(g[0], g[1], "r*", ms=14, label="goal")
    ax.arrow(g[0], g[1], 2.0 * R[0, 0], 2.0 * R[1, 0], color="r", width=0.08)
    pad = 0.05 * max(float(hi[0] - lo[0]), float(hi[1] - lo[1]), 1.0)
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m, world ENU)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{scene.name}: {len(scene.objects)} objects, {scene.n_triangles} triangles")
    ax.legend(loc="upper right", fontsize=8)
    try:
        fig.savefig(path, dpi=dpi)
    except OSError as err:
        msg = f"{path}: cannot write the preview: {err}"
        raise OutputError(msg) from err
    finally:
        plt.close(fig)
