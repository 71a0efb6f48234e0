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
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from roslan.scene import textures as tx
from roslan.scene.mesh import (
    LocalMesh,
    box,
    capsule,
    cylinder,
    cylinder_between,
    merge,
    place,
    plane,
    pose_matrix,
    ring,
    sphere,
    transformed,
)
from roslan.scene.model import DAYLIGHT_SKY, Lights, Material, Scene, SceneObject
from roslan.scene.perch import perch_object

__all__ = [
    "APPROACH_ZONE",
    "REFINERY_GOAL",
    "WAREHOUSE_GOAL",
    "empty",
    "refinery",
    "warehouse",
]

F64 = NDArray[np.float64]

WAREHOUSE_GOAL = ((2.0, -1.0, 0.01), (0.0, 0.0, 0.3))
"""(position, rpy) of the warehouse landing marker's top centre."""
REFINERY_GOAL = ((0.0, 0.0, 2.5), (0.0, 0.0, 0.25))
"""(position, rpy) of the top of the refinery's perching pipe (axis along F's y)."""
APPROACH_ZONE = ((-12.5, 2.0), (-9.0, 9.0))
"""(x range, y range) in the goal frame F kept free of obstacles (m)."""


# --------------------------------------------------------------------------- helpers
class _Builder:
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
    ) -> None:
        T = pose_matrix(position, (0.0, 0.0, yaw))
        obj = place(name, mesh, material, T, source=f"builtin:{name}")
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


def _at(
    mesh: LocalMesh, position: Sequence[float], rpy: Sequence[float] = (0.0, 0.0, 0.0)
) -> LocalMesh:
    return transformed(mesh, pose_matrix(position, rpy))


def _box_at(size: Sequence[float], x: float, y: float, z0: float) -> LocalMesh:
    """Box standing on z0 with its footprint centred at (x, y)."""
    return box(size, (x, y, z0 + size[2] / 2.0))


def _pallet() -> LocalMesh:
    """EUR pallet (1.2 x 0.8 x 0.144 m) in its own frame, standing on z = 0."""
    parts = []
    for x in (-0.55, -0.3, 0.0, 0.3, 0.55):
        parts.append(box((0.1, 0.8, 0.022), (x, 0.0, 0.133)))
    for y in (-0.35, 0.0, 0.35):
        parts.append(box((1.2, 0.1, 0.022), (0.0, y, 0.111)))
        for x in (-0.5, 0.0, 0.5):
            parts.append(box((0.14, 0.1, 0.078), (x, y, 0.061)))
        parts.append(box((1.2, 0.1, 0.022), (0.0, y, 0.011)))
    return merge(parts)


def _forklift() -> tuple[LocalMesh, LocalMesh]:
    """(body, wheels+forks) of a ~2.9 m forklift standing on z = 0, forks along +x."""
    body = merge(
        [
            _box_at((1.9, 1.1, 1.0), -0.2, 0.0, 0.25),
            _box_at((0.5, 1.1, 0.6), -1.0, 0.0, 1.25),  # counterweight
            _box_at((0.06, 0.06, 1.0), 0.5, 0.5, 1.25),  # cab pillars
            _box_at((0.06, 0.06, 1.0), 0.5, -0.5, 1.25),
            _box_at((0.06, 0.06, 1.0), -0.7, 0.5, 1.25),
            _box_at((0.06, 0.06, 1.0), -0.7, -0.5, 1.25),
            _box_at((1.3, 1.1, 0.06), -0.1, 0.0, 2.25),  # overhead guard
            _box_at((0.4, 0.5, 0.5), -0.3, 0.0, 1.25),  # seat
        ]
    )
    wheel = cylinder(0.28, 0.22, 24)
    parts = [
        _at(wheel, (x, y, 0.28), (math.pi / 2, 0.0, 0.0))
        for x in (0.45, -0.85)
        for y in (-0.45, 0.45)
    ]
    parts += [_box_at((0.1, 0.1, 2.4), 0.85, y, 0.1) for y in (-0.35, 0.35)]  # mast
    parts += [_box_at((1.1, 0.12, 0.05), 1.45, y, 0.1) for y in (-0.3, 0.3)]  # forks
    return body, merge(parts)


