"""Embree ray caster over the shared :class:`~roslan.scene.model.Scene`.

Every beam sensor (spinning and solid-state LiDAR, 2-D laser, sonar, altimeter)
casts its rays here, against exactly the triangles the rasterizer draws
(``Scene.triangles``), so images and beams cannot disagree.

Moving objects: the Embree scene holds the static world only; each moving
object has its own Embree scene of its model-frame geometry (scaled), and every ray is
cast against it in the object's frame at the ray's own time (``T(t)^-1`` applied to the
ray: a rigid motion keeps the distance along it), the nearest of all hits winning.
Triangle indices stay those of ``Scene.triangles``, so objects and labels keep their
ids. A static scene builds and casts exactly as before.

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

if TYPE_CHECKING:
    from roslan.scene.model import Scene, SceneObject

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
        verts, faces, owner = scene.at(0.0).triangles
        self.scene_name = scene.name
        self._movers: list[_Mover] = []
        self._static_tri: NDArray[np.int64] | None = None  # Embree primID -> triangle
        bvh_faces = faces
        if not scene.is_static:
            bvh_faces = self._split_movers(scene, faces, owner)
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
        if bvh_faces.shape[0]:
            self._embree, self._mesh = _embree_scene(verts, bvh_faces)

    def _split_movers(
        self, scene: Scene, faces: NDArray[np.int32], owner: Any
    ) -> NDArray[np.int32]:
        """Build each moving object's own Embree scene (object frame); return the static
        world's faces for the shared one."""
        tri0 = np.concatenate([[0], np.cumsum([o.n_triangles for o in scene.objects])])
        for i, obj in enumerate(scene.objects):
            if obj.is_static or obj.n_triangles == 0:
                continue
            local = obj.model_geometry()[0].astype(np.float64) * np.asarray(obj.scale)
            emb, mesh = _embree_scene(local.astype(np.float32), obj.faces)
            e1 = local[obj.faces[:, 1]] - local[obj.faces[:, 0]]
            e2 = local[obj.faces[:, 2]] - local[obj.faces[:, 0]]
            nrm = np.cross(e1, e2)
            nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
            self._movers.append(_Mover(obj, int(tri0[i]), emb, mesh, nrm))
        keep = np.flatnonzero(np.asarray([o.is_static for o in scene.objects])[owner])
        self._static_tri = keep.astype(np.int64)
        return np.ascontiguousarray(faces[keep])

    # ------------------------------------------------------------------ casting
    def _run(
        self, o: NDArray[np.float32], d: NDArray[np.float32], tfar: NDArray[np.float32]
    ) -> tuple[NDArray[np.float32], NDArray[np.int32]]:
        res = self._embree.run(o, d, dists=tfar, output=1)
        return res["tfar"], res["primID"]

    def _parallel(
        self, emb: Any, o: NDArray[np.float32], d: NDArray[np.float32], tfar: NDArray[np.float32]
    ) -> tuple[NDArray[np.float32], NDArray[np.int32]]:
        """Embree scene ``emb``'s tfar and primID of the rays, over the thread pool."""

        def run(s: slice) -> tuple[NDArray[np.float32], NDArray[np.int32]]:
            res = emb.run(o[s], d[s], dists=tfar[s], output=1)
            return res["tfar"], res["primID"]

        n = o.shape[0]
        if self.threads > 1 and n >= PARALLEL_MIN_RAYS:
            n_chunks = max(self.threads, -(-n // _CHUNK_RAYS))
            bounds = np.linspace(0, n, n_chunks + 1).astype(np.int64)
            sl = [slice(int(a), int(b)) for a, b in itertools.pairwise(bounds)]
            parts = list(_pool(self.threads).map(run, sl))
            return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
        return run(slice(0, n))

    def _trace(
        self,
        origins: ArrayLike,
        directions: ArrayLike,
        max_range: float | ArrayLike,
        t: float | ArrayLike | None = None,
    ) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32], NDArray[np.int32]]:
        """float32 contiguous (o, d), raw tfar and the scene triangle hit (-1 for a miss;
        the Embree primID itself in a static scene)."""
        o = np.ascontiguousarray(np.asarray(origins, dtype=np.float32).reshape(-1, 3))
        d = np.ascontiguousarray(np.asarray(directions, dtype=np.float32).reshape(-1, 3))
        if o.shape != d.shape:
            msg = f"origins {o.shape} and directions {d.shape} must both be (N, 3)"
            raise RenderError(msg)
        n = o.shape[0]
        mr = np.asarray(max_range, dtype=np.float64)
        tfar = np.empty(n, np.float32)
        tfar[:] = np.minimum(np.where(np.isfinite(mr), mr, 1e37), 1e37)
        if self._movers or self._static_tri is not None:
            return self._trace_moving(o, d, tfar, t)
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

    def _trace_moving(
        self,
        o: NDArray[np.float32],
        d: NDArray[np.float32],
        tfar: NDArray[np.float32],
        t: float | ArrayLike | None,
    ) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32], NDArray[np.int32]]:
        """:meth:`_trace` of a scene with moving objects: the static world, then each
        moving object in its own frame at each ray's time, nearest hit first."""
        n = o.shape[0]
        dist = np.full(n, np.inf, np.float32)
        tri = np.full(n, -1, np.int32)
        if n == 0:
            return o, d, dist, tri
        if self._embree is not None:
            dist, prim = self._parallel(self._embree, o, d, tfar.copy())
            prim = prim.astype(np.int64)
            assert self._static_tri is not None
            tri = np.where(prim >= 0, self._static_tri[np.maximum(prim, 0)], -1).astype(np.int32)
        best = np.where(tri >= 0, dist, tfar).astype(np.float32)
        times, which = _ray_times(t, n)
        o64, d64 = o.astype(np.float64), d.astype(np.float64)
        for m in self._movers:
            T = _poses(m.obj, times)[which]  # (N, 4, 4) each ray's pose of the object
            R = T[:, :3, :3]
            ol = np.einsum("nji,nj->ni", R, o64 - T[:, :3, 3]).astype(np.float32)
            dl = np.einsum("nji,nj->ni", R, d64).astype(np.float32)
            dm, pm = self._parallel(m.embree, ol, dl, best.copy())
            near = (pm >= 0) & (dm < best)
            best = np.where(near, dm, best).astype(np.float32)
            tri = np.where(near, m.tri0 + pm, tri).astype(np.int32)
        dist = np.where(tri >= 0, best, np.float32(np.inf)).astype(np.float32)
        return o, d, dist, tri

    def _moved_normals(
        self, normal: NDArray[np.float32], tri: NDArray[np.int32], n: int, t: Any
    ) -> NDArray[np.float32]:
        """``normal`` (N, 3) with the hits on moving objects rotated to their time."""
        times, which = _ray_times(t, n)
        out = normal.copy()
        for m in self._movers:
            sel = np.flatnonzero((tri >= m.tri0) & (tri < m.tri0 + m.normals.shape[0]))
            if sel.size == 0:
                continue
            R = _poses(m.obj, times)[which[sel], :3, :3]
            nl = m.normals[tri[sel] - m.tri0]
            out[sel] = np.einsum("nij,nj->ni", R, nl).astype(np.float32)
        return out

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
            t: trajectory time (s) of the rays, scalar or (N,) (None: t = 0): each ray
                meets every moving object where it is at the ray's own time; a static
                scene is the same at every time.

        Returns:
            :class:`Hits`, the hit record (float32/int32 arrays of length N; the hit
            points and objects are computed when read).
        """
        o, d, dist, tri = self._trace(origins, directions, max_range, t)
        n = tri.shape[0]
        if self.n_triangles == 0:
            zero = np.zeros(n, np.float32)
            return Hits(dist, tri, np.zeros((n, 3), np.float32), zero, o, d, self._owner)
        hit = tri >= 0
        dist = np.where(hit, dist, np.float32(np.inf)).astype(np.float32, copy=False)
        idx = np.where(hit, tri, 0)
        normal = self._normals[idx]
        if self._movers:
            normal = self._moved_normals(normal, tri, n, t)
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
        _o, d, dist, tri = self._trace(origins, directions, max_range, t)
        if self.n_triangles == 0:
            return dist, np.zeros(tri.shape[0], np.float32)
        hit = tri >= 0
        idx = np.where(hit, tri, 0)
        n = self._normals[idx]
        if self._movers:
            n = self._moved_normals(n, tri, tri.shape[0], t)
        cos = np.abs(n[:, 0] * d[:, 0] + n[:, 1] * d[:, 1] + n[:, 2] * d[:, 2])
        echo = np.where(hit, self._reflectivity[idx] * cos, np.float32(0.0)).astype(np.float32)
        dist = np.where(hit, dist, np.float32(np.inf)).astype(np.float32, copy=False)
        return dist, echo


class _Mover(NamedTuple):
    """A moving object's own Embree scene (object frame) and its first scene triangle."""

    obj: SceneObject
    tri0: int
    embree: Any
    mesh: Any
    normals: NDArray[np.float64]  # (F, 3) object-frame unit normals


