"""Trajectory clearance: does the path touch scene geometry before touchdown?"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Any

import numpy as np

from roslan.scene.model import Scene
from roslan.trajectory import Trajectory

__all__ = ["check_clearance"]


@lru_cache(maxsize=4)
def _embree(scene: Scene) -> Any:
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    verts, faces, _ = scene.triangles
    es = rtcs.EmbreeScene()
    TriangleMesh(
        es,
        np.ascontiguousarray(verts, dtype=np.float32),
        np.ascontiguousarray(faces, dtype=np.int32),
    )
    return es


def check_clearance(
    scene: Scene,
    trajectory: Trajectory,
    *,
    body_radius: float = 0.1,
    goal_tolerance: float = 0.3,
    step: float = 0.02,
) -> str | None:
    """Check that the flown path up to touchdown passes through no scene geometry.

    The closed-form path is sampled every ``step`` metres (at most) from t = 0 to the
    touchdown time; each segment between samples is cast as 7 rays (the centre and
    offsets of ``body_radius`` along the world axes) against the scene's triangles with
    Embree. Hits within ``goal_tolerance`` (m) of the goal are ignored: landing on the
    marker or perch is the point.

    Returns:
        None if clear, else ``"trajectory hits object 'NAME' at t = T s (position [x y z] m)"``.
    """
    if scene.n_triangles == 0:
        return None
    T = float(trajectory.T)
    coarse = trajectory.state(np.linspace(0.0, T, 2001)).position
    length = float(np.linalg.norm(np.diff(coarse, axis=0), axis=1).sum())
    n = int(min(max(math.ceil(length / step), 2000), 400_000))
    t = np.linspace(0.0, T, n + 1)
    p = trajectory.state(t).position
    goal = np.asarray(trajectory.p_world_goal, dtype=np.float64)
    # skip the segments inside the goal zone (both ends near the goal)
    near = np.linalg.norm(p - goal, axis=1) < goal_tolerance
    keep = ~(near[:-1] & near[1:])
    p0, p1, t0, t1 = p[:-1][keep], p[1:][keep], t[:-1][keep], t[1:][keep]
    d = p1 - p0
    seg = np.linalg.norm(d, axis=1)
    moving = seg > 1e-12
    p0, d, seg, t0, t1 = p0[moving], d[moving], seg[moving], t0[moving], t1[moving]
    if p0.shape[0] == 0:
        return None
    u = d / seg[:, None]
    offsets = np.concatenate([np.zeros((1, 3)), body_radius * np.eye(3), -body_radius * np.eye(3)])
    origins = (p0[None, :, :] + offsets[:, None, :]).reshape(-1, 3)
    dirs = np.broadcast_to(u, (offsets.shape[0], *u.shape)).reshape(-1, 3)
    lengths = np.broadcast_to(seg, (offsets.shape[0], seg.shape[0])).reshape(-1)
    es = _embree(scene)
    res = es.run(
        np.ascontiguousarray(origins, dtype=np.float32),
        np.ascontiguousarray(dirs, dtype=np.float32),
        output=1,
        dists=np.ascontiguousarray(lengths, dtype=np.float32),
    )
    prim = np.asarray(res["primID"]).reshape(offsets.shape[0], -1)
    tfar = np.asarray(res["tfar"]).reshape(offsets.shape[0], -1)
    hit_any = (prim >= 0).any(axis=0)
    if not hit_any.any():
        return None
    hit_points = p0[:, None, :] + 0.0  # placeholder shape (N, 1, 3)
    del hit_points
    # report the earliest hit; its point must be out of the goal zone too
    order = np.flatnonzero(hit_any)
    owner = scene.triangles[2]
    for i in order:
        rays = np.flatnonzero(prim[:, i] >= 0)
        j = rays[np.argmin(tfar[rays, i])]
        frac = float(np.clip(tfar[j, i] / seg[i], 0.0, 1.0))
        where = p0[i] + frac * d[i]
        if np.linalg.norm(where - goal) < goal_tolerance:
            continue
        th = float(t0[i] + frac * (t1[i] - t0[i]))
        name = scene.objects[int(owner[int(prim[j, i])])].name
        x, y, z = where
        return (
            f"trajectory hits object {name!r} at t = {th:.3f} s "
            f"(position [{x:.2f} {y:.2f} {z:.2f}] m)"
        )
    return None