def _mat(
    name: str, color: Sequence[float], tex: NDArray[np.uint8] | None, scale: float, refl: float
) -> Material:
    if tex is not None:
        tex.flags.writeable = False
    c = (float(color[0]), float(color[1]), float(color[2]))
    return Material(color=c, texture=tex, texture_scale=scale, reflectivity=refl, name=name)


# --------------------------------------------------------------------------- warehouse
def warehouse(seed: int = 0) -> Scene:
    """A 60 x 40 x 10 m warehouse: concrete floor with lane markings, clad walls, a roof
    with two skylight bands, roof beams, steel columns, 7 pallet racks with boxes,
    pallets, barrels, a forklift and a helipad-style landing marker at
    :data:`WAREHOUSE_GOAL`."""
    rng = tx.rng_for(seed, "warehouse")
    b = _Builder(WAREHOUSE_GOAL)
    concrete = _mat("concrete", (1, 1, 1), tx.concrete(seed, 512), 0.25, 0.35)
    cladding = _mat(
        "cladding", (1, 1, 1), tx.painted_metal(seed, (0.62, 0.66, 0.7), 256, ribs=8), 0.5, 0.5
    )
    roof = _mat(
        "roof", (1, 1, 1), tx.painted_metal(seed, (0.5, 0.52, 0.55), 256, ribs=8), 0.25, 0.4
    )
    steel = _mat("steel_blue", (1, 1, 1), tx.painted_metal(seed, (0.15, 0.28, 0.6)), 2.0, 0.55)
    orange = _mat("steel_orange", (1, 1, 1), tx.painted_metal(seed, (0.9, 0.42, 0.08)), 2.0, 0.6)
    yellow = _mat("paint_yellow", (1, 1, 1), tx.painted_metal(seed, (0.95, 0.78, 0.1)), 2.0, 0.8)
    cardboard = _mat("cardboard", (1, 1, 1), tx.cardboard(seed), 2.0, 0.45)
    wood = _mat("wood", (1, 1, 1), tx.wood(seed), 1.0, 0.4)
    hazard = _mat("hazard", (1, 1, 1), tx.hazard(), 2.0, 0.7)
    marker = _mat("landing_marker", (1, 1, 1), tx.landing_marker(512), 1.0 / 1.6, 0.9)

    L, W, H = 60.0, 40.0, 10.0
    b.add("floor", box((L, W, 0.2), (0.0, 0.0, -0.1)), concrete, check=False)
    walls = merge(
        [
            box((L, 0.3, H), (0.0, W / 2 + 0.15, H / 2)),
            box((L, 0.3, H), (0.0, -W / 2 - 0.15, H / 2)),
            box((0.3, W, H), (L / 2 + 0.15, 0.0, H / 2)),
            box((0.3, W, H), (-L / 2 - 0.15, 0.0, H / 2)),
        ]
    )
    b.add("walls", walls, cladding, check=False)
    # roof with two open skylight bands along x (y = -7..-5 and 5..7): the sun reaches the
    # floor in stripes crossed by the trusses' shadows (a closed roof would leave the
    # whole hall in shadow, lit by the ambient term alone)
    edges = (-W / 2 - 0.3, -7.0, -5.0, 5.0, 7.0, W / 2 + 0.3)
    slabs = [
        box((L + 0.6, y1 - y0, 0.2), (0.0, (y0 + y1) / 2, H + 0.1))
        for y0, y1 in zip(edges[0::2], edges[1::2], strict=True)
    ]
    b.add("roof", merge(slabs), roof, check=False)
    # roof trusses across y every 6 m: top and bottom chords plus diagonals
    truss_parts = []
    for x in np.arange(-27.0, 27.1, 6.0):
        truss_parts.append(box((0.25, W, 0.25), (x, 0.0, 9.85)))
        truss_parts.append(box((0.25, W, 0.2), (x, 0.0, 8.6)))
        for y in np.arange(-W / 2, W / 2 - 3.9, 4.0):
            truss_parts.append(cylinder_between((x, y, 8.7), (x, y + 2.0, 9.75), 0.05, 8))
            truss_parts.append(cylinder_between((x, y + 2.0, 9.75), (x, y + 4.0, 8.7), 0.05, 8))
    for y in (-12.0, 0.0, 12.0):
        truss_parts.append(box((L, 0.2, 0.2), (0.0, y, 9.6)))  # purlins
    b.add("roof_beams", merge(truss_parts), steel, check=False)
    # lamps under the beams (bright boxes: texture for cameras looking up)
    lamps = [
        box((1.2, 0.3, 0.1), (x, y, 8.4))
        for x in np.arange(-24.0, 24.1, 12.0)
        for y in (-10.0, 0.0, 10.0)
    ]
    b.add("lamps", merge(lamps), _mat("lamp", (0.98, 0.98, 0.95), None, 1.0, 0.9), check=False)
    # steel columns, hazard-striped feet
    cols, feet = [], []
    for x in (-24.0, -12.0, 12.0, 24.0):
        for y in (-14.5, 14.5):
            cols.append(_box_at((0.4, 0.4, H - 1.2), x, y, 1.2))
            feet.append(_box_at((0.42, 0.42, 1.2), x, y, 0.0))
    b.add("columns", merge(cols), steel)
    b.add("column_guards", merge(feet), hazard)

    # pallet racks: 4 bays of 2.7 m, 1.1 m deep, 4 beam levels, 6 m tall
    racks = [
        ((-18.0, 17.5), 0.0),
        ((-4.0, 17.5), 0.0),
        ((10.0, 17.5), 0.0),
        ((-12.0, -17.5), 0.0),
        ((14.0, -17.5), 0.0),
        ((19.0, 1.0), math.pi / 2),
        ((25.0, 1.0), math.pi / 2),
    ]
    levels = (0.15, 1.6, 3.05, 4.5)
    for k, ((rx, ry), yaw) in enumerate(racks, start=1):
        frame = []
        for i in range(5):
            x = -5.4 + 2.7 * i
            for y in (-0.5, 0.5):
                frame.append(_box_at((0.1, 0.08, 6.0), x, y, 0.0))
            for z in (1.0, 3.0, 5.0):  # bracing
                frame.append(box((0.05, 1.0, 0.05), (x, 0.0, z)))
        beams = []
        for z in levels[1:]:
            for y in (-0.52, 0.52):
                beams.append(box((10.8, 0.06, 0.12), (0.0, y, z - 0.06)))
        b.add(f"rack_{k:02d}_frame", merge(frame), steel, (rx, ry, 0.0), yaw)
        b.add(f"rack_{k:02d}_beams", merge(beams), orange, (rx, ry, 0.0), yaw)
        goods, pallets = [], []
        for bay in range(4):
            for lv, z in enumerate(levels):
                if rng.random() < 0.2:
                    continue  # empty slot
                for px in (-0.65, 0.65):
                    cx = -5.4 + 2.7 * bay + 1.35 + px
                    pallets.append(_at(_pallet(), (cx, 0.0, z), (0.0, 0.0, math.pi / 2)))
                    top = z + 0.144
                    clear = (levels[lv + 1] - 0.15 - top) if lv + 1 < len(levels) else 1.2
                    for _ in range(int(rng.integers(1, 4))):
                        sx, sy = rng.uniform(0.3, 0.75, 2)
                        sz = min(rng.uniform(0.25, 0.6), clear / 2)
                        ox = rng.uniform(-0.4 + sx / 2, 0.4 - sx / 2)
                        oy = rng.uniform(-0.55 + sy / 2, 0.55 - sy / 2)
                        goods.append(_box_at((sx, sy, sz), cx + ox, oy, top))
                        if rng.random() < 0.5 and top + 2 * sz < top + clear:
                            goods.append(_box_at((sx * 0.9, sy * 0.9, sz), cx + ox, oy, top + sz))
        if goods:
            b.add(f"rack_{k:02d}_boxes", merge(goods), cardboard, (rx, ry, 0.0), yaw)
        if pallets:
            b.add(f"rack_{k:02d}_pallets", merge(pallets), wood, (rx, ry, 0.0), yaw)

    # floor markings: aisle lines and a walkway frame around the landing area
    lines = [box((40.0, 0.12, 0.004), (0.0, y, 0.002)) for y in (-15.5, 15.5)]
    lines += [box((0.12, 28.0, 0.004), (x, 0.0, 0.002)) for x in (-27.0, 16.5)]
    b.add("floor_lines", merge(lines), yellow, check=False)
    gx, gy, gz = WAREHOUSE_GOAL[0]
    gyaw = WAREHOUSE_GOAL[1][2]
    b.add(
        "landing_marker",
        box((1.6, 1.6, gz), (0.0, 0.0, gz / 2.0)),
        marker,
        (gx, gy, 0.0),
        gyaw,
        check=False,
    )
    pad = [box((3.2, 0.08, 0.004), (0.0, s * 1.6, 0.002)) for s in (-1, 1)]
    pad += [box((0.08, 3.2, 0.004), (s * 1.6, 0.0, 0.002)) for s in (-1, 1)]
    b.add("landing_area_lines", merge(pad), yellow, (gx, gy, 0.0), gyaw, check=False)

    # random: loose pallet stacks, crates, barrels, a forklift (west and east parts)
    zones = [
        ((-28.0, -14.0), (-14.0, 14.0)),
        ((8.0, 16.0), (-14.0, 10.0)),
        ((-28.0, 28.0), (-14.0, 14.0)),
    ]
    for i in range(8):
        spot = b.free_spot(rng, *zones[i % 3], (0.7, 0.5))
        if spot is None:
            continue
        x, y, yaw = spot
        n = int(rng.integers(1, 6))
        stack = merge([_at(_pallet(), (0.0, 0.0, 0.144 * j)) for j in range(n)])
        b.add(f"pallet_stack_{i:02d}", stack, wood, (x, y, 0.0), yaw)
    for i in range(10):
        spot = b.free_spot(rng, *zones[i % 3], (0.6, 0.6))
        if spot is None:
            continue
        x, y, yaw = spot
        if i % 2:
            bar = merge(
                [
                    _at(cylinder(0.29, 0.88, 24), (dx, dy, 0.44))
                    for dx in (-0.3, 0.3)
                    for dy in (-0.3, 0.3)
                ]
            )
            color = (0.1, 0.25, 0.7) if rng.random() < 0.5 else (0.7, 0.12, 0.1)
            b.add(
                f"clutter_barrels_{i:02d}",
                bar,
                _mat(f"barrel{i}", (1, 1, 1), tx.painted_metal(seed, color), 2.0, 0.5),
                (x, y, 0.0),
                yaw,
            )
        else:
            sx, sy, sz = rng.uniform(0.6, 1.2, 3)
            crate = merge(
                [
                    _box_at((sx, sy, sz), 0.0, 0.0, 0.0),
                    _box_at((sx * 0.8, sy * 0.8, sz * 0.7), 0.0, 0.0, sz),
                ]
            )
            b.add(f"clutter_crates_{i:02d}", crate, cardboard, (x, y, 0.0), yaw)
    spot = b.free_spot(rng, (-28.0, -16.0), (-12.0, 12.0), (1.5, 0.7))
    if spot is not None:
        x, y, yaw = spot
        body, wheels = _forklift()
        b.add("forklift_body", body, yellow, (x, y, 0.0), yaw)
        b.add(
            "forklift_wheels_mast",
            wheels,
            _mat("rubber", (0.08, 0.08, 0.08), None, 1.0, 0.1),
            (x, y, 0.0),
            yaw,
        )
    lights = Lights(
        sun_direction=(0.2, 0.1, -1.0), sun_intensity=0.7, ambient=0.45, sky=DAYLIGHT_SKY
    )
    return b.scene("warehouse", lights, WAREHOUSE_GOAL)


