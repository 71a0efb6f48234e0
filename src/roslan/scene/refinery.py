"""The built-in ``refinery`` scene (see :mod:`roslan.scene.builtin` for what the seed
varies and the approach zone every built-in keeps clear).

:func:`refinery` builds the tanks, the distillation columns, the pipe rack and pipe runs,
the flare stack and buildings, the random clutter and the perching pipe in that order;
the order of the objects and of the random draws fixes the output.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from roslan.scene import textures as tx
from roslan.scene.builtin import SceneBuilder, at, box_at, each_part, material
from roslan.scene.classes import PartLabels
from roslan.scene.mesh import (
    LocalMesh,
    box,
    capsule,
    cylinder,
    cylinder_between,
    merge,
    pose_matrix,
    ring,
    sphere,
    transformed,
)
from roslan.scene.model import DAYLIGHT_SKY, Lights, Material, Scene
from roslan.scene.perch import perch_object

__all__ = ["REFINERY_GOAL", "refinery"]

REFINERY_GOAL = ((0.0, 0.0, 2.5), (0.0, 0.0, 0.25))
"""(position, rpy) of the top of the refinery's perching pipe (axis along F's y)."""


@dataclass(frozen=True)
class _Materials:
    ground: Material
    white: Material
    grey: Material
    steel: Material
    pipes: list[Material]
    concrete: Material
    red_white: Material


def _materials(seed: int) -> _Materials:
    ground = material("gravel", (1, 1, 1), tx.gravel(seed, 512), 0.2, 0.25)
    white = material(
        "tank_white", (1, 1, 1), tx.painted_metal(seed, (0.85, 0.85, 0.82), 256, ribs=16), 0.25, 0.7
    )
    grey = material("column_grey", (1, 1, 1), tx.painted_metal(seed, (0.55, 0.57, 0.6)), 1.0, 0.55)
    steel = material("steel_yellow", (1, 1, 1), tx.painted_metal(seed, (0.9, 0.7, 0.12)), 2.0, 0.6)
    pipe_colors = [
        (0.6, 0.6, 0.62),
        (0.75, 0.2, 0.12),
        (0.2, 0.45, 0.25),
        (0.85, 0.75, 0.2),
        (0.25, 0.35, 0.6),
    ]
    pipe_mats = [
        material(f"pipe_{i}", (1, 1, 1), tx.painted_metal(seed, c), 2.0, 0.6)
        for i, c in enumerate(pipe_colors)
    ]
    concrete = material("concrete", (1, 1, 1), tx.concrete(seed, 256, 0.62), 0.5, 0.35)
    red_white = material(
        "flare_paint", (1, 1, 1), tx.hazard(256, ((0.85, 0.12, 0.1), (0.92, 0.92, 0.9))), 0.25, 0.6
    )
    return _Materials(ground, white, grey, steel, pipe_mats, concrete, red_white)


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
) -> tuple[LocalMesh, LocalMesh, PartLabels]:
    """(shell, steelwork, the steelwork's labels: its ladder, then each platform with its
    railing) of a distillation column standing on z = 0 at the origin."""
    shell = merge(
        [
            at(cylinder(radius + 0.2, 2.0, 32), (0.0, 0.0, 1.0)),  # skirt
            at(cylinder(radius, height - 2.0, 32), (0.0, 0.0, 2.0 + (height - 2.0) / 2)),
            at(sphere(radius, 32), (0.0, 0.0, height)),
        ]
    )
    steel = [at(_ladder(height), (radius + 0.25, 0.0, 0.0))]
    labels = PartLabels.whole("ladder", steel[0].n_triangles)
    for z in platforms:
        start = len(steel)
        steel.append(at(ring(radius, radius + 1.2, 0.08, 32), (0.0, 0.0, z)))
        steel.append(
            at(ring(radius + 1.15, radius + 1.2, 0.05, 32), (0.0, 0.0, z + 1.05))
        )  # handrail
        for a in np.linspace(0.0, 2 * math.pi, 10, endpoint=False):
            r = radius + 1.17
            steel.append(box((0.04, 0.04, 1.0), (r * math.cos(a), r * math.sin(a), z + 0.55)))
        labels += PartLabels.whole("platform", sum(p.n_triangles for p in steel[start:]))
    return shell, merge(steel), labels


def _tanks(b: SceneBuilder, m: _Materials) -> None:
    """Four storage tanks (64 segments) with spiral-ish stairs and concrete bunds."""
    tanks = [
        ((40.0, 30.0), 10.0, 12.0),
        ((40.0, -28.0), 9.0, 14.0),
        ((-38.0, 34.0), 8.0, 11.0),
        ((-40.0, -30.0), 11.0, 12.0),
    ]
    for i, ((x, y), r, h) in enumerate(tanks):
        shell = merge(
            [
                at(cylinder(r, h, 64), (0.0, 0.0, h / 2)),
                at(cylinder(r * 0.9, 0.8, 64), (0.0, 0.0, h + 0.4)),
            ]
        )
        b.add(f"tank_{i:02d}", shell, m.white, (x, y, 0.0), labels="tank")
        steps = []
        for j in range(int(h / 0.25)):
            a = j * 0.035
            z = (j + 1) * 0.25
            steps.append(
                at(
                    box((0.3, 0.9, 0.05), (0.0, 0.0, 0.0)),
                    ((r + 0.5) * math.cos(a), (r + 0.5) * math.sin(a), z),
                    (0.0, 0.0, a),
                )
            )
        n_steps = sum(p.n_triangles for p in steps)
        steps.append(at(ring(r, r + 1.0, 0.08, 64), (0.0, 0.0, h - 0.1)))  # roof walkway
        stairs = PartLabels.whole("stairs", n_steps) + PartLabels.whole(
            "platform", steps[-1].n_triangles
        )
        b.add(f"tank_{i:02d}_stairs", merge(steps), m.steel, (x, y, 0.0), labels=stairs)
        b.add(
            f"tank_{i:02d}_bund",
            merge(
                [box_at((2 * r + 8, 0.3, 1.0), 0.0, s * (r + 4), 0.0) for s in (-1, 1)]
                + [box_at((0.3, 2 * r + 8, 1.0), s * (r + 4), 0.0, 0.0) for s in (-1, 1)]
            ),
            m.concrete,
            (x, y, 0.0),
            labels="bund",
        )


def _columns(b: SceneBuilder, m: _Materials) -> None:
    """Three distillation columns with platforms and caged ladders."""
    cols = [((22.0, -6.0), 1.6, 32.0), ((26.0, 4.0), 1.2, 26.0), ((18.0, 12.0), 2.0, 22.0)]
    for i, ((x, y), r, h) in enumerate(cols):
        shell, steelwork, labels = _column(r, h, [z for z in np.arange(6.0, h - 2.0, 6.0)])
        b.add(f"column_{i:02d}", shell, m.grey, (x, y, 0.0), labels="distillation_column")
        b.add(f"column_{i:02d}_platforms", steelwork, m.steel, (x, y, 0.0), labels=labels)


def _pipe_rack(b: SceneBuilder, m: _Materials) -> Callable[[float], float]:
    """The pipe rack (bents every 6 m, pipes at two levels) along F's y axis, 20 m behind
    the goal (across every approach). Returns the world x of its centre line at a world y."""
    bents = []
    for y in np.arange(-42.0, 42.1, 6.0):
        for x in (-1.5, 1.5):
            bents.append(box_at((0.3, 0.3, 7.3), x, y, 0.0))
        bents.append(box((3.4, 0.3, 0.3), (0.0, y, 5.0)))
        bents.append(box((3.4, 0.3, 0.3), (0.0, y, 7.15)))
    bents += [box((0.2, 84.3, 0.2), (x, 0.0, 7.4)) for x in (-1.5, 1.5)]
    ryaw = REFINERY_GOAL[1][2]
    rc, rs = math.cos(ryaw), math.sin(ryaw)
    rack_pos = (-20.0 * rc, -20.0 * rs, 0.0)

    def rack_x(y: float) -> float:
        """World x of the rack's centre line at world y."""
        t = (y - rack_pos[1]) / rc
        return rack_pos[0] - t * rs

    b.add("pipe_rack", merge(bents), m.steel, rack_pos, ryaw, labels="pipe_rack")
    for lvl, z in enumerate((5.15, 7.3)):
        xs = np.linspace(-1.2, 1.2, 5)
        for k, xk in enumerate(xs):
            r = (0.08, 0.2, 0.12, 0.15, 0.1)[(k + lvl) % 5]
            pipe = cylinder_between((xk, -42.0, z + r), (xk, 42.0, z + r), r, 24)
            mat = m.pipes[(k + 2 * lvl) % 5]
            b.add(f"rack_pipe_{lvl}{k}", pipe, mat, rack_pos, ryaw, labels="pipe")
    return rack_x


