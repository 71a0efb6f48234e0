"""Containment: which points lie inside a closed scene object.

The clearance check (:mod:`roslan.scene.clearance`) and the environment's contact check
(:mod:`roslan.env.contact`) cast the vehicle's point paths against the scene's surfaces:
a point that crosses a surface is caught there. A point that never crosses one - a
vehicle whose whole body starts (or is held by a pose file) inside a box - hits nothing;
this module finds it.

An object has an inside only when its triangles close a volume: a **watertight** mesh
(every edge shared by exactly two triangles once coincident vertices are merged;
:attr:`trimesh.Trimesh.is_watertight`), such as the box, cylinder and sphere primitives
and closed mesh files. For those, the **generalized winding number** decides: the solid
angle the object's triangles subtend at the point over 4 pi (Van Oosterom and Strackee's
formula per triangle), 1 inside a closed surface and 0 outside, and a point counts as
inside where it exceeds 1/2. Unlike ray parity it needs no ray that misses every edge,
and it is exact arithmetic in a fixed order, so the same points give the same answer on
every call (``trimesh.Trimesh.contains`` with Embree did not: 62, 60 and 56 of the same
20,000 points on three calls, 2026-12-02). Each mesh's winding is made consistent
(:func:`trimesh.repair.fix_winding`) and its sign taken from its volume. Objects that
are **not watertight** - open surfaces such as a ground plane or a wall quad, or meshes
with holes - have no defined inside and are not tested: their surfaces are still hit by
the path casts, but a point inside a leaky mesh that never crosses its surface is not
reported.

Each point is first tested against the object's bounding box (vectorised), so only the
few points near a closed object reach the winding test, and an object is meshed (and checked
watertight) only when some point lies in its box.
"""

from __future__ import annotations

import weakref
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from roslan.scene.model import Scene

__all__ = [
    "CONTACT_DEPTH",
    "ClosedObject",
    "Inside",
    "closed_objects",
    "contact_labels",
    "first_inside",
    "inside",
    "vehicle_contacts",
    "vehicle_inside",
]

F64 = NDArray[np.float64]

CONTACT_DEPTH = 1e-3
"""m: a contact point (foot, grasp point) counts as inside an object only this deep below
its surface: at touchdown it lies on the surface itself."""


class ClosedObject:
    """A scene object that may close a volume: its bounding box at once, its merged
    :class:`trimesh.Trimesh` (None when not watertight) when first needed."""

    def __init__(self, index: int, obj: Any) -> None:
        self.index = index
        """Its index in :attr:`Scene.objects`."""
        self.name: str = obj.name
        v = np.asarray(obj.vertices, dtype=np.float64)
        self.lo: F64 = v.min(axis=0)
        self.hi: F64 = v.max(axis=0)
        self._obj = obj

    @cached_property
    def mesh(self) -> Any:
        """The object's triangles with coincident vertices merged, if watertight."""
        import trimesh

        obj = self._obj
        mesh = trimesh.Trimesh(
            np.asarray(obj.vertices, dtype=np.float64), np.asarray(obj.faces), process=True
        )
        if not mesh.is_watertight:
            return None
        if not mesh.is_winding_consistent:
            trimesh.repair.fix_winding(mesh)  # type: ignore[no-untyped-call]
        return mesh

    @cached_property
    def triangles(self) -> F64:
        """(T, 3, 3) the closed mesh's triangles, wound so that its volume is positive."""
        tri = np.asarray(self.mesh.triangles, dtype=np.float64)
        return tri if float(self.mesh.volume) >= 0.0 else tri[:, ::-1]


class Inside(NamedTuple):
    """The first point found inside a closed object (:func:`first_inside`)."""

    instant: int
    """Row of the instants given."""
    point: int
    """Column: which point."""
    obj: str
    """Name of the object."""
    where: F64
    """(3,) the point's world position, m."""


_CANDIDATES: weakref.WeakKeyDictionary[Scene, tuple[ClosedObject, ...]] = (
    weakref.WeakKeyDictionary()
)
"""Each live scene's candidates (their meshes built lazily), never keeping a scene alive."""


