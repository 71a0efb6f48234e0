"""Preview of a scene: a top view (matplotlib: object outlines coloured by height, goal,
approach zone) beside two views rendered by the simulation's own renderer (the approach
to the goal, and a high oblique overview), so a scene file can be checked by eye before
anything is simulated in it (``roslan scene preview`` and ``roslan scene info``)."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from roslan.errors import OutputError, RenderError
from roslan.frames import rpy_to_matrix
from roslan.scene.model import Scene

__all__ = ["look_at", "render_views", "scene_info", "write_preview"]

PREVIEW_FOV_DEG = 70.0
"""Horizontal field of view of the rendered views."""


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
    lines += _class_lines(scene)
    return "\n".join(lines)


def _class_lines(scene: Scene) -> list[str]:
    """The scene's classes in use (id, name, instances, triangles) and the unlabelled rest."""
    from roslan.scene.instances import scene_labels

    labels = scene_labels(scene)
    counts = labels.instance_counts()
    tris = np.bincount(labels.triangle_class, minlength=len(labels.classes))
    used = [c for c in labels.classes if c.name in counts]
    lines = [
        f"classes: {len(used)} in use, {len(labels.instances)} instances"
        f"{'' if tris[0] == 0 else f', {tris[0]} triangles unlabelled (class 0)'}"
    ]
    w = max([len(c.name) for c in used] + [5])
    lines.append(f"{'id':>3}  {'class':<{w}}  {'instances':>9}  {'triangles':>9}")
    for c in used:
        lines.append(f"{c.id:>3}  {c.name:<{w}}  {counts[c.name]:>9}  {int(tris[c.id]):>9}")
    return lines


def look_at(
    eye: NDArray[np.floating], target: NDArray[np.floating], up: tuple[float, ...] = (0, 0, 1)
) -> NDArray[np.float64]:
    """(4, 4) pose in the world of a camera *optical* frame (z forward, x right, y down) at
    ``eye`` looking at ``target``, with ``up`` (world) pointing up in the image."""
    e = np.asarray(eye, dtype=np.float64)
    z = np.asarray(target, dtype=np.float64) - e
    z /= max(float(np.linalg.norm(z)), 1e-12)
    u = np.asarray(up, dtype=np.float64)
    if abs(float(z @ u)) > 0.999 * float(np.linalg.norm(u)):  # looking straight up/down
        u = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(z, u)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)  # down in the image
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, y, z])
    T[:3, 3] = e
    return T


def _viewpoints(scene: Scene) -> list[tuple[str, NDArray[np.float64], NDArray[np.float64]]]:
    """(title, eye, target): the approach (from the far end of the approach zone, 4.5 m
    up, as the default landing starts) and a high oblique overview from a corner of the
    bounds towards the middle of the floor."""
    from roslan.scene.builtin import APPROACH_ZONE

    g = np.asarray(scene.goal_position, dtype=np.float64)
    R = rpy_to_matrix(np.asarray(scene.goal_rpy, dtype=np.float64))
    (x0, _), _ = APPROACH_ZONE
    eye = g + R @ np.array([0.7 * x0, 0.0, 0.0]) + np.array([0.0, 0.0, 4.5])
    lo, hi = scene.bounds
    centre = 0.5 * (lo + hi)
    size = hi - lo
    # inside the bounds (walls and roofs of enclosed scenes would hide everything)
    high = np.array([centre[0] - 0.42 * size[0], centre[1] - 0.42 * size[1], lo[2] + 0.8 * size[2]])
    centre[2] = lo[2]
    return [("approach to the goal", eye, g), ("overview", high, centre)]


