"""The built-in ``warehouse`` scene (see :mod:`roslan.scene.builtin` for what the seed
varies and the approach zone every built-in keeps clear).

:func:`warehouse` builds the hall, the racks, the floor markings and the random clutter
in that order; the order of the objects and of the random draws fixes the output.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from roslan.scene import textures as tx
from roslan.scene.builtin import SceneBuilder, at, box_at, each_part, material
from roslan.scene.classes import PartLabels
from roslan.scene.mesh import LocalMesh, box, cylinder, cylinder_between, merge
from roslan.scene.model import DAYLIGHT_SKY, Lights, Material, Scene

__all__ = ["WAREHOUSE_GOAL", "warehouse"]

WAREHOUSE_GOAL = ((2.0, -1.0, 0.01), (0.0, 0.0, 0.3))
"""(position, rpy) of the warehouse landing marker's top centre."""

HALL_SIZE = (60.0, 40.0, 10.0)
"""Hall length (x), width (y) and height (m)."""
RACK_LEVELS = (0.15, 1.6, 3.05, 4.5)
"""Heights of a pallet rack's beam levels (m)."""


@dataclass(frozen=True)
class _Materials:
    concrete: Material
    cladding: Material
    roof: Material
    steel: Material
    orange: Material
    yellow: Material
    cardboard: Material
    wood: Material
    hazard: Material
    marker: Material


def _materials(seed: int) -> _Materials:
    concrete = material("concrete", (1, 1, 1), tx.concrete(seed, 512), 0.25, 0.35)
    cladding = material(
        "cladding", (1, 1, 1), tx.painted_metal(seed, (0.62, 0.66, 0.7), 256, ribs=8), 0.5, 0.5
    )
    roof = material(
        "roof", (1, 1, 1), tx.painted_metal(seed, (0.5, 0.52, 0.55), 256, ribs=8), 0.25, 0.4
    )
    steel = material("steel_blue", (1, 1, 1), tx.painted_metal(seed, (0.15, 0.28, 0.6)), 2.0, 0.55)
    orange = material(
        "steel_orange", (1, 1, 1), tx.painted_metal(seed, (0.9, 0.42, 0.08)), 2.0, 0.6
    )
    yellow = material(
        "paint_yellow", (1, 1, 1), tx.painted_metal(seed, (0.95, 0.78, 0.1)), 2.0, 0.8
    )
    cardboard = material("cardboard", (1, 1, 1), tx.cardboard(seed), 2.0, 0.45)
    wood = material("wood", (1, 1, 1), tx.wood(seed), 1.0, 0.4)
    hazard = material("hazard", (1, 1, 1), tx.hazard(), 2.0, 0.7)
    marker = material("landing_marker", (1, 1, 1), tx.landing_marker(512), 1.0 / 1.6, 0.9)
    return _Materials(
        concrete, cladding, roof, steel, orange, yellow, cardboard, wood, hazard, marker
    )


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
            box_at((1.9, 1.1, 1.0), -0.2, 0.0, 0.25),
            box_at((0.5, 1.1, 0.6), -1.0, 0.0, 1.25),  # counterweight
            box_at((0.06, 0.06, 1.0), 0.5, 0.5, 1.25),  # cab pillars
            box_at((0.06, 0.06, 1.0), 0.5, -0.5, 1.25),
            box_at((0.06, 0.06, 1.0), -0.7, 0.5, 1.25),
            box_at((0.06, 0.06, 1.0), -0.7, -0.5, 1.25),
            box_at((1.3, 1.1, 0.06), -0.1, 0.0, 2.25),  # overhead guard
            box_at((0.4, 0.5, 0.5), -0.3, 0.0, 1.25),  # seat
        ]
    )
    wheel = cylinder(0.28, 0.22, 24)
    parts = [
        at(wheel, (x, y, 0.28), (math.pi / 2, 0.0, 0.0))
        for x in (0.45, -0.85)
        for y in (-0.45, 0.45)
    ]
    parts += [box_at((0.1, 0.1, 2.4), 0.85, y, 0.1) for y in (-0.35, 0.35)]  # mast
    parts += [box_at((1.1, 0.12, 0.05), 1.45, y, 0.1) for y in (-0.3, 0.3)]  # forks
    return body, merge(parts)