def _pipe_runs(b: SceneBuilder, m: _Materials, rack_x: Callable[[float], float]) -> None:
    """Pipe runs from the rack to columns and tanks, with elbows (spheres) and supports."""
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
        parts += [at(sphere(rr * 1.15, 16), p) for p in pts[1:-1]]
        supports = []
        for p, q in itertools.pairwise(pts):
            if abs(p[2] - q[2]) < 1e-9 and p[2] > 1.0:
                seg = np.subtract(q, p)
                n_sup = int(np.linalg.norm(seg) // 8)
                for j in range(1, n_sup + 1):
                    c = np.add(p, seg * j / (n_sup + 1))
                    supports.append(box_at((0.2, 0.2, c[2] - rr), c[0], c[1], 0.0))
        b.add(f"pipe_run_{i:02d}", merge(parts), m.pipes[i % 5], labels="pipe")
        if supports:
            b.add(
                f"pipe_run_{i:02d}_supports",
                merge(supports),
                m.steel,
                labels=each_part("pipe_support", supports),
            )


def _flare_and_buildings(b: SceneBuilder, m: _Materials) -> None:
    """A guyed flare stack, the control building and two horizontal bullet tanks."""
    fx, fy, fh = -45.0, -5.0, 45.0
    flare = merge(
        [
            at(cylinder(0.6, fh, 32), (0.0, 0.0, fh / 2)),
            at(cylinder(0.9, 2.0, 32), (0.0, 0.0, fh + 1.0)),
            at(cylinder(1.2, 1.0, 32), (0.0, 0.0, 0.5)),
        ]
    )
    b.add("flare_stack", flare, m.red_white, (fx, fy, 0.0), labels="flare_stack")
    guys = []
    for a in (0.3, 0.3 + 2 * math.pi / 3, 0.3 + 4 * math.pi / 3):
        for z in (15.0, 30.0):
            guys.append(
                cylinder_between(
                    (0.0, 0.0, z), (20.0 * math.cos(a), 20.0 * math.sin(a), 0.0), 0.03, 6
                )
            )
    b.add(
        "flare_guy_wires",
        merge(guys),
        m.pipes[0],
        (fx, fy, 0.0),
        labels=each_part("guy_wire", guys),
    )
    b.add(
        "control_building",
        merge([box_at((12.0, 8.0, 4.0), 0.0, 0.0, 0.0), box_at((12.6, 8.6, 0.3), 0.0, 0.0, 4.0)]),
        m.concrete,
        (-5.0, -35.0, 0.0),
        labels="building",
    )
    for i, (x, y) in enumerate(((8.0, -30.0), (8.0, -25.0))):
        bullet = merge(
            [at(capsule(1.5, 12.0, 32), (0.0, 0.0, 2.0), (0.0, math.pi / 2, 0.0))]
            + [box_at((0.8, 2.4, 1.0), sx, 0.0, 0.0) for sx in (-3.0, 3.0)]
        )
        b.add(f"bullet_tank_{i}", bullet, m.white, (x, y, 0.0), labels="tank")


def _clutter(b: SceneBuilder, rng: np.random.Generator, m: _Materials) -> None:
    """Random clutter: drums, valves and crates around the plant."""
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
        labels: PartLabels | str
        if i % 3 == 0:
            drums = [at(cylinder(0.29, 0.88, 24), (dx, 0.0, 0.44)) for dx in (-0.3, 0.3)]
            mesh, labels = merge(drums), each_part("barrel", drums)
        elif i % 3 == 1:
            mesh = merge(
                [
                    at(cylinder(0.15, 1.2, 24), (0.0, 0.0, 0.6)),
                    at(sphere(0.3, 16), (0.0, 0.0, 1.2)),
                    at(cylinder(0.4, 0.05, 24), (0.0, 0.0, 1.55)),
                ]
            )
            labels = "valve"
        else:
            s = rng.uniform(0.6, 1.2)
            mesh, labels = box_at((s, s, s * 0.8), 0.0, 0.0, 0.0), "crate"
        mat = m.pipes[int(rng.integers(0, 5))]
        b.add(f"clutter_{i:02d}", mesh, mat, (x, y, 0.0), yaw, labels=labels)


def refinery(seed: int = 0) -> Scene:
    """An open-air refinery: gravel ground, four storage tanks with stairs, three distillation
    columns with platforms and caged ladders, a pipe rack with pipe runs, a guyed flare
    stack, a control building and a perching pipe whose top is :data:`REFINERY_GOAL`."""
    rng = tx.rng_for(seed, "refinery")
    b = SceneBuilder(REFINERY_GOAL)
    m = _materials(seed)
    b.add(
        "ground", box((240.0, 240.0, 0.2), (0.0, 0.0, -0.1)), m.ground, check=False, labels="ground"
    )
    _tanks(b, m)
    _columns(b, m)
    rack_x = _pipe_rack(b, m)
    _pipe_runs(b, m, rack_x)
    _flare_and_buildings(b, m)
    _clutter(b, rng, m)
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