# --------------------------------------------------------------------------- refinery
def _ladder(height: float, z0: float = 0.0) -> LocalMesh:
    """Caged ladder along z at the origin, rungs across y (0.45 m wide)."""
    parts = [box((0.05, 0.05, height), (0.0, y, z0 + height / 2)) for y in (-0.225, 0.225)]
    parts += [box((0.03, 0.45, 0.03), (0.0, 0.0, z)) for z in np.arange(z0 + 0.3, z0 + height, 0.3)]
    hoops = [
        transformed(ring(0.33, 0.36, 0.04, 12), pose_matrix((0.35, 0.0, z)))
        for z in np.arange(z0 + 2.5, z0 + height, 1.5)
    ]
    return merge(parts + hoops)


def _column(
    radius: float, height: float, platforms: Sequence[float]
) -> tuple[LocalMesh, LocalMesh]:
    """(shell, steelwork) of a distillation column standing on z = 0 at the origin."""
    shell = merge(
        [
            _at(cylinder(radius + 0.2, 2.0, 32), (0.0, 0.0, 1.0)),  # skirt
            _at(cylinder(radius, height - 2.0, 32), (0.0, 0.0, 2.0 + (height - 2.0) / 2)),
            _at(sphere(radius, 32), (0.0, 0.0, height)),
        ]
    )
    steel = [_at(_ladder(height), (radius + 0.25, 0.0, 0.0))]
    for z in platforms:
        steel.append(_at(ring(radius, radius + 1.2, 0.08, 32), (0.0, 0.0, z)))
        steel.append(
            _at(ring(radius + 1.15, radius + 1.2, 0.05, 32), (0.0, 0.0, z + 1.05))
        )  # handrail
        for a in np.linspace(0.0, 2 * math.pi, 10, endpoint=False):
            r = radius + 1.17
            steel.append(box((0.04, 0.04, 1.0), (r * math.cos(a), r * math.sin(a), z + 0.55)))
    return shell, merge(steel)