def _hall(b: SceneBuilder, m: _Materials) -> None:
    """Floor, walls, roof with skylights, roof trusses, lamps and steel columns."""
    L, W, H = HALL_SIZE
    b.add("floor", box((L, W, 0.2), (0.0, 0.0, -0.1)), m.concrete, check=False, labels="ground")
    wall_parts = [
        box((L, 0.3, H), (0.0, W / 2 + 0.15, H / 2)),
        box((L, 0.3, H), (0.0, -W / 2 - 0.15, H / 2)),
        box((0.3, W, H), (L / 2 + 0.15, 0.0, H / 2)),
        box((0.3, W, H), (-L / 2 - 0.15, 0.0, H / 2)),
    ]
    walls = merge(wall_parts)
    b.add("walls", walls, m.cladding, check=False, labels=each_part("wall", wall_parts))
    # roof with two open skylight bands along x (y = -7..-5 and 5..7): the sun reaches the
    # floor in stripes crossed by the trusses' shadows (a closed roof would leave the
    # whole hall in shadow, lit by the ambient term alone)
    edges = (-W / 2 - 0.3, -7.0, -5.0, 5.0, 7.0, W / 2 + 0.3)
    slabs = [
        box((L + 0.6, y1 - y0, 0.2), (0.0, (y0 + y1) / 2, H + 0.1))
        for y0, y1 in zip(edges[0::2], edges[1::2], strict=True)
    ]
    b.add("roof", merge(slabs), m.roof, check=False, labels="roof")
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
    b.add("roof_beams", merge(truss_parts), m.steel, check=False, labels="roof_beam")
    # lamps under the beams (bright boxes: texture for cameras looking up)
    lamps = [
        box((1.2, 0.3, 0.1), (x, y, 8.4))
        for x in np.arange(-24.0, 24.1, 12.0)
        for y in (-10.0, 0.0, 10.0)
    ]
    b.add(
        "lamps",
        merge(lamps),
        material("lamp", (0.98, 0.98, 0.95), None, 1.0, 0.9),
        check=False,
        labels=each_part("lamp", lamps),
    )
    # steel columns, hazard-striped feet
    cols, feet = [], []
    for x in (-24.0, -12.0, 12.0, 24.0):
        for y in (-14.5, 14.5):
            cols.append(box_at((0.4, 0.4, H - 1.2), x, y, 1.2))
            feet.append(box_at((0.42, 0.42, 1.2), x, y, 0.0))
    keys = [f"column_{k:02d}" for k in range(len(cols))]  # a column and its foot: one
    b.add("columns", merge(cols), m.steel, labels=each_part("column", cols, keys))
    b.add("column_guards", merge(feet), m.hazard, labels=each_part("column", feet, keys))


def _rack_structure() -> tuple[LocalMesh, LocalMesh]:
    """(frame, beams) of one pallet rack in its own frame: 4 bays of 2.7 m, 1.1 m deep,
    6 m tall."""
    frame = []
    for i in range(5):
        x = -5.4 + 2.7 * i
        for y in (-0.5, 0.5):
            frame.append(box_at((0.1, 0.08, 6.0), x, y, 0.0))
        for z in (1.0, 3.0, 5.0):  # bracing
            frame.append(box((0.05, 1.0, 0.05), (x, 0.0, z)))
    beams = []
    for z in RACK_LEVELS[1:]:
        for y in (-0.52, 0.52):
            beams.append(box((10.8, 0.06, 0.12), (0.0, y, z - 0.06)))
    return merge(frame), merge(beams)


def _rack_load(rng: np.random.Generator) -> tuple[list[LocalMesh], list[LocalMesh]]:
    """(boxes, pallets) on one rack's slots (about one slot in five left empty)."""
    levels = RACK_LEVELS
    goods, pallets = [], []
    for bay in range(4):
        for lv, z in enumerate(levels):
            if rng.random() < 0.2:
                continue  # empty slot
            for px in (-0.65, 0.65):
                cx = -5.4 + 2.7 * bay + 1.35 + px
                pallets.append(at(_pallet(), (cx, 0.0, z), (0.0, 0.0, math.pi / 2)))
                top = z + 0.144
                clear = (levels[lv + 1] - 0.15 - top) if lv + 1 < len(levels) else 1.2
                for _ in range(int(rng.integers(1, 4))):
                    sx, sy = rng.uniform(0.3, 0.75, 2)
                    sz = min(rng.uniform(0.25, 0.6), clear / 2)
                    ox = rng.uniform(-0.4 + sx / 2, 0.4 - sx / 2)
                    oy = rng.uniform(-0.55 + sy / 2, 0.55 - sy / 2)
                    goods.append(box_at((sx, sy, sz), cx + ox, oy, top))
                    if rng.random() < 0.5 and top + 2 * sz < top + clear:
                        goods.append(box_at((sx * 0.9, sy * 0.9, sz), cx + ox, oy, top + sz))
    return goods, pallets


def _racks(b: SceneBuilder, rng: np.random.Generator, m: _Materials) -> None:
    """7 pallet racks (4 beam levels) with random boxes and pallets on them."""
    racks = [
        ((-18.0, 17.5), 0.0),
        ((-4.0, 17.5), 0.0),
        ((10.0, 17.5), 0.0),
        ((-12.0, -17.5), 0.0),
        ((14.0, -17.5), 0.0),
        ((19.0, 1.0), math.pi / 2),
        ((25.0, 1.0), math.pi / 2),
    ]
    for k, ((rx, ry), yaw) in enumerate(racks, start=1):
        frame, beams = _rack_structure()
        rack = PartLabels.whole("rack", frame.n_triangles, f"rack_{k:02d}")
        b.add(f"rack_{k:02d}_frame", frame, m.steel, (rx, ry, 0.0), yaw, labels=rack)
        rack = PartLabels.whole("rack", beams.n_triangles, f"rack_{k:02d}")
        b.add(f"rack_{k:02d}_beams", beams, m.orange, (rx, ry, 0.0), yaw, labels=rack)
        goods, pallets = _rack_load(rng)
        if goods:
            b.add(
                f"rack_{k:02d}_boxes",
                merge(goods),
                m.cardboard,
                (rx, ry, 0.0),
                yaw,
                labels=each_part("box", goods),
            )
        if pallets:
            b.add(
                f"rack_{k:02d}_pallets",
                merge(pallets),
                m.wood,
                (rx, ry, 0.0),
                yaw,
                labels=each_part("pallet", pallets),
            )