def _embree_scene(verts: NDArray[np.float32], faces: NDArray[np.int32]) -> tuple[Any, Any]:
    """A committed Embree scene (robust mode) of the triangles, and its mesh."""
    try:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh
    except ImportError as err:  # pragma: no cover - embreex is a dependency
        msg = f"the Embree ray caster needs embreex ({err}); run: pip install embreex"
        raise RenderError(msg) from err
    # robust mode: no rays slipping through shared edges of adjacent triangles
    emb = rtcore_scene.EmbreeScene(robust=True)
    mesh = TriangleMesh(
        emb,
        np.ascontiguousarray(verts, dtype=np.float32),
        np.ascontiguousarray(faces, dtype=np.int32),
    )
    # the first run commits the BVH; do it here, once, on this thread
    emb.run(np.zeros((1, 3), np.float32), np.array([[0, 0, 1]], np.float32))
    return emb, mesh


def _ray_times(t: float | ArrayLike | None, n: int) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """The distinct times of ``n`` rays and each ray's index into them."""
    tt = np.broadcast_to(np.asarray(0.0 if t is None else t, dtype=np.float64), (n,))
    uniq, inv = np.unique(tt, return_inverse=True)
    return uniq, inv.reshape(-1)


def _poses(obj: SceneObject, times: NDArray[np.float64]) -> NDArray[np.float64]:
    """(K, 4, 4) ``T_world_object`` at each time (one call per distinct ray time)."""
    return np.stack([obj.pose_at(float(x)) for x in times]) if times.size else np.zeros((0, 4, 4))


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
