"""Embree ray caster over the shared :class:`~roslan.scene.model.Scene`.

Every beam sensor (spinning and solid-state LiDAR, 2-D laser, sonar, altimeter)
casts its rays here, against exactly the triangles the rasterizer draws
(``Scene.triangles``), so images and beams cannot disagree.

Threading: ``embreex``'s ``EmbreeScene.run`` loops over the rays in C with the
GIL released around ``rtcIntersect1``, so a ``ThreadPoolExecutor`` over
contiguous chunks of rays runs them in parallel. Batches smaller than
:data:`PARALLEL_MIN_RAYS` run inline, where the thread hand-off would cost more than
it saves. ``ROSLAN_RAYCAST_THREADS`` overrides the thread count (default: the CPUs
this process may run on).
"""

from __future__ import annotations

import itertools
import os
import threading
import weakref
from concurrent.futures import ThreadPoolExecutor
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from roslan.errors import RenderError
from roslan.scene.model import require_static

if TYPE_CHECKING:
    from roslan.scene.model import Scene

__all__ = ["PARALLEL_MIN_RAYS", "Hits", "RayCaster", "get_raycaster", "raycast_threads"]

PARALLEL_MIN_RAYS = 4096
"""Below this many rays a cast runs on the calling thread only."""

_CHUNK_RAYS = 8192
"""Rays per task: small enough to balance cheap (sky) and expensive chunks over threads."""


class Hits(NamedTuple):
    """The hit record of :meth:`RayCaster.cast` for N rays: range, point, triangle,
    object (and the normal and reflectivity beams need).

    Attributes:
        distance: (N,) float32 range along the (unit) ray to the first hit, m; ``inf``
            where nothing is hit within ``max_range``.
        triangle: (N,) int32 index into ``Scene.triangles`` faces; -1 for no hit.
        normal: (N, 3) float32 world unit normal of the hit triangle, flipped to face
            the incoming ray (``dot(normal, direction) <= 0``); 0 for no hit.
        reflectivity: (N,) float32 LiDAR reflectivity of the hit material; 0 for no hit.
        origins, directions: (N, 3) float32 the rays cast (what :attr:`point` is made of).
        owner: (T,) the scene's triangle -> object index map (``Scene.triangles[2]``).
    """

    distance: NDArray[np.float32]
    triangle: NDArray[np.int32]
    normal: NDArray[np.float32]
    reflectivity: NDArray[np.float32]
    origins: NDArray[np.float32]
    directions: NDArray[np.float32]
    owner: NDArray[np.integer[Any]]

    @property
    def hit(self) -> NDArray[np.bool_]:
        """(N,) True where a surface was hit."""
        return self.triangle >= 0

    @property
    def range(self) -> NDArray[np.float32]:
        """(N,) :attr:`distance`: the range to the hit, m (``inf``: no hit)."""
        return self.distance

    @property
    def point(self) -> NDArray[np.float32]:
        """(N, 3) float32 world position of each hit, m; NaN for no hit."""
        hit = self.hit
        d = np.where(hit, self.distance, np.float32(0.0))
        p = (self.origins + d[:, None] * self.directions).astype(np.float32, copy=False)
        p[~hit] = np.nan
        return p

    @property
    def object(self) -> NDArray[np.int32]:
        """(N,) int32 index into ``Scene.objects`` of the object hit; -1 for no hit."""
        tri = self.triangle
        if self.owner.shape[0] == 0:
            return np.full(tri.shape[0], -1, np.int32)
        obj = np.asarray(self.owner, dtype=np.int32)[np.where(tri >= 0, tri, 0)]
        return np.where(tri >= 0, obj, np.int32(-1)).astype(np.int32, copy=False)

    def cos_incidence(self, directions: ArrayLike) -> NDArray[np.float32]:
        """(N,) cosine of the angle between each ray and its surface normal (0 for misses)."""
        d = np.asarray(directions, dtype=np.float32)
        cos: NDArray[np.float32] = np.maximum(-np.einsum("ij,ij->i", self.normal, d), 0.0)
        return cos.astype(np.float32, copy=False)


