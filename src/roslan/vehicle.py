"""The ``vehicle:`` config block: the airframe's body and the points it touches down on.

Everything is in ``base_link`` (x forward, y left, z up; metres). The body is a box or an
ellipsoid (``size`` = full extents along x, y, z, centred on ``center``); the clearance
check keeps it, and every sensor, out of the scene for the whole run. The contact point
is where the vehicle meets the surface at touchdown:

* ``feet``: the landing gear; the contact is below the feet's centroid at the lowest
  foot's height (level feet all touch a level goal at once);
* ``grasp``: the claw's grasp point, for perching;
* ``auto`` (default): ``grasp`` when the goal lies on a perch (the refinery's pipe, a
  scene file's ``perch:``), else ``feet``.

The trajectory's ``goal`` is where the contact point meets the surface. base_link's own
goal - the origin of the goal frame F of ``trajectory.csv`` - is the goal moved by the
contact point at the goal attitude: ``p_goal - R_goal @ contact``. trajectory.csv and the
ground truth keep describing base_link.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Annotated, Any, Literal, Protocol

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, model_validator

from roslan.config.base import Coord, FiniteFloat, Pose, StrictModel, Vec3

if TYPE_CHECKING:
    from roslan.trajectory.config import TrajectoryConfig

__all__ = [
    "Body",
    "Perches",
    "VehicleConfig",
    "base_link_trajectory",
    "body_points",
    "contact_depends_on_scene",
    "contact_point",
    "goal_on_perch",
    "resolve_contact",
    "vehicle_from_mapping",
]


class _Object(Protocol):
    @property
    def source(self) -> str: ...

    @property
    def vertices(self) -> NDArray[np.floating]: ...


class Perches(Protocol):
    """What the contact choice reads of a scene (:class:`roslan.scene.model.Scene`, which
    sits above the vehicle): its objects, the perches among them by ``source``."""

    @property
    def objects(self) -> Sequence[_Object]: ...


F64 = NDArray[np.float64]

Extent = Annotated[FiniteFloat, Field(gt=0.0, le=100.0)]


class Body(StrictModel):
    """The airframe's shape in base_link."""

    shape: Literal["ellipsoid", "box"] = "ellipsoid"
    size: tuple[Extent, Extent, Extent] = (0.30, 0.10, 0.08)
    """Full extents along base_link x, y, z (m): an ornithopter's fuselage without wings."""
    center: Vec3 = (0.0, 0.0, 0.0)
    """Centre of the shape in base_link (m)."""

    @property
    def bottom(self) -> float:
        """z of the body's lowest point in base_link (m)."""
        return float(self.center[2] - 0.5 * self.size[2])


Point = tuple[Coord, Coord, Coord]

DEFAULT_FEET: tuple[Point, ...] = (
    (0.05, 0.05, -0.08),
    (0.05, -0.05, -0.08),
    (-0.05, 0.05, -0.08),
    (-0.05, -0.05, -0.08),
)


class VehicleConfig(StrictModel):
    """``vehicle:`` block: body shape and contact points, in base_link (m)."""

    body: Body = Body()
    feet: Annotated[tuple[Point, ...], Field(min_length=1, max_length=16)] = DEFAULT_FEET
    """Landing-gear contact points: 4 cm legs under the default body."""
    grasp: Point = (0.0, 0.0, -0.08)
    """The claw's grasp point (perching); by default level with the feet."""
    contact: Literal["auto", "feet", "grasp"] = "auto"
    """Which contact meets the goal: ``auto`` = ``grasp`` on a perch, else ``feet``."""

    @model_validator(mode="after")
    def _below_body(self) -> VehicleConfig:
        bottom = self.body.bottom
        for key, points in (("feet", self.feet), ("grasp", (self.grasp,))):
            for p in points:
                if not p[2] < bottom:
                    which = key if key == "grasp" else f"feet point {list(p)}"
                    msg = (
                        f"{which}: z = {p[2]} m must lie below the body's bottom "
                        f"(body.center z - size z / 2 = {bottom:.4g} m), or the body would "
                        "enter the surface at touchdown"
                    )
                    raise ValueError(msg)
        return self


