"""Clearance: does any part of the vehicle or any sensor enter scene geometry?

The vehicle is a set of labelled points rigidly attached to base_link: points on its
body's surface (:func:`roslan.vehicle.body_points`), every sensor's origin, and the
corners and centre of every rendering sensor's near-clipping rectangle (its
``near_clip`` in front of the optical centre). Each point's path over the whole run,
hold included, is cut into segments of at most ``step`` metres and cast against the
scene's triangles through the run's ray caster (``caster``: the same robust Embree
:class:`~roslan.render.raycast.RayCaster` the beam sensors cast with, handed down by the
caller, :class:`roslan.render.backends.SceneBackends`, so that clearance, contact and the
sensors see the same hits); at the first and the last instant a segment also joins
base_link to every point (nothing may lie between base_link and its own sensors). Any
hit is a collision: unlike the contact points (feet, grasp point), none of these points
may touch a surface, so no tolerance around the goal is needed. A point held inside a
closed object without crossing its surface (a body wholly inside a box), and a contact
point more than 1 mm inside one at the start, is a collision too
(:mod:`roslan.scene.containment`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray

from roslan.scene.model import Scene
from roslan.trajectory import Trajectory

__all__ = [
    "PathHit",
    "SegmentCaster",
    "VehiclePoints",
    "check_clearance",
    "path_hit",
    "segment_hits",
    "vehicle_points",
]

F64 = NDArray[np.float64]

_MAX_RAYS = 2_000_000
"""Rays per Embree call (bounds the memory of long runs)."""


class SegmentCaster(Protocol):
    """What the clearance check needs of a ray caster (a
    :class:`~roslan.render.base.BeamCaster`): the first hit of each ray within its range,
    a record with ``distance`` and ``triangle`` (N,) arrays."""

    def cast(
        self, origins: Any, directions: Any, max_range: Any = ..., *, t: Any = None
    ) -> Any: ...


class VehiclePoints(NamedTuple):
    """Points rigidly attached to base_link and what each one is."""

    points: F64
    """(K, 3) positions in base_link, m."""
    labels: tuple[str, ...]
    """(K,) e.g. ``"the body"``, ``"sensor 'sonar' (origin)"``."""


def vehicle_points(vehicle: Any = None, sensors: Sequence[Any] = ()) -> VehiclePoints:
    """The points the clearance check keeps out of the scene.

    Args:
        vehicle: a :class:`roslan.vehicle.VehicleConfig` (None: the default vehicle).
        sensors: sensor configs: each one's ``pose`` origin, and for rendering sensors
            (camera-like configs: those with ``calibration_cameras()``, as
            :class:`roslan.sensors.cameras.config.CameraIntrinsics`) the near-plane
            corners and centre of every eye.
    """
    from roslan.vehicle import VehicleConfig, body_points

    v = vehicle if vehicle is not None else VehicleConfig()
    pts: list[F64] = [body_points(v.body)]
    labels: list[str] = ["the body"] * pts[0].shape[0]
    for s in sensors:
        name = str(s.name)
        pts.append(np.asarray(s.pose.position, dtype=np.float64)[None, :])
        labels.append(f"sensor {name!r} (origin)")
        if hasattr(s, "calibration_cameras"):
            near = float(getattr(s, "near_clip", 0.01))
            for cam in s.calibration_cameras():
                m = cam.model
                uv = np.array(
                    [
                        [-0.5, -0.5],
                        [m.width - 0.5, -0.5],
                        [-0.5, m.height - 0.5],
                        [m.width - 0.5, m.height - 0.5],
                    ]
                )
                xy = np.vstack([m.undistort_normalized(uv), [[0.0, 0.0]]])
                corners = np.column_stack([xy * near, np.full(xy.shape[0], near)])
                T = cam.T_base_optical
                world = corners @ T[:3, :3].T + T[:3, 3]
                if cam.name != name:  # a stereo eye: its optical centre too
                    pts.append(T[:3, 3][None, :])
                    labels.append(f"sensor {name!r} ({cam.name} optical centre)")
                pts.append(world)
                what = f"{cam.name} near plane" if cam.name != name else "near plane"
                labels += [f"sensor {name!r} ({what}, near_clip {near:g} m)"] * 5
    return VehiclePoints(np.concatenate(pts), tuple(labels))


def segment_hits(
    caster: SegmentCaster, origins: F64, ends: F64, t: float | F64 = 0.0
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """First hit of each segment ``origins -> ends`` (N, 3): the triangle (-1 = none) and
    the fraction of the segment at the hit (0 for none), cast through ``caster`` against
    the scene at each segment's trajectory time ``t`` (s, scalar or (N,): its start)."""
    d = ends - origins
    seg = np.linalg.norm(d, axis=1)
    moving = seg > 1e-9
    prim = np.full(seg.shape[0], -1, dtype=np.int64)
    frac = np.zeros(seg.shape[0])
    if not moving.any():
        return prim, frac
    idx = np.flatnonzero(moving)
    u = d[idx] / seg[idx, None]
    ts = np.asarray(t, dtype=np.float64)
    hits = caster.cast(
        np.ascontiguousarray(origins[idx], dtype=np.float32),
        np.ascontiguousarray(u, dtype=np.float32),
        np.ascontiguousarray(seg[idx], dtype=np.float32),
        t=ts if ts.ndim == 0 else ts[idx],
    )
    p = np.asarray(hits.triangle).astype(np.int64)
    tf = np.where(p >= 0, np.asarray(hits.distance, dtype=np.float64), 0.0)
    prim[idx] = p
    frac[idx] = np.where(p >= 0, np.clip(tf / seg[idx], 0.0, 1.0), 0.0)
    return prim, frac