def _candidates(scene: Scene) -> tuple[ClosedObject, ...]:
    found = _CANDIDATES.get(scene)
    if found is None:
        # fewer than a tetrahedron's four faces cannot close a volume
        found = tuple(ClosedObject(i, o) for i, o in enumerate(scene.objects) if o.n_triangles >= 4)
        _CANDIDATES[scene] = found
    return found


def closed_objects(scene: Scene) -> tuple[ClosedObject, ...]:
    """The watertight objects of ``scene`` (see the module docstring), in scene order."""
    return tuple(c for c in _candidates(scene) if c.mesh is not None)


def inside(scene: Scene, points: F64, depth: float = 0.0) -> NDArray[np.int64]:
    """(N,) index (into :attr:`Scene.objects`) of the closed object each of ``points``
    (N, 3, world, m) lies inside, -1 for none (the first such object in scene order).

    ``depth`` > 0: only points at least that far from the object's surface count (a
    contact point resting on a surface is not inside it).
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    owner = np.full(p.shape[0], -1, dtype=np.int64)
    cands = _candidates(scene)
    if cands and p.shape[0] * len(cands) <= _BOX_BATCH:
        # every box at once (the same comparisons), then only the objects some point is near
        lo, hi = _boxes(scene, cands)
        box = np.all(p[:, None, :] >= lo - depth, axis=2) & np.all(
            p[:, None, :] <= hi + depth, axis=2
        )
        for k in np.flatnonzero(box.any(axis=0)):
            obj = cands[int(k)]
            near = np.flatnonzero((owner < 0) & box[:, k])
            if near.size and obj.mesh is not None:
                _claim(obj, p, near, depth, owner)
        return owner
    for obj in cands:  # meshes built (and checked closed) only when needed
        near = np.flatnonzero(
            (owner < 0) & np.all(p >= obj.lo - depth, axis=1) & np.all(p <= obj.hi + depth, axis=1)
        )
        if not near.size or obj.mesh is None:
            continue
        _claim(obj, p, near, depth, owner)
    return owner


_BOX_BATCH = 1 << 16
"""Points x candidates up to which :func:`inside` tests every bounding box in one array
operation (the closed loop's few points per step); beyond it, object by object."""

_BOXES: weakref.WeakKeyDictionary[Scene, tuple[F64, F64]] = weakref.WeakKeyDictionary()


def _boxes(scene: Scene, cands: tuple[ClosedObject, ...]) -> tuple[F64, F64]:
    """(K, 3) lower and upper corners of the candidates' bounding boxes, cached per scene."""
    found = _BOXES.get(scene)
    if found is None:
        found = (np.stack([c.lo for c in cands]), np.stack([c.hi for c in cands]))
        _BOXES[scene] = found
    return found


def _claim(
    obj: ClosedObject, p: F64, near: NDArray[np.intp], depth: float, owner: NDArray[np.int64]
) -> None:
    """Mark the points ``near`` (indices into ``p``) that lie inside ``obj`` (deeper than
    ``depth``) as its own."""
    within = near[winding_number(obj.triangles, p[near]) > 0.5]
    if depth > 0.0 and within.size:
        within = within[_surface_distance(obj.mesh, p[within]) >= depth]
    owner[within] = obj.index


_WINDING_BATCH = 1 << 21
"""Points x triangles per array operation of :func:`winding_number` (memory bound)."""


def winding_number(triangles: F64, points: F64) -> F64:
    """(M,) generalized winding number of each of ``points`` (M, 3) with respect to the
    surface ``triangles`` (T, 3, 3): the signed solid angle it subtends over 4 pi (1 inside
    a closed, outward-wound surface, 0 outside, 1/2 on it); summed in a fixed order."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    out = np.empty(pts.shape[0])
    step = max(1, _WINDING_BATCH // max(1, triangles.shape[0]))
    for s in range(0, pts.shape[0], step):  # chunks of points, every triangle at once
        q = pts[s : s + step, None, None, :]
        d = triangles[None, :, :, :] - q  # (m, T, 3 corners, 3)
        a, b, c = d[:, :, 0], d[:, :, 1], d[:, :, 2]
        la, lb, lc = (np.sqrt((x * x).sum(axis=2)) for x in (a, b, c))
        det = (a * np.cross(b, c)).sum(axis=2)
        den = (
            la * lb * lc
            + (a * b).sum(axis=2) * lc
            + (a * c).sum(axis=2) * lb
            + (b * c).sum(axis=2) * la
        )
        out[s : s + step] = np.arctan2(det, den).sum(axis=1) / (2.0 * np.pi)
    return out


def _surface_distance(mesh: Any, points: F64) -> F64:
    """(M,) distance of each point to the nearest triangle of ``mesh`` (exact; every
    triangle against each point, for the few points found inside)."""
    from trimesh.triangles import closest_point

    tri = np.asarray(mesh.triangles, dtype=np.float64)
    out = np.empty(points.shape[0])
    for i, q in enumerate(points):  # a handful of contact points, each against every face
        c = closest_point(tri, np.broadcast_to(q, (tri.shape[0], 3)))  # type: ignore[no-untyped-call]
        out[i] = float(np.sqrt(((c - q) ** 2).sum(axis=1).min()))
    return out


def first_inside(scene: Scene, world: F64, depth: float = 0.0) -> Inside | None:
    """The earliest (then lowest-numbered) point of ``world`` (n instants, K points, 3;
    m) inside a closed object of ``scene``, or None."""
    w = np.asarray(world, dtype=np.float64)
    if w.size == 0 or not _candidates(scene):
        return None
    n, k = w.shape[0], w.shape[1]
    owner = inside(scene, w.reshape(-1, 3), depth)
    hit = np.flatnonzero(owner >= 0)
    if not hit.size:
        return None
    j = int(hit[0])
    row, col = divmod(j, k)
    assert row < n
    return Inside(row, col, scene.objects[int(owner[j])].name, w[row, col].copy())


def contact_labels(contacts: F64, grasp: bool = False) -> tuple[str, ...]:
    """Labels of contact points (base_link, m): ``foot 1 [x y z]``... (the last one ``the
    grasp point`` when ``grasp``)."""
    c = np.asarray(contacts, dtype=np.float64).reshape(-1, 3)
    out = [f"foot {i + 1} [{p[0]:g} {p[1]:g} {p[2]:g}]" for i, p in enumerate(c)]
    if grasp and out:
        out[-1] = "the grasp point"
    return tuple(out)


def vehicle_contacts(vehicle: Any) -> tuple[F64, tuple[str, ...]]:
    """Every contact point of a :class:`~roslan.vehicle.VehicleConfig` (its feet, then
    its grasp point; base_link, m) and their labels."""
    pts = np.asarray([*vehicle.feet, vehicle.grasp], dtype=np.float64).reshape(-1, 3)
    return pts, contact_labels(pts, grasp=True)


def vehicle_inside(
    scene: Scene,
    t: F64,
    position: F64,
    R_world_body: F64,
    points: F64,
    labels: tuple[str, ...],
    contacts: F64,
    contact_names: tuple[str, ...],
) -> tuple[float, str, str, F64] | None:
    """The first instant of ``t`` (n,) at which a vehicle point (K, 3, base_link: body,
    sensors; any depth) or a contact point (C, 3: feet, grasp; deeper than
    :data:`CONTACT_DEPTH`) lies inside a closed object while base_link is at
    ``position`` (n, 3), ``R_world_body`` (n, 3, 3): ``(time, label, object, where)``;
    None if no point is inside at any of them."""
    found: list[tuple[float, str, str, F64]] = []
    for pts, names, depth in ((points, labels, 0.0), (contacts, contact_names, CONTACT_DEPTH)):
        pb = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
        if not pb.size:
            continue
        world = position[:, None, :] + np.einsum("nij,kj->nki", R_world_body, pb)
        hit = first_inside(scene, world, depth)
        if hit is not None:
            found.append((float(t[hit.instant]), names[hit.point], hit.obj, hit.where))
    return min(found, key=lambda f: f[0]) if found else None