def contact_point(vehicle: VehicleConfig, contact: Literal["feet", "grasp"]) -> F64:
    """(3,) the contact point in base_link (m) for ``contact``."""
    if contact == "grasp":
        return np.asarray(vehicle.grasp, dtype=np.float64)
    feet = np.asarray(vehicle.feet, dtype=np.float64)
    return np.array([feet[:, 0].mean(), feet[:, 1].mean(), feet[:, 2].min()])


def contact_depends_on_scene(vehicle: VehicleConfig) -> bool:
    """Whether ``auto`` could pick different points (feet and grasp differ)."""
    return vehicle.contact == "auto" and not np.array_equal(
        contact_point(vehicle, "feet"), contact_point(vehicle, "grasp")
    )


def goal_on_perch(scene: Perches | None, goal: Pose) -> bool:
    """Whether ``goal`` lies on a perch object of ``scene`` (within 2 cm of its bounds)."""
    if scene is None:
        return False
    g = np.asarray(goal.position, dtype=np.float64)
    for obj in scene.objects:
        if not obj.source.startswith("builtin:perch:") or obj.vertices.shape[0] == 0:
            continue
        lo = obj.vertices.min(axis=0) - 0.02
        hi = obj.vertices.max(axis=0) + 0.02
        if bool(np.all((g >= lo) & (g <= hi))):
            return True
    return False


def resolve_contact(
    vehicle: VehicleConfig, scene: Perches | None, goal: Pose
) -> Literal["feet", "grasp"]:
    """``vehicle.contact`` with ``auto`` resolved against the scene."""
    if vehicle.contact != "auto":
        return vehicle.contact
    return "grasp" if goal_on_perch(scene, goal) else "feet"


def base_link_trajectory(
    trajectory: TrajectoryConfig, vehicle: VehicleConfig, scene: Perches | None = None
) -> TrajectoryConfig:
    """``trajectory`` with its goal moved from the contact point to base_link.

    At touchdown base_link has the goal's attitude ``R_goal``; the contact point ``c``
    (base_link) lies on ``goal.position`` when base_link is at ``goal.position - R_goal c``.
    A pose-file trajectory (``trajectory.file``: base_link's own poses) or a config
    without a ``goal`` is returned unchanged (the same object).
    """
    goal = getattr(trajectory, "goal", None)
    if not isinstance(goal, Pose) or getattr(trajectory, "file", None) is not None:
        return trajectory
    from roslan.frames import rpy_to_matrix

    c = contact_point(vehicle, resolve_contact(vehicle, scene, goal))
    R = rpy_to_matrix(np.asarray(goal.rpy, dtype=np.float64))
    p = np.asarray(goal.position, dtype=np.float64) - R @ c
    moved = Pose(position=(float(p[0]), float(p[1]), float(p[2])), rpy=goal.rpy)
    out: TrajectoryConfig = trajectory.model_copy(update={"goal": moved})
    return out


# 26 directions: the faces, edges and corners of a cube
_DIRS = np.array(
    [
        (x, y, z)
        for x in (-1.0, 0.0, 1.0)
        for y in (-1.0, 0.0, 1.0)
        for z in (-1.0, 0.0, 1.0)
        if (x, y, z) != (0.0, 0.0, 0.0)
    ]
)


def body_points(body: Body) -> F64:
    """(26, 3) points on the body's surface in base_link: a box's corners, edge middles
    and face centres, or the ellipsoid's points in the same 26 directions."""
    half = 0.5 * np.asarray(body.size, dtype=np.float64)
    if body.shape == "box":
        pts = _DIRS * half
    else:
        unit = _DIRS / np.linalg.norm(_DIRS, axis=1, keepdims=True)
        pts = unit * half
    out: F64 = pts + np.asarray(body.center, dtype=np.float64)
    return out


def vehicle_from_mapping(data: Mapping[str, Any] | None) -> VehicleConfig:
    """A :class:`VehicleConfig` from a saved (run.json) mapping, or the default."""
    return VehicleConfig() if data is None else VehicleConfig.model_validate(data)