def check_clearance(
    scene: Scene,
    trajectory: Trajectory,
    *,
    caster: SegmentCaster,
    vehicle: Any = None,
    sensors: Sequence[Any] = (),
    step: float = 0.02,
) -> str | None:
    """Check that no part of the vehicle and no sensor enters scene geometry.

    Args:
        scene: the scene.
        caster: the scene's ray caster (:meth:`roslan.render.backends.SceneBackends.
            caster`, or :func:`roslan.render.raycast.get_raycaster`).
        trajectory: base_link's trajectory (built with the vehicle's contact offset,
            :func:`roslan.vehicle.base_link_trajectory`), checked from 0 to its end.
        vehicle: the :class:`~roslan.vehicle.VehicleConfig` (None: the default body).
        sensors: sensor configs whose origins and near planes are checked too.
        step: longest path segment of any point between two checked instants, m.

    Returns:
        None if clear, else ``"<what> enters object 'NAME' at t = T s (position [x y z]
        m)"`` for the earliest collision.
    """
    if scene.n_triangles == 0:
        return None
    vp = vehicle_points(vehicle, sensors)
    P = vp.points
    T_end = float(trajectory.duration)
    t_td = float(trajectory.T)
    # instants: dense enough that no point moves more than `step` between two of them
    coarse_t = np.linspace(0.0, t_td, 2001)
    st = trajectory.state(coarse_t)
    world = st.position[:, None, :] + np.einsum("nij,kj->nki", st.R_world_body, P)
    length = float(np.linalg.norm(np.diff(world, axis=0), axis=2).sum(axis=0).max())
    n = int(min(max(math.ceil(length / step), 2000), 400_000))
    t = np.linspace(0.0, t_td, n + 1)
    if T_end > t_td:
        t = np.append(t, T_end)
    owner = scene.triangles[2]
    K = P.shape[0]

    def message(label: str, prim: int, where: F64, when: float) -> str:
        name = scene.objects[int(owner[prim])].name
        x, y, z = where
        return (
            f"{label} enters object {name!r} at t = {when:.3f} s "
            f"(position [{x:.3f} {y:.3f} {z:.3f}] m)"
        )

    def static(when: float) -> str | None:
        # base_link -> every point at one instant
        s1 = trajectory.state([when])
        pw = s1.position[0] + P @ s1.R_world_body[0].T
        o = np.broadcast_to(s1.position[0], pw.shape).copy()
        prim, frac = segment_hits(caster, o, pw, when)
        hit = np.flatnonzero(prim >= 0)
        if not hit.size:
            return None
        k = int(hit[0])
        where = s1.position[0] + frac[k] * (pw[k] - s1.position[0])
        return message(vp.labels[k], int(prim[k]), where, when)

    first = _inside(scene, st, vp, vehicle, slice(0, 1)) or static(0.0)
    if first is not None:
        return first
    # every point's path, in blocks of instants
    block = max(2, _MAX_RAYS // K)
    for i0 in range(0, t.shape[0] - 1, block - 1):
        tb = t[i0 : i0 + block]
        sb = trajectory.state(tb)
        hit = path_hit(scene, caster, P, tb, sb.position, sb.R_world_body)
        if hit is not None:
            return message(vp.labels[hit.point], hit.triangle, hit.where, hit.time)
    # later on, a contact point may sink into what it lands on (a floor marking's paint)
    return _inside(scene, st, vp, vehicle, slice(None, None, 20), feet=False) or static(T_end)


def _inside(
    scene: Scene, st: Any, vp: VehiclePoints, vehicle: Any, pick: slice, *, feet: bool = True
) -> str | None:
    """A body, sensor or (``feet``) contact point inside a closed object at the instants
    ``pick`` of the states ``st`` (:mod:`roslan.scene.containment`): a point that never
    crosses a surface (the path casts find every one crossed) but is held inside."""
    from roslan.scene.containment import vehicle_contacts, vehicle_inside
    from roslan.vehicle import VehicleConfig

    contacts, names = vehicle_contacts(vehicle if vehicle is not None else VehicleConfig())
    if not feet:
        contacts, names = contacts[:0], ()
    found = vehicle_inside(
        scene, st.t[pick], st.position[pick], st.R_world_body[pick], vp.points, vp.labels,
        contacts, names,
    )  # fmt: skip
    if found is None:
        return None
    when, label, name, (x, y, z) = found
    return (
        f"{label} lies inside object {name!r} at t = {when:.3f} s "
        f"(position [{x:.3f} {y:.3f} {z:.3f}] m): inside a closed object is a collision"
    )


class PathHit(NamedTuple):
    """The earliest hit of points moving with base_link (:func:`path_hit`)."""

    point: int
    """Index of the point (row of ``points``)."""
    triangle: int
    """The scene triangle hit."""
    obj: str
    """Name of the scene object hit."""
    time: float
    """When, s (linear between the two instants around the hit)."""
    where: F64
    """(3,) world position of the hit, m."""


def path_hit(
    scene: Scene,
    caster: SegmentCaster,
    points: F64,
    t: F64,
    position: F64,
    R_world_body: F64,
) -> PathHit | None:
    """The earliest hit of ``points`` (K, 3, base_link) with the scene's triangles (cast
    through ``caster``, the scene's ray caster) while
    base_link goes through poses ``position`` (n, 3), ``R_world_body`` (n, 3, 3) at
    instants ``t`` (n,) (straight segments between consecutive instants); None if clear."""
    # (any object with a triangle: the closed loop's every step need not count them all)
    if t.shape[0] < 2 or not any(o.n_triangles for o in scene.objects):
        return None
    K = points.shape[0]
    wb = position[:, None, :] + np.einsum("nij,kj->nki", R_world_body, points)
    a, b = wb[:-1].reshape(-1, 3), wb[1:].reshape(-1, 3)
    prim, frac = segment_hits(caster, a, b, np.repeat(np.asarray(t, np.float64)[:-1], K))
    hit = np.flatnonzero(prim >= 0)
    if not hit.size:
        return None
    j = int(hit[0])  # row-major: the earliest segment first
    seg, k = divmod(j, K)
    where = a[j] + frac[j] * (b[j] - a[j])
    when = float(t[seg] + frac[j] * (t[seg + 1] - t[seg]))
    name = scene.objects[int(scene.triangles[2][int(prim[j])])].name
    return PathHit(k, int(prim[j]), name, when, where)