def render_views(
    scene: Scene, width: int = 480, height: int = 360
) -> list[tuple[str, NDArray[np.uint8]]]:
    """The scene seen from :func:`_viewpoints` by the simulation's renderer: a list of
    (title, (height, width, 3) uint8 sRGB image).

    Raises:
        RenderError: no OpenGL (EGL) is available.
    """
    from roslan.render.gl import get_renderer
    from roslan.sensors.cameras.encoding import encode_linear, srgb_lut

    r = get_renderer(scene)
    f = 0.5 * width / math.tan(math.radians(PREVIEW_FOV_DEG) / 2)
    K = np.array([[f, 0.0, (width - 1) / 2], [0.0, f, (height - 1) / 2], [0.0, 0.0, 1.0]])
    lut = srgb_lut("srgb")
    out = []
    for title, eye, target in _viewpoints(scene):
        res = r.render(look_at(eye, target), K, width, height, color=True, depth=False)
        assert res.color is not None
        out.append((title, encode_linear(res.color, lut)))
    return out


_HEIGHT_IN = 7.0
"""Height of the preview figure (inches)."""


def _column_widths(
    map_aspect: float, views: list[tuple[str, NDArray[np.uint8]]]
) -> tuple[float, float]:
    """Widths (inches) of the top view's column and of the rendered views' column that
    the figure's height fills: the top view at its aspect (width / height) plus its
    colour bar, the views stacked at theirs, so neither column leaves a blank strip."""
    titles, colorbar = 0.45, 1.5  # per row: a title line; the colour bar and its labels
    h, w = views[0][1].shape[:2]
    right = (w / h) * (_HEIGHT_IN / len(views) - titles) + 0.2
    left = map_aspect * (_HEIGHT_IN - 2.0 * titles) + colorbar
    return left, right


def write_preview(scene: Scene, path: Path, *, dpi: int = 120, rendered: bool = True) -> None:
    """PNG top view: every triangle projected on x-y, coloured by its top height (floors
    and roofs left out), the goal with the goal frame's x axis, and the approach zone;
    with ``rendered``, beside it the views of :func:`render_views` (left out, with a
    warning, where no OpenGL is available).

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
    views: list[tuple[str, NDArray[np.uint8]]] = []
    if rendered:
        try:
            views = render_views(scene)
        except RenderError as err:
            warnings.warn(f"preview without rendered views: {err}", stacklevel=2)
    g = np.asarray(scene.goal_position, dtype=np.float64)
    R = rpy_to_matrix(np.asarray(scene.goal_rpy, dtype=np.float64))
    (x0, x1), (y0, y1) = APPROACH_ZONE
    zone = np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0], [x0, y0, 0]]) @ R.T + g
    # scaled to what is drawn (objects, goal, approach zone), not to a wide ground slab
    shown = [zone[:, :2]] + ([np.concatenate(tris).reshape(-1, 2)] if tris else [])
    pts = np.concatenate(shown)
    lo2, hi2 = pts.min(axis=0), pts.max(axis=0)
    pad = 0.05 * max(float(hi2[0] - lo2[0]), float(hi2[1] - lo2[1]), 1.0)
    lo2, hi2 = lo2 - pad, hi2 + pad
    if views:
        left, right = _column_widths(float((hi2[0] - lo2[0]) / (hi2[1] - lo2[1])), views)
        fig = plt.figure(figsize=(left + right, _HEIGHT_IN), layout="constrained")
        grid = fig.add_gridspec(len(views), 2, width_ratios=(left, right))
        ax = fig.add_subplot(grid[:, 0])
        for k, (title, img) in enumerate(views):
            axr = fig.add_subplot(grid[k, 1])
            axr.imshow(img)
            axr.set_title(f"rendered: {title}", fontsize=9)
            axr.set_axis_off()
    else:
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
    ax.plot(zone[:, 0], zone[:, 1], "r--", lw=1, label="approach zone (F)")
    ax.plot(g[0], g[1], "r*", ms=14, label="goal")
    ax.arrow(g[0], g[1], 2.0 * R[0, 0], 2.0 * R[1, 0], color="r", width=0.08)
    ax.set_xlim(lo2[0], hi2[0])
    ax.set_ylim(lo2[1], hi2[1])
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
