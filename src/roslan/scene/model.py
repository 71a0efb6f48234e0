"""The in-memory scene shared by the rasterizer and the ray caster.

A :class:`Scene` is built once (from a scene file or a built-in generator) and
handed to both back-ends, so images and beams see exactly the same triangles.
All geometry is in the world frame (ENU, metres), float32 for the GPU, with
per-object materials.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from roslan.scene.classes import PartLabels

__all__ = ["Lights", "Material", "Scene", "SceneObject"]

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
    """One rigid object, its triangles already posed and scaled into the world frame.

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

    @property
    def n_triangles(self) -> int:
        return int(self.faces.shape[0])


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

    def object(self, name: str) -> SceneObject:
        for o in self.objects:
            if o.name == name:
                return o
        raise KeyError(name)