def refinery(seed: int = 0) -> Scene:
    """An open-air refinery: gravel ground, four storage tanks with stairs, three distillation
    columns with platforms and caged ladders, a pipe rack with pipe runs, a guyed flare
    stack, a control building and a perching pipe whose top is :data:`REFINERY_GOAL`."""
    rng = tx.rng_for(seed, "refinery")
    b = _Builder(REFINERY_GOAL)
    ground = _mat("gravel", (1, 1, 1), tx.gravel(seed, 512), 0.2, 0.25)
    white = _mat(
        "tank_white", (1, 1, 1), tx.painted_metal(seed, (0.85, 0.85, 0.82), 256, ribs=16), 0.25, 0.7
    )
    grey = _mat("column_grey", (1, 1, 1), tx.painted_metal(seed, (0.55, 0.57, 0.6)), 1.0, 0.55)
    steel = _mat("steel_yellow", (1, 1, 1), tx.painted_metal(seed, (0.9, 0.7, 0.12)), 2.0, 0.6)
    pipe_colors = [
        (0.6, 0.6, 0.62),
        (0.75, 0.2, 0.12),
        (0.2, 0.45, 0.25),
        (0.85, 0.75, 0.2),
        (0.25, 0.35, 0.6),
    ]
    pipe_mats = [
        _mat(f"pipe_{i}", (1, 1, 1), tx.painted_metal(seed, c), 2.0, 0.6)
        for i, c in enumerate(pipe_colors)
    ]
    concrete = _mat("concrete", (1, 1, 1), tx.concrete(seed, 256, 0.62), 0.5, 0.35)
    red_white = _mat(
        "flare_paint", (1, 1, 1), tx.hazard(256, ((0.85, 0.12, 0.1), (0.92, 0.92, 0.9))), 0.25, 0.6
    )

    b.add("ground", box((240.0, 240.0, 0.2), (0.0, 0.0, -0.1)), ground, check=False)
    # storage tanks (64 segments) with spiral-ish stairs
    tanks = [
        ((40.0, 30.0), 10.0, 12.0),
        ((40.0, -28.0), 9.0, 14.0),
        ((-38.0, 34.0), 8.0, 11.0),
        ((-40.0, -30.0), 11.0, 12.0),
    ]
    for i, ((x, y), r, h) in enumerate(tanks):
        shell = merge(
            [
                _at(cylinder(r, h, 64), (0.0, 0.0, h / 2)),
                _at(cylinder(r * 0.9, 0.8, 64), (0.0, 0.0, h + 0.4)),
            ]
        )
        b.add(f"tank_{i:02d}", shell, white, (x, y, 0.0))
        steps = []
        for j in range(int(h / 0.25)):
            a = j * 0.035
            z = (j + 1) * 0.25
            steps.append(
                _at(
                    box((0.3, 0.9, 0.05), (0.0, 0.0, 0.0)),
                    ((r + 0.5) * math.cos(a), (r + 0.5) * math.sin(a), z),
                    (0.0, 0.0, a),
                )
            )
        rail_a = [(r + 0.95) * math.cos(a) for a in (0.0, 0.035 * h / 0.25)]
        steps.append(_at(ring(r, r + 1.0, 0.08, 64), (0.0, 0.0, h - 0.1)))  # roof walkway
        del rail_a
        b.add(f"tank_{i:02d}_stairs", merge(steps), steel, (x, y, 0.0))
        b.add(
            f"tank_{i:02d}_bund",
            merge(
                [_box_at((2 * r + 8, 0.3, 1.0), 0.0, s * (r + 4), 0.0) for s in (-1, 1)]
                + [_box_at((0.3, 2 * r + 8, 1.0), s * (r + 4), 0.0, 0.0) for s in (-1, 1)]
            ),
            concrete,
            (x, y, 0.0),
        )
    # distillation columns
    cols = [((22.0, -6.0), 1.6, 32.0), ((26.0, 4.0), 1.2, 26.0), ((18.0, 12.0), 2.0, 22.0)]
    for i, ((x, y), r, h) in enumerate(cols):
        shell, steelwork = _column(r, h, [z for z in np.arange(6.0, h - 2.0, 6.0)])
        b.add(f"column_{i:02d}", shell, grey, (x, y, 0.0))
        b.add(f"column_{i:02d}_platforms", steelwork, steel, (x, y, 0.0))
    # pipe rack along y at x = -20: bents every 6 m, pipes at two levels
    bents = []
    for y in np.arange(-42.0, 42.1, 6.0):
        for x in (-1.5, 1.5):
            bents.append(_box_at((0.3, 0.3, 7.3), x, y, 0.0))
        bents.append(box((3.4, 0.3, 0.3), (0.0, y, 5.0)))
        bents.append(box((3.4, 0.3, 0.3), (0.0, y, 7.15)))
    bents += [box((0.2, 84.3, 0.2), (x, 0.0, 7.4)) for x in (-1.5, 1.5)]
    # the rack runs along F's y axis, 20 m behind the goal (across every approach)
    ryaw = REFINERY_GOAL[1][2]
    rc, rs = math.cos(ryaw), math.sin(ryaw)
    rack_pos = (-20.0 * rc, -20.0 * rs, 0.0)

    def rack_x(y: float) -> float:
        """World x of the rack's centre line at world y."""
        t = (y - rack_pos[1]) / rc
        return rack_pos[0] - t * rs

    b.add("pipe_rack", merge(bents), steel, rack_pos, ryaw)
    for lvl, z in enumerate((5.15, 7.3)):
        xs = np.linspace(-1.2, 1.2, 5)
        for k, xk in enumerate(xs):
            r = (0.08, 0.2, 0.12, 0.15, 0.1)[(k + lvl) % 5]
            pipe = cylinder_between((xk, -42.0, z + r), (xk, 42.0, z + r), r, 24)
            b.add(f"rack_pipe_{lvl}{k}", pipe, pipe_mats[(k + 2 * lvl) % 5], rack_pos, ryaw)
    # pipe runs from the rack to columns and tanks, with elbows (spheres)
    runs = [
        [(rack_x(24.0), 24.0, 6.0), (18.0, 24.0, 6.0), (18.0, 14.5, 6.0), (18.0, 14.5, 3.0)],
        [(rack_x(-24.0), -24.0, 6.0), (22.0, -24.0, 6.0), (22.0, -8.0, 6.0)],
        [(rack_x(36.0), 36.0, 4.0), (-34.0, 36.0, 4.0), (-34.0, 34.0, 1.0)],
        [(26.0, 5.5, 9.0), (26.0, 20.0, 9.0), (40.0, 20.0, 9.0), (40.0, 20.0, 12.0)],
        [(rack_x(-38.0), -38.0, 2.0), (-32.0, -38.0, 2.0), (-32.0, -30.0, 2.0)],
    ]
    for i, pts in enumerate(runs):
        rr = 0.15 + 0.05 * (i % 3)
        parts = [cylinder_between(p, q, rr, 24) for p, q in itertools.pairwise(pts)]
        parts += [_at(sphere(rr * 1.15, 16), p) for p in pts[1:-1]]
        supports = []
        for p, q in itertools.pairwise(pts):
            if abs(p[2] - q[2]) < 1e-9 and p[2] > 1.0:
                seg = np.subtract(q, p)
                n_sup = int(np.linalg.norm(seg) // 8)
                for j in range(1, n_sup + 1):
                    c = np.add(p, seg * j / (n_sup + 1))
                    supports.append(_box_at((0.2, 0.2, c[2] - rr), c[0], c[1], 0.0))
        b.add(f"pipe_run_{i:02d}", merge(parts), pipe_mats[i % 5])
        if supports:
            b.add(f"pipe_run_{i:02d}_supports", merge(supports), steel)
    # flare stack with guy wires
    fx, fy, fh = -45.0, -5.0, 45.0
    flare = merge(
        [
            _at(cylinder(0.6, fh, 32), (0.0, 0.0, fh / 2)),
            _at(cylinder(0.9, 2.0, 32), (0.0, 0.0, fh + 1.0)),
            _at(cylinder(1.2, 1.0, 32), (0.0, 0.0, 0.5)),
        ]
    )
    b.add("flare_stack", flare, red_white, (fx, fy, 0.0))
    guys = []
    for a in (0.3, 0.3 + 2 * math.pi / 3, 0.3 + 4 * math.pi / 3):
        for z in (15.0, 30.0):
            guys.append(
                cylinder_between(
                    (0.0, 0.0, z), (20.0 * math.cos(a), 20.0 * math.sin(a), 0.0), 0.03, 6
                )
            )
    b.add("flare_guy_wires", merge(guys), pipe_mats[0], (fx, fy, 0.0))
    # control building and horizontal bullet tanks (capsules)
    b.add(
        "control_building",
        merge([_box_at((12.0, 8.0, 4.0), 0.0, 0.0, 0.0), _box_at((12.6, 8.6, 0.3), 0.0, 0.0, 4.0)]),
        concrete,
        (-5.0, -35.0, 0.0),
    )
    for i, (x, y) in enumerate(((8.0, -30.0), (8.0, -25.0))):
        bullet = merge(
            [_at(capsule(1.5, 12.0, 32), (0.0, 0.0, 2.0), (0.0, math.pi / 2, 0.0))]
            + [_box_at((0.8, 2.4, 1.0), sx, 0.0, 0.0) for sx in (-3.0, 3.0)]
        )
        b.add(f"bullet_tank_{i}", bullet, white, (x, y, 0.0))
    # random clutter: drums, valves and crates around the plant
    zones = [
        ((-35.0, -25.0), (-20.0, 20.0)),
        ((5.0, 14.0), (-20.0, 20.0)),
        ((-15.0, 10.0), (15.0, 25.0)),
    ]
    for i in range(9):
        spot = b.free_spot(rng, *zones[i % 3], (0.7, 0.7))
        if spot is None:
            continue
        x, y, yaw = spot
        if i % 3 == 0:
            mesh = merge([_at(cylinder(0.29, 0.88, 24), (dx, 0.0, 0.44)) for dx in (-0.3, 0.3)])
        elif i % 3 == 1:
            mesh = merge(
                [
                    _at(cylinder(0.15, 1.2, 24), (0.0, 0.0, 0.6)),
                    _at(sphere(0.3, 16), (0.0, 0.0, 1.2)),
                    _at(cylinder(0.4, 0.05, 24), (0.0, 0.0, 1.55)),
                ]
            )
        else:
            s = rng.uniform(0.6, 1.2)
            mesh = _box_at((s, s, s * 0.8), 0.0, 0.0, 0.0)
        b.add(f"clutter_{i:02d}", mesh, pipe_mats[int(rng.integers(0, 5))], (x, y, 0.0), yaw)
    # the perching pipe (goal on its top) on two posts
    gp, gr = REFINERY_GOAL
    perch = perch_object(
        "pipe",
        pose_matrix(gp, gr),
        length=3.0,
        radius=0.08,
        supports=True,
        name="perching_pipe",
        seed=seed,
    )
    b.objects.append(perch)
    lights = Lights(
        sun_direction=(0.4, 0.3, -0.8), sun_intensity=1.0, ambient=0.35, sky=DAYLIGHT_SKY
    )
    return b.scene("refinery", lights, REFINERY_GOAL)


# --------------------------------------------------------------------------- empty
def empty(seed: int = 0) -> Scene:
    """A 200 x 200 m textured ground: the plane z = 0 (1 m checker squares with grain)."""
    ground = _mat("checker", (1, 1, 1), tx.checker(seed, 512, 8), 1.0 / 8.0, 0.5)
    obj = place("ground", plane((200.0, 200.0)), ground, source="builtin:ground")
    return Scene(
        name="empty",
        objects=(obj,),
        lights=Lights(sky=DAYLIGHT_SKY),
        goal_position=(0.0, 0.0, 0.0),
        goal_rpy=(0.0, 0.0, 0.0),
    )