def raycast_threads() -> int:
    """Threads a cast uses: ``ROSLAN_RAYCAST_THREADS`` or the CPUs available to this process."""
    env = os.environ.get("ROSLAN_RAYCAST_THREADS")
    if env:
        try:
            n = int(env)
        except ValueError:
            n = 0
        if n < 1:
            msg = f"ROSLAN_RAYCAST_THREADS = {env!r}: must be a positive integer"
            raise RenderError(msg)
        return n
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - non-Linux
        return max(1, os.cpu_count() or 1)


_POOL: ThreadPoolExecutor | None = None
_POOL_LOCK = threading.Lock()


def _forget_pool_after_fork() -> None:
    # a forked child inherits the executor object but not its threads: start afresh
    global _POOL, _POOL_LOCK
    _POOL = None
    _POOL_LOCK = threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pool_after_fork)


def _pool(n: int) -> ThreadPoolExecutor:
    global _POOL
    with _POOL_LOCK:
        if _POOL is None or _POOL._max_workers != n:
            if _POOL is not None:
                _POOL.shutdown(wait=False)
            _POOL = ThreadPoolExecutor(max_workers=n, thread_name_prefix="roslan-raycast")
        return _POOL


class RayCaster:
    """Embree BVH of one scene's triangles (built once), cast from any thread.

    Use :func:`get_raycaster` to share one per process and scene.
    """

    def __init__(self, scene: Scene, *, threads: int | None = None) -> None:
        require_static(scene, "the Embree ray caster")
        verts, faces, owner = scene.at(0.0).triangles
        self.scene_name = scene.name
        self._owner = owner
        self.n_triangles = int(faces.shape[0])
        self.threads = threads if threads is not None else raycast_threads()
        v64 = verts.astype(np.float64)
        if self.n_triangles:
            # per-triangle geometric normals (float64 cross product for thin slivers)
            e1 = v64[faces[:, 1]] - v64[faces[:, 0]]
            e2 = v64[faces[:, 2]] - v64[faces[:, 0]]
            n = np.cross(e1, e2)
            norm = np.linalg.norm(n, axis=1, keepdims=True)
            self._normals = (n / np.where(norm > 0, norm, 1.0)).astype(np.float32)
        else:
            self._normals = np.zeros((0, 3), np.float32)
        self._reflectivity = np.ascontiguousarray(scene.triangle_reflectivity, dtype=np.float32)
        self._embree: Any = None
        if self.n_triangles:
            try:
                from embreex import rtcore_scene
                from embreex.mesh_construction import TriangleMesh
            except ImportError as err:  # pragma: no cover - embreex is a dependency
                msg = f"the Embree ray caster needs embreex ({err}); run: pip install embreex"
                raise RenderError(msg) from err
            # robust mode: no rays slipping through shared edges of adjacent triangles
            emb = rtcore_scene.EmbreeScene(robust=True)
            self._mesh = TriangleMesh(
                emb,
                np.ascontiguousarray(verts, dtype=np.float32),
                np.ascontiguousarray(faces, dtype=np.int32),
            )
            # the first run commits the BVH; do it here, once, on this thread
            emb.run(np.zeros((1, 3), np.float32), np.array([[0, 0, 1]], np.float32))
            self._embree = emb

    # ------------------------------------------------------------------ casting
    def _run(
        self, o: NDArray[np.float32], d: NDArray[np.float32], tfar: NDArray[np.float32]
    ) -> tuple[NDArray[np.float32], NDArray[np.int32]]:
        res = self._embree.run(o, d, dists=tfar, output=1)
        return res["tfar"], res["primID"]

    def _trace(
        self, origins: ArrayLike, directions: ArrayLike, max_range: float | ArrayLike
    ) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32], NDArray[np.int32]]:
        """float32 contiguous (o, d), raw tfar and primID (-1 for a miss)."""
        o = np.ascontiguousarray(np.asarray(origins, dtype=np.float32).reshape(-1, 3))
        d = np.ascontiguousarray(np.asarray(directions, dtype=np.float32).reshape(-1, 3))
        if o.shape != d.shape:
            msg = f"origins {o.shape} and directions {d.shape} must both be (N, 3)"
            raise RenderError(msg)
        n = o.shape[0]
        mr = np.asarray(max_range, dtype=np.float64)
        tfar = np.empty(n, np.float32)
        tfar[:] = np.minimum(np.where(np.isfinite(mr), mr, 1e37), 1e37)
        if n == 0 or self._embree is None:
            return o, d, np.full(n, np.inf, np.float32), np.full(n, -1, np.int32)
        if self.threads > 1 and n >= PARALLEL_MIN_RAYS:
            n_chunks = max(self.threads, -(-n // _CHUNK_RAYS))
            bounds = np.linspace(0, n, n_chunks + 1).astype(np.int64)
            sl = [slice(int(a), int(b)) for a, b in itertools.pairwise(bounds)]
            parts = list(_pool(self.threads).map(lambda s: self._run(o[s], d[s], tfar[s]), sl))
            dist = np.concatenate([p[0] for p in parts])
            tri = np.concatenate([p[1] for p in parts])
        else:
            dist, tri = self._run(o, d, tfar)
        return o, d, dist, tri.astype(np.int32, copy=False)

    def cast(
        self,
        origins: ArrayLike,
        directions: ArrayLike,
        max_range: float | ArrayLike = np.inf,
        *,
        t: float | ArrayLike | None = None,
    ) -> Hits:
        """Cast N rays; first hit of each.

        Args:
            origins: (N, 3) world ray origins, m.
            directions: (N, 3) world unit directions (not renormalized: distances are in
                units of their length).
            max_range: scalar or (N,) largest distance reported, m; farther hits are misses.
            t: trajectory time (s) of the rays, scalar or (N,) (None: t = 0): the scene is
                cast at that time (:meth:`Scene.at <roslan.scene.model.Scene.at>`); a
                static scene, the only kind this caster builds, is the same at every time.

        Returns:
            :class:`Hits`, the hit record (float32/int32 arrays of length N; the hit
            points and objects are computed when read).
        """
        o, d, dist, tri = self._trace(origins, directions, max_range)
        n = tri.shape[0]
        if self.n_triangles == 0:
            zero = np.zeros(n, np.float32)
            return Hits(dist, tri, np.zeros((n, 3), np.float32), zero, o, d, self._owner)
        hit = tri >= 0
        dist = np.where(hit, dist, np.float32(np.inf)).astype(np.float32, copy=False)
        idx = np.where(hit, tri, 0)
        normal = self._normals[idx]
        # face the ray: the sign of a triangle's winding must not matter to a beam
        flip = np.einsum("ij,ij->i", normal, d) > 0
        normal[flip] *= -1.0
        normal[~hit] = 0.0
        refl = np.where(hit, self._reflectivity[idx], np.float32(0.0)).astype(np.float32)
        return Hits(dist, tri, normal, refl, o, d, self._owner)

    def cast_incidence(
        self,
        origins: ArrayLike,
        directions: ArrayLike,
        max_range: float | ArrayLike = np.inf,
        *,
        t: float | ArrayLike | None = None,
    ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
        """What a LiDAR needs, without the (N, 3) normals: ``distance`` (N,) float32 as in
        :meth:`cast` and ``reflectivity * cos(incidence)`` (N,) float32 (0 for misses);
        ``t`` as in :meth:`cast`."""
        _o, d, dist, tri = self._trace(origins, directions, max_range)
        if self.n_triangles == 0:
            return dist, np.zeros(tri.shape[0], np.float32)
        hit = tri >= 0
        idx = np.where(hit, tri, 0)
        n = self._normals[idx]
        cos = np.abs(n[:, 0] * d[:, 0] + n[:, 1] * d[:, 1] + n[:, 2] * d[:, 2])
        echo = np.where(hit, self._reflectivity[idx] * cos, np.float32(0.0)).astype(np.float32)
        dist = np.where(hit, dist, np.float32(np.inf)).astype(np.float32, copy=False)
        return dist, echo


_CACHE: weakref.WeakKeyDictionary[Scene, RayCaster] = weakref.WeakKeyDictionary()
_CACHE_LOCK = threading.Lock()


def get_raycaster(scene: Scene) -> RayCaster:
    """The process-wide :class:`RayCaster` of ``scene`` (BVH built on first call only)."""
    with _CACHE_LOCK:
        rc = _CACHE.get(scene)
        if rc is None:
            rc = RayCaster(scene)
            _CACHE[scene] = rc
        return rc
