"""Independent geometry for the label tests: point-to-mesh distances with trimesh's
closest-point-on-triangle (``trimesh.triangles.closest_point``; no spatial index needed)."""

from __future__ import annotations

import numpy as np
import trimesh


def mesh_distance(triangles: np.ndarray, points: np.ndarray, block: int = 1 << 20) -> np.ndarray:
    """(N,) distance of each point to the nearest of ``triangles`` (T, 3, 3), m."""
    tri = np.asarray(triangles, dtype=np.float64)
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    out = np.full(pts.shape[0], np.inf)
    if tri.shape[0] == 0:
        return out
    per = max(1, block // tri.shape[0])
    for i in range(0, pts.shape[0], per):
        p = pts[i : i + per]
        rep_t = np.broadcast_to(tri[None], (p.shape[0], *tri.shape)).reshape(-1, 3, 3)
        rep_p = np.repeat(p, tri.shape[0], axis=0)
        q = trimesh.triangles.closest_point(rep_t, rep_p)
        d = np.linalg.norm(q - rep_p, axis=1).reshape(p.shape[0], tri.shape[0])
        out[i : i + per] = d.min(axis=1)
    return out
