"""Perches (bar, branch, pipe) placed at a goal for perching trajectories.

A perch's frame has its origin at the contact point on top of the perch (the goal)
and its long axis along the frame's y axis, i.e. across the approach, which flies
along the goal frame's +x. Optional posts hold it up from the ground (world z = 0).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from roslan.scene import textures as tx
from roslan.scene.classes import PartLabels
from roslan.scene.mesh import (
    LocalMesh,
    box,
    cylinder_between,
    merge,
    place,
    pose_matrix,
    sphere,
    transformed,
)
from roslan.scene.model import Material, Scene, SceneObject

__all__ = ["DEFAULT_RADIUS", "PERCH_TYPES", "PerchKind", "add_perch", "perch_object"]

PerchKind = Literal["bar", "branch", "pipe"]
PERCH_TYPES: tuple[str, ...] = ("bar", "branch", "pipe")
DEFAULT_RADIUS = {"bar": 0.02, "branch": 0.03, "pipe": 0.05}
"""Half the side of the bar's square section, or the radius of branch and pipe (m)."""


def _branch(length: float, radius: float, rng: np.random.Generator) -> LocalMesh:
    """A slightly crooked, tapering branch with a few twigs, top of its middle at the origin."""
    n = 8
    y = np.linspace(-length / 2.0, length / 2.0, n + 1)
    # wobble grows away from the middle, so the contact point stays exactly at the origin
    w = (y / (length / 2.0)) ** 2
    x = w * rng.uniform(-0.08, 0.08)
    z = -radius + w * rng.uniform(-0.06, 0.04)
    r = radius * (1.0 - 0.35 * np.abs(y) / (length / 2.0))
    parts = []
    for i in range(n):
        parts.append(
            cylinder_between(
                (x[i], y[i], z[i]), (x[i + 1], y[i + 1], z[i + 1]), float(max(r[i], r[i + 1])), 16
            )
        )
    for i in range(1, n):
        joint = sphere(float(max(r[i - 1], r[i])), 12)
        parts.append(transformed(joint, pose_matrix((x[i], y[i], z[i]))))
    # twigs leave the outer parts away from the approach side (+x) and downwards
    for i in (1, 2, n - 2, n - 1):
        ang = rng.uniform(-0.6, 0.3)
        ln = rng.uniform(0.15, 0.3)
        d = np.array([math.cos(ang), rng.uniform(-0.3, 0.3), math.sin(ang)])
        p0 = np.array([x[i], y[i], z[i]])
        parts.append(cylinder_between(p0, p0 + ln * d / np.linalg.norm(d), float(r[i]) * 0.4, 8))
    return merge(parts)


def perch_object(
    kind: str,
    pose: NDArray[np.float64],
    *,
    length: float = 1.5,
    radius: float | None = None,
    supports: bool = True,
    name: str = "perch",
    seed: int = 0,
) -> SceneObject:
    """The perch as one :class:`SceneObject` whose top touches ``pose``'s origin.

    Args:
        kind: ``bar``, ``branch`` or ``pipe``.
        pose: (4, 4) ``T_world_perch`` (usually the goal pose).
        length: along the perch frame's y axis, m.
        radius: see :data:`DEFAULT_RADIUS`.
        supports: add two posts from the perch ends down to world z = 0.
    """
    if kind not in PERCH_TYPES:
        msg = f"perch type {kind!r} unknown; allowed: {', '.join(PERCH_TYPES)}"
        raise ValueError(msg)
    r = float(radius if radius is not None else DEFAULT_RADIUS[kind])
    rng = tx.rng_for(seed, f"perch:{name}")
    half = length / 2.0
    if kind == "pipe":
        body = cylinder_between((0.0, -half, -r), (0.0, half, -r), r, 32)
        mat = Material(
            (0.75, 0.55, 0.2), tx.painted_metal(seed, (0.9, 0.65, 0.25)), 2.0, 0.6, "perch_pipe"
        )
    elif kind == "bar":
        body = box((2 * r, length, 2 * r), (0.0, 0.0, -r))
        mat = Material((1.0, 1.0, 1.0), tx.hazard(), 4.0, 0.7, "perch_bar")
    else:
        body = _branch(length, r, rng)
        mat = Material((1.0, 1.0, 1.0), tx.bark(seed), 4.0, 0.3, "perch_branch")
    parts = [body]
    height = float(pose[2, 3]) - 2 * r
    if supports and height > 0.05:
        post = max(r, 0.03)
        for y in (-half + post, half - post):
            parts.append(box((2 * post, 2 * post, height), (0.0, y, -2 * r - height / 2.0)))
    mesh = merge(parts)
    obj = place(name, mesh, mat, pose, source=f"builtin:perch:{kind}")
    return replace(obj, labels=PartLabels.whole("perch", mesh.n_triangles))


def add_perch(
    scene: Scene,
    kind: str,
    pose: NDArray[np.float64] | None = None,
    *,
    length: float = 1.5,
    radius: float | None = None,
    supports: bool = True,
    name: str = "perch",
    seed: int = 0,
) -> Scene:
    """A copy of ``scene`` with a perch whose top is at ``pose`` (default: the scene's goal).

    Args:
        pose: (4, 4) ``T_world_perch``; None places it at ``scene.goal_position`` with
            ``scene.goal_rpy``, its axis across the approach.
    Raises:
        ValueError: unknown kind or a name already used in the scene.
    """
    if any(o.name == name for o in scene.objects):
        msg = f"object name {name!r} already used in scene {scene.name!r}"
        raise ValueError(msg)
    T = (
        pose_matrix(scene.goal_position, scene.goal_rpy)
        if pose is None
        else np.asarray(pose, dtype=np.float64)
    )
    obj = perch_object(
        kind, T, length=length, radius=radius, supports=supports, name=name, seed=seed
    )
    return replace(scene, objects=(*scene.objects, obj))
