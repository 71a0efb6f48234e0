"""Built-in procedural scenes: ``warehouse``, ``refinery``, ``empty``.

Deterministic from the seed. The *structure* (floor, walls, columns, rack frames,
tanks, columns, pipe racks, goal) is fixed; the seed changes only what is meant to
vary: the textures' noise, the boxes on the racks (``rack_NN_boxes``), pallets,
clutter and forklift placement (``pallet_*``, ``clutter_*``, ``forklift*``).

Every built-in keeps an *approach zone* clear: in the goal frame F, the box
x in [-12.5, 2], |y| <= 9 (m) holds nothing taller than ``goal z - 1 m`` except the
goal's own marker or perch, so the default trajectory (start (-8, 2, 4.6) in F) and the
paper's dataset approaches (distance 8-12 m, elevation pi/6, heading in [-pi/4, pi/4],
any speed) reach the goal without collision; ceilings are above the starting heights.

This module holds the builder the scenes share and the ``empty`` scene;
:mod:`roslan.scene.warehouse` and :mod:`roslan.scene.refinery` build the other two.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from roslan.scene import textures as tx
from roslan.scene.classes import PartLabels
from roslan.scene.mesh import LocalMesh, box, place, plane, pose_matrix, transformed
from roslan.scene.model import DAYLIGHT_SKY, Lights, Material, Scene, SceneObject

__all__ = [
    "APPROACH_ZONE",
    "SceneBuilder",
    "at",
    "box_at",
    "each_part",
    "empty",
    "material",
]

F64 = NDArray[np.float64]

APPROACH_ZONE = ((-12.5, 2.0), (-9.0, 9.0))
"""(x range, y range) in the goal frame F kept free of obstacles (m)."""


# --------------------------------------------------------------------------- helpers
class SceneBuilder:
    """Collects objects; checks footprints against the approach zone."""

    def __init__(self, goal: tuple[Sequence[float], Sequence[float]]) -> None:
        self.objects: list[SceneObject] = []
        self.goal_T = pose_matrix(goal[0], goal[1])
        self.goal_z = float(goal[0][2])
        self.footprints: list[tuple[F64, str]] = []

    def add(
        self,
        name: str,
        mesh: LocalMesh,
        material: Material,
        position: Sequence[float] = (0.0, 0.0, 0.0),
        yaw: float = 0.0,
        *,
        check: bool = True,
        labels: PartLabels | str | None = None,
    ) -> None:
        """Place ``mesh`` as object ``name``; ``labels``: its parts' classes and instances
        (a class name: one instance of that class)."""
        T = pose_matrix(position, (0.0, 0.0, yaw))
        obj = place(name, mesh, material, T, source=f"builtin:{name}")
        if labels is not None:
            lab = PartLabels.whole(labels, mesh.n_triangles) if isinstance(labels, str) else labels
            assert lab.n_triangles == mesh.n_triangles, name
            obj = replace(obj, labels=lab)
        if check and self.blocks_approach(obj.vertices.astype(np.float64), faces=obj.faces):
            msg = f"built-in scene object {name!r} intrudes into the approach zone"
            raise AssertionError(msg)
        self.objects.append(obj)

    def to_goal(self, p_world: F64) -> F64:
        """(N, 3) world points -> goal frame F."""
        R = self.goal_T[:3, :3]
        return (p_world - self.goal_T[:3, 3]) @ R

    def blocks_approach(
        self, verts: F64, margin: float = 0.0, faces: NDArray[np.int32] | None = None
    ) -> bool:
        """Whether any triangle (or, without ``faces``, the hull of ``verts``) may reach into
        the approach zone above ``goal z - 1`` (conservative: bounds of each triangle in F)."""
        pf = self.to_goal(verts)
        tri = pf[faces] if faces is not None else pf[None]
        lo, hi = tri.min(axis=1), tri.max(axis=1)
        (x0, x1), (y0, y1) = APPROACH_ZONE
        hit = (
            (lo[:, 0] < x1 + margin)
            & (hi[:, 0] > x0 - margin)
            & (lo[:, 1] < y1 + margin)
            & (hi[:, 1] > y0 - margin)
            & (hi[:, 2] > -1.0)
        )
        return bool(hit.any())

    def free_spot(
        self,
        rng: np.random.Generator,
        xr: Sequence[float],
        yr: Sequence[float],
        half: Sequence[float],
        tries: int = 50,
    ) -> tuple[float, float, float] | None:
        """Random (x, y, yaw) in the world box whose footprint (half extents) avoids the
        approach zone and earlier random footprints."""
        for _ in range(tries):
            x = float(rng.uniform(xr[0], xr[1]))
            y = float(rng.uniform(yr[0], yr[1]))
            yaw = float(rng.uniform(-math.pi, math.pi))
            c, s = math.cos(yaw), math.sin(yaw)
            hx, hy = half
            corners = np.array([[sx * hx, sy * hy] for sx in (-1, 1) for sy in (-1, 1)]) @ np.array(
                [[c, s], [-s, c]]
            )
            corners += [x, y]
            pts = np.column_stack([corners, np.zeros(4)])
            if self.blocks_approach(pts, margin=0.5):
                continue
            r = math.hypot(hx, hy)
            if any(np.hypot(*(fp[:2] - [x, y])) < r + fp[2] for fp, _ in self.footprints):
                continue
            self.footprints.append((np.array([x, y, r]), ""))
            return x, y, yaw
        return None

    def scene(
        self, name: str, lights: Lights, goal: tuple[Sequence[float], Sequence[float]]
    ) -> Scene:
        gp, gr = goal
        return Scene(
            name=name,
            objects=tuple(self.objects),
            lights=lights,
            goal_position=(float(gp[0]), float(gp[1]), float(gp[2])),
            goal_rpy=(float(gr[0]), float(gr[1]), float(gr[2])),
        )


def at(
    mesh: LocalMesh, position: Sequence[float], rpy: Sequence[float] = (0.0, 0.0, 0.0)
) -> LocalMesh:
    return transformed(mesh, pose_matrix(position, rpy))


def box_at(size: Sequence[float], x: float, y: float, z0: float) -> LocalMesh:
    """Box standing on z0 with its footprint centred at (x, y)."""
    return box(size, (x, y, z0 + size[2] / 2.0))


def each_part(
    name: str, parts: Sequence[LocalMesh], keys: Sequence[str] | None = None
) -> PartLabels:
    """Labels of ``merge(parts)``: one instance of class ``name`` per mesh of ``parts``
    (optional instance ``keys``, one per mesh)."""
    return PartLabels.each(name, [p.n_triangles for p in parts], keys)


def material(
    name: str, color: Sequence[float], tex: NDArray[np.uint8] | None, scale: float, refl: float
) -> Material:
    if tex is not None:
        tex.flags.writeable = False
    c = (float(color[0]), float(color[1]), float(color[2]))
    return Material(color=c, texture=tex, texture_scale=scale, reflectivity=refl, name=name)


# --------------------------------------------------------------------------- empty
def empty(seed: int = 0) -> Scene:
    """A 200 x 200 m textured ground: the plane z = 0 (1 m checker squares with grain)."""
    ground = material("checker", (1, 1, 1), tx.checker(seed, 512, 8), 1.0 / 8.0, 0.5)
    obj = place("ground", plane((200.0, 200.0)), ground, source="builtin:ground")
    obj = replace(obj, labels=PartLabels.whole("ground", obj.n_triangles))
    return Scene(
        name="empty",
        objects=(obj,),
        lights=Lights(sky=DAYLIGHT_SKY),
        goal_position=(0.0, 0.0, 0.0),
        goal_rpy=(0.0, 0.0, 0.0),
    )
