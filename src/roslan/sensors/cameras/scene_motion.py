"""The scene's own motion as the cameras' motion fields and flows read it.

The exact image motion of a pixel depends on the camera's twist and on the motion of the
surface point it sees. Both the event camera's motion field (its ``optic_flow`` topic
and the ``optical_flow`` sampler's flow bound) and the DSEC flow maps read the second
through :class:`~roslan.scene.model.SceneAt` (``point_velocity``, ``carry``) and nowhere
else, so a moving object (a :class:`~roslan.scene.pose.PoseTrack` that is not constant)
changes them in one place. A static scene (every scene today) takes the fast path: the
camera's own velocity, the same array, and the flow of a static world.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from roslan.errors import RenderError
from roslan.scene.model import SceneAt

__all__ = ["object_ids", "relative_velocity", "require_ids"]

F64 = NDArray[np.float64]


def require_ids(view: SceneAt, ids: NDArray[np.integer] | None, what: str) -> NDArray[np.integer]:
    """``ids`` (the object index each pixel sees), or a RenderError naming the moving
    scene when there are none (``what``: who needs them)."""
    if ids is None:
        msg = (
            f"scene {view.scene.name!r}: its objects move, and {what} needs the object each "
            "pixel sees; the renderer draws no object ids yet (a static scene needs none)"
        )
        raise RenderError(msg)
    return ids


def object_ids(view: SceneAt, tri_ids: NDArray[np.integer]) -> NDArray[np.int32]:
    """(H, W) int32 index into ``Scene.objects`` of the object each pixel sees (-1:
    nothing) from a render's triangle ids (:attr:`RenderResult.ids
    <roslan.render.base.RenderResult.ids>`: 1 + the scene triangle, 0: nothing)."""
    owner = view.scene.triangles[2]
    ids = np.asarray(tri_ids).astype(np.int64)
    if owner.shape[0] == 0:
        return np.full(ids.shape, -1, np.int32)
    obj = owner[np.clip(ids - 1, 0, owner.shape[0] - 1)]
    return np.where(ids > 0, obj, -1).astype(np.int32)


def relative_velocity(
    view: SceneAt,
    T_world_cam: F64,
    v_cam: F64,
    depth: NDArray[np.floating],
    rays: tuple[F64, F64],
    ids: NDArray[np.integer] | None,
) -> F64:
    """The camera's velocity relative to the surface point each pixel sees, in the
    optical frame: ``v_cam`` (3,) itself for a static scene; else (H, W, 3)
    ``v_cam - R_cw V(P)``, ``V`` the world velocity of pixel ``(x z, y z, z)``'s point
    (:meth:`SceneAt.point_velocity`; 0 where nothing is hit). A point moving with ``V``
    moves in the camera as if the camera moved with ``-V``: the motion field's formula
    with this velocity per pixel is the exact image motion."""
    if view.is_static:
        return v_cam
    own = require_ids(view, ids, "the motion field")
    z = np.asarray(depth, np.float64)
    hit = np.isfinite(z) & (z > 0)
    x, y = rays
    T = np.asarray(T_world_cam, np.float64)
    P_c = np.stack([x[hit] * z[hit], y[hit] * z[hit], z[hit]], axis=1)
    V_w = view.point_velocity(P_c @ T[:3, :3].T + T[:3, 3], np.asarray(own)[hit])
    out = np.empty((*z.shape, 3))
    out[...] = np.asarray(v_cam, np.float64)
    out[hit] -= V_w @ T[:3, :3]
    return out
