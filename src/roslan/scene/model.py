"""The in-memory scene shared by the rasterizer and the ray caster.

A :class:`Scene` is built once (from a scene file or a built-in generator) and
handed to both back-ends, so images and beams see exactly the same triangles.
Each object keeps its geometry in its model frame plus a pose over time
(:mod:`roslan.scene.pose`; constant today) and its world-placed triangles at that pose
(ENU, metres, float32 for the GPU), with per-object materials. Every consumer reads
"the scene at t" through :meth:`Scene.at`; a static scene's view is its world-placed
arrays themselves (the fast path: the same bytes, nothing recomputed).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from roslan.errors import RenderError
from roslan.scene.classes import PartLabels
from roslan.scene.pose import ConstantPose, PoseTrack

__all__ = ["Lights", "Material", "Scene", "SceneAt", "SceneObject", "require_static"]

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Material:
    """Surface appearance.

    Attributes:
        color: (3,) linear RGB albedo in [0, 1] (multiplies the texture).
        texture: (H, W, 3) uint8 sRGB image or None.
        texture_scale: texture repeats per UV unit (UVs are in metres for primitives).
        reflectivity: LiDAR reflectivity in [0, 1] (intensity = reflectivity * cos(incidence)).
        name: for reports and export.
    """

    color: tuple[float, float, float] = (0.7, 0.7, 0.7)
    texture: NDArray[np.uint8] | None = None
    texture_scale: float = 1.0
    reflectivity: float = 0.5
    name: str = "default"


@dataclass(frozen=True, eq=False)
class SceneObject:
    """One rigid object: its model-frame geometry, its pose over time and its triangles
    posed and scaled into the world frame at its pose at t = 0.

    Attributes:
        name: unique within the scene.
        vertices: (V, 3) float32 world positions, m.
        normals: (V, 3) float32 unit vertex normals (world).
        uvs: (V, 2) float32 texture coordinates.
        faces: (F, 3) int32 vertex indices, counter-clockwise seen from outside.
        material: its :class:`Material`.
        pose: (4, 4) float64 ``T_world_object`` used to place it (for export/poses.yaml).
        scale: (3,) scale applied in the object frame before the pose.
        source: where it came from: a mesh path, ``primitive:box``, ``builtin:...``.
        local_vertices: (V, 3) float32 positions in the object frame before scale and pose
            (``vertices = R (scale * local_vertices) + t``), or None; kept so that an export
            reloads to bit-identical world triangles.
        local_normals: (V, 3) float32 object-frame normals matching ``local_vertices``, or None.
        labels: class and instance of its triangles (:class:`~roslan.scene.classes.PartLabels`),
            or None (unlabelled: class 0); see :mod:`roslan.scene.instances`.
        motion: its pose over time (:class:`~roslan.scene.pose.PoseTrack`), or None:
            constant at ``pose`` (every object today).
    """

    name: str
    vertices: F32
    normals: F32
    uvs: F32
    faces: NDArray[np.int32]
    material: Material = field(default_factory=Material)
    pose: F64 = field(default_factory=lambda: np.eye(4))
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    source: str = ""
    local_vertices: F32 | None = None
    local_normals: F32 | None = None
    labels: PartLabels | None = None
    motion: PoseTrack | None = None

    @property
    def n_triangles(self) -> int:
        return int(self.faces.shape[0])

    @property
    def track(self) -> PoseTrack:
        """Its pose over time (a :class:`~roslan.scene.pose.ConstantPose` at ``pose``
        when it has no ``motion``)."""
        return self.motion if self.motion is not None else ConstantPose(self.pose)

    @property
    def is_static(self) -> bool:
        return self.motion is None or self.motion.is_static

    def pose_at(self, t: float) -> F64:
        """(4, 4) ``T_world_object`` at trajectory time ``t`` (s)."""
        return self.pose if self.motion is None else self.motion.at(t)

    def model_geometry(self) -> tuple[F32, F32]:
        """Model-frame (before scale) vertices and normals, (V, 3) float32 each: the kept
        ``local_vertices``/``local_normals``, or the world arrays taken back through
        ``pose`` and ``scale`` for an object built without them."""
        if self.local_vertices is not None and self.local_normals is not None:
            return self.local_vertices, self.local_normals
        R, t = self.pose[:3, :3], self.pose[:3, 3]
        sc = np.asarray(self.scale, dtype=np.float64)
        v = ((self.vertices.astype(np.float64) - t) @ R) / sc
        n = (self.normals.astype(np.float64) @ R) * sc
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
        return v.astype(np.float32), n.astype(np.float32)

    def vertices_at(self, t: float) -> F32:
        """(V, 3) float32 world vertices at time ``t``: ``vertices`` itself for a static
        object, else the model geometry placed at :meth:`pose_at` (``R (scale p) + t``,
        the loader's formula, so a pose equal to ``pose`` gives the same bytes)."""
        if self.is_static:
            return self.vertices
        T = self.pose_at(t)
        local = self.model_geometry()[0].astype(np.float64) * np.asarray(self.scale)
        return np.ascontiguousarray(local @ T[:3, :3].T + T[:3, 3], dtype=np.float32)

    def point_velocity(self, t: float, points: F64) -> F64:
        """(N, 3) world velocity (m/s) at time ``t`` of the object's surface points
        ``points`` (N, 3, world, at ``t``): ``v + w x (p - origin)``; zero when static."""
        p = np.asarray(points, dtype=np.float64)
        if self.is_static:
            return np.zeros_like(p)
        v, w = self.track.twist(t)
        return v + np.cross(w, p - self.pose_at(t)[:3, 3])

    def carry(self, t0: float, t1: float, points: F64) -> F64:
        """(N, 3) world positions at ``t1`` of the object's surface points ``points``
        (N, 3, world, at ``t0``): ``T(t1) T(t0)^-1 p``; ``points`` itself when static."""
        p = np.asarray(points, dtype=np.float64)
        if self.is_static:
            return p
        T = self.pose_at(t1) @ np.linalg.inv(self.pose_at(t0))
        out: F64 = p @ T[:3, :3].T + T[:3, 3]
        return out


@dataclass(frozen=True)
class Lights:
    """Directional sun (direction the light travels, world frame) plus ambient term, and
    the sky: the linear RGB radiance cameras see where no surface is hit (black by
    default; the built-in scenes use :data:`DAYLIGHT_SKY`)."""

    sun_direction: tuple[float, float, float] = (0.3, 0.2, -1.0)
    sun_intensity: float = 1.0
    ambient: float = 0.3
    sky: tuple[float, float, float] = (0.0, 0.0, 0.0)


DAYLIGHT_SKY = (0.45, 0.58, 0.8)
"""Linear RGB of a clear daylight sky (sRGB ~(178, 201, 231)), as the built-in scenes use."""


@dataclass(frozen=True, eq=False)
class Scene:
    """A set of posed objects plus lights; the single geometry source of every sensor.

    ``goal`` is the scene's suggested landing goal (position, rpy) in the world, used
    when a simulation config names the scene without its own goal.
    """

    name: str
    objects: tuple[SceneObject, ...]
    lights: Lights = Lights()
    goal_position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    goal_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @cached_property
    def triangles(self) -> tuple[F32, NDArray[np.int32], NDArray[np.int32]]:
        """All objects concatenated: vertices (V, 3) float32, faces (F, 3) int32 and the
        object index of every triangle (F,) int32 (index into :attr:`objects`)."""
        verts, faces, owner = [], [], []
        offset = 0
        for i, obj in enumerate(self.objects):
            verts.append(obj.vertices)
            faces.append(obj.faces + offset)
            owner.append(np.full(obj.n_triangles, i, dtype=np.int32))
            offset += obj.vertices.shape[0]
        if not verts:
            return (
                np.zeros((0, 3), np.float32),
                np.zeros((0, 3), np.int32),
                np.zeros((0,), np.int32),
            )
        return (
            np.concatenate(verts).astype(np.float32, copy=False),
            np.concatenate(faces).astype(np.int32, copy=False),
            np.concatenate(owner),
        )

    @cached_property
    def triangle_reflectivity(self) -> F32:
        """(F,) float32 LiDAR reflectivity of every triangle of :attr:`triangles`."""
        refl = np.array([o.material.reflectivity for o in self.objects], dtype=np.float32)
        return refl[self.triangles[2]] if len(self.objects) else np.zeros(0, np.float32)

    @property
    def n_triangles(self) -> int:
        return int(sum(o.n_triangles for o in self.objects))

    @cached_property
    def bounds(self) -> F64:
        """(2, 3) axis-aligned min and max corners of all geometry (m)."""
        v = self.triangles[0]
        if v.shape[0] == 0:
            return np.zeros((2, 3))
        return np.stack([v.min(axis=0), v.max(axis=0)]).astype(np.float64)

    @cached_property
    def is_static(self) -> bool:
        """True when no object moves: :meth:`at` is then the same view at every time."""
        return all(o.is_static for o in self.objects)

    def at(self, t: float) -> SceneAt:
        """The scene at trajectory time ``t`` (s): what the renderer, the caster, the
        clearance check and the motion field read."""
        return SceneAt(self, float(t))

    def object(self, name: str) -> SceneObject:
        for o in self.objects:
            if o.name == name:
                return o
        raise KeyError(name)


@dataclass(frozen=True, eq=False)
class SceneAt:
    """A :class:`Scene` at one trajectory time: the world-placed triangles and the motion
    of its surfaces at ``t``. A static scene's view is its own arrays (no copy), so the
    back-ends' static fast paths see exactly today's bytes."""

    scene: Scene
    t: float

    @property
    def is_static(self) -> bool:
        return self.scene.is_static

    @cached_property
    def triangles(self) -> tuple[F32, NDArray[np.int32], NDArray[np.int32]]:
        """As :attr:`Scene.triangles` (same faces and owners) with every object's
        vertices at ``t``."""
        tri = self.scene.triangles
        if self.scene.is_static or not self.scene.objects:
            return tri
        verts = np.concatenate([o.vertices_at(self.t) for o in self.scene.objects])
        return verts.astype(np.float32, copy=False), tri[1], tri[2]

    @property
    def triangle_reflectivity(self) -> F32:
        return self.scene.triangle_reflectivity

    @cached_property
    def bounds(self) -> F64:
        """(2, 3) axis-aligned min and max corners of the geometry at ``t`` (m)."""
        if self.scene.is_static:
            return self.scene.bounds
        v = self.triangles[0]
        if v.shape[0] == 0:
            return np.zeros((2, 3))
        return np.stack([v.min(axis=0), v.max(axis=0)]).astype(np.float64)

    def point_velocity(self, points: F64, owner: NDArray[np.integer]) -> F64:
        """(N, 3) world velocity (m/s) of surface points ``points`` (N, 3) lying on
        objects ``owner`` (N,) (indices into ``Scene.objects``; negative: no surface, 0
        velocity): the object-motion term of the motion field; zero for a static scene."""
        p = np.asarray(points, dtype=np.float64)
        out = np.zeros(p.shape)
        if self.scene.is_static:
            return out
        own = np.asarray(owner)
        for i in np.unique(own[own >= 0]):  # one call per moving object, not per point
            obj = self.scene.objects[int(i)]
            if not obj.is_static:
                sel = own == i
                out[sel] = obj.point_velocity(self.t, p[sel])
        return out

    def carry(self, points: F64, owner: NDArray[np.integer], t1: float) -> F64:
        """(N, 3) world positions at ``t1`` of surface points ``points`` (N, 3, at this
        view's ``t``) lying on objects ``owner`` (N,; negative: no surface, unmoved): what
        a flow over an interval needs of the scene's own motion; ``points`` itself (the
        same array) for a static scene."""
        p = np.asarray(points, dtype=np.float64)
        if self.scene.is_static:
            return p
        out = p.copy()
        own = np.asarray(owner)
        for i in np.unique(own[own >= 0]):  # one call per moving object, not per point
            obj = self.scene.objects[int(i)]
            if not obj.is_static:
                sel = own == i
                out[sel] = obj.carry(self.t, t1, p[sel])
        return out


def require_static(scene: Scene, what: str) -> None:
    """Raise RenderError unless every object of ``scene`` keeps a constant pose (``what``
    names the back-end: those build their structures once, from ``scene.at(0)``, and
    take their time argument as the same scene at every time)."""
    if scene.is_static:
        return
    moving = [o.name for o in scene.objects if not o.is_static]
    msg = (
        f"scene {scene.name!r}: objects {moving} move over time, but {what} draws only "
        "scenes whose objects keep a constant pose"
    )
    raise RenderError(msg)