def _markings(b: SceneBuilder, m: _Materials) -> None:
    """Floor markings: aisle lines, the landing marker and a walkway frame around it."""
    lines = [box((40.0, 0.12, 0.004), (0.0, y, 0.002)) for y in (-15.5, 15.5)]
    lines += [box((0.12, 28.0, 0.004), (x, 0.0, 0.002)) for x in (-27.0, 16.5)]
    b.add("floor_lines", merge(lines), m.yellow, check=False, labels="floor_marking")
    gx, gy, gz = WAREHOUSE_GOAL[0]
    gyaw = WAREHOUSE_GOAL[1][2]
    b.add(
        "landing_marker",
        box((1.6, 1.6, gz), (0.0, 0.0, gz / 2.0)),
        m.marker,
        (gx, gy, 0.0),
        gyaw,
        check=False,
        labels="landing_marker",
    )
    pad = [box((3.2, 0.08, 0.004), (0.0, s * 1.6, 0.002)) for s in (-1, 1)]
    pad += [box((0.08, 3.2, 0.004), (s * 1.6, 0.0, 0.002)) for s in (-1, 1)]
    b.add(
        "landing_area_lines",
        merge(pad),
        m.yellow,
        (gx, gy, 0.0),
        gyaw,
        check=False,
        labels="floor_marking",
    )


def _clutter(b: SceneBuilder, rng: np.random.Generator, seed: int, m: _Materials) -> None:
    """Random loose pallet stacks, crates, barrels and a forklift (west and east parts)."""
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
        layers = [at(_pallet(), (0.0, 0.0, 0.144 * j)) for j in range(n)]
        b.add(
            f"pallet_stack_{i:02d}",
            merge(layers),
            m.wood,
            (x, y, 0.0),
            yaw,
            labels=each_part("pallet", layers),
        )
    for i in range(10):
        spot = b.free_spot(rng, *zones[i % 3], (0.6, 0.6))
        if spot is None:
            continue
        x, y, yaw = spot
        if i % 2:
            drums = [
                at(cylinder(0.29, 0.88, 24), (dx, dy, 0.44))
                for dx in (-0.3, 0.3)
                for dy in (-0.3, 0.3)
            ]
            bar = merge(drums)
            color = (0.1, 0.25, 0.7) if rng.random() < 0.5 else (0.7, 0.12, 0.1)
            b.add(
                f"clutter_barrels_{i:02d}",
                bar,
                material(f"barrel{i}", (1, 1, 1), tx.painted_metal(seed, color), 2.0, 0.5),
                (x, y, 0.0),
                yaw,
                labels=each_part("barrel", drums),
            )
        else:
            sx, sy, sz = rng.uniform(0.6, 1.2, 3)
            crates = [
                box_at((sx, sy, sz), 0.0, 0.0, 0.0),
                box_at((sx * 0.8, sy * 0.8, sz * 0.7), 0.0, 0.0, sz),
            ]
            b.add(
                f"clutter_crates_{i:02d}",
                merge(crates),
                m.cardboard,
                (x, y, 0.0),
                yaw,
                labels=each_part("crate", crates),
            )
    spot = b.free_spot(rng, (-28.0, -16.0), (-12.0, 12.0), (1.5, 0.7))
    if spot is not None:
        x, y, yaw = spot
        body, wheels = _forklift()
        fork = PartLabels.whole("forklift", body.n_triangles, "forklift")
        b.add("forklift_body", body, m.yellow, (x, y, 0.0), yaw, labels=fork)
        b.add(
            "forklift_wheels_mast",
            wheels,
            material("rubber", (0.08, 0.08, 0.08), None, 1.0, 0.1),
            (x, y, 0.0),
            yaw,
            labels=PartLabels.whole("forklift", wheels.n_triangles, "forklift"),
        )


def warehouse(seed: int = 0) -> Scene:
    """A 60 x 40 x 10 m warehouse: concrete floor with lane markings, clad walls, a roof
    with two skylight bands, roof beams, steel columns, 7 pallet racks with boxes,
    pallets, barrels, a forklift and a helipad-style landing marker at
    :data:`WAREHOUSE_GOAL`."""
    rng = tx.rng_for(seed, "warehouse")
    b = SceneBuilder(WAREHOUSE_GOAL)
    m = _materials(seed)
    _hall(b, m)
    _racks(b, rng, m)
    _markings(b, m)
    _clutter(b, rng, seed, m)
    lights = Lights(
        sun_direction=(0.2, 0.1, -1.0), sun_intensity=0.7, ambient=0.45, sky=DAYLIGHT_SKY
    )
    return b.scene("warehouse", lights, WAREHOUSE_GOAL)
