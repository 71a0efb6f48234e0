"""The scene file (YAML) model: the documented contract of scene files (docs/guide/scenes.md).

.. code-block:: yaml

    name: my_hangar
    lights: {sun: {direction: [0.3, 0.2, -1.0], intensity: 1.0}, ambient: 0.3}
    goal: {position: [0, 0, 0.01], rpy: [0, 0, 0]}        # optional suggested landing goal
    perch: {type: pipe, length: 1.5, radius: 0.05}           # optional perch placed at the goal
    objects:
      - name: rack_01
        mesh: models/rack.glb            # relative to this file: OBJ, glTF/GLB, STL, PLY
        pose: {position: [4.0, 2.0, 0.0], rpy: [0.0, 0.0, 1.57]}
        scale: [1.0, 1.0, 1.0]
        class: rack                      # optional: its class (an object without one is class 0)
      - name: floor
        primitive: {type: box, size: [60.0, 40.0, 0.1]}  # box|plane|cylinder|sphere|capsule
        pose: {position: [0, 0, -0.05], rpy: [0, 0, 0]}
        material: {color: [0.55, 0.55, 0.5], texture: textures/concrete.png,
                   texture_scale: 2.0, reflectivity: 0.3}

Primitives are centred at their pose origin (cylinder/capsule along local z); a plane
lies in local z = 0 facing +z. UVs of primitives are in metres, so ``texture_scale``
is texture repeats per metre.

Labels (see :mod:`roslan.scene.classes`): ``class`` names the object's class and makes it
one instance; ``instance`` names that instance (objects with the same ``instance`` are one,
e.g. a vehicle's body and wheels); ``parts`` instead cuts the object's triangles, in the
model's face order, into consecutive runs, each ``{class, triangles, instance}`` its own
instance (what ``roslan scene export`` writes for the built-ins' merged meshes).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from roslan.config.base import FiniteFloat, Pose, StrictModel, Vec3
from roslan.limits import MAX_SIZE_M, MIN_SIZE_M

__all__ = [
    "BoxSpec",
    "CapsuleSpec",
    "CylinderSpec",
    "LightsSpec",
    "MaterialSpec",
    "ObjectSpec",
    "PartSpec",
    "PerchSpec",
    "PlaneSpec",
    "PrimitiveSpec",
    "SceneFile",
    "SphereSpec",
    "SunSpec",
]

Pos = Annotated[FiniteFloat, Field(gt=0, le=MAX_SIZE_M)]
Size = Annotated[FiniteFloat, Field(ge=MIN_SIZE_M, le=MAX_SIZE_M)]
"""Every dimension of every primitive (one rule for all): MIN_SIZE_M to MAX_SIZE_M."""
Unit = Annotated[FiniteFloat, Field(ge=0, le=1)]
Segments = Annotated[int, Field(ge=3, le=512)]
Name = Annotated[str, Field(min_length=1, max_length=100, pattern=r"^[A-Za-z0-9_.\-]+$")]


class SunSpec(StrictModel):
    """Directional light: ``direction`` the light travels (world), ``intensity`` >= 0."""

    direction: Vec3 = (0.3, 0.2, -1.0)
    intensity: Annotated[FiniteFloat, Field(ge=0)] = 1.0

    @model_validator(mode="after")
    def _nonzero(self) -> SunSpec:
        if not any(self.direction):
            msg = "sun.direction must not be the zero vector"
            raise ValueError(msg)
        return self


class LightsSpec(StrictModel):
    """``sky``: linear RGB radiance in [0, 1] seen where no surface is hit (default black)."""

    sun: SunSpec = SunSpec()
    ambient: Unit = 0.3
    sky: tuple[Unit, Unit, Unit] = (0.0, 0.0, 0.0)


class MaterialSpec(StrictModel):
    """``color`` linear RGB in [0, 1] (multiplies the texture); ``texture`` an image file
    relative to the scene file; ``texture_scale`` repeats per metre (per UV unit);
    ``reflectivity`` LiDAR reflectivity in [0, 1]."""

    color: tuple[Unit, Unit, Unit] = (0.7, 0.7, 0.7)
    texture: str | None = None
    texture_scale: Pos = 1.0
    reflectivity: Unit = 0.5
    name: str | None = None


class BoxSpec(StrictModel):
    type: Literal["box"]
    size: tuple[Size, Size, Size]


class PlaneSpec(StrictModel):
    type: Literal["plane"]
    size: tuple[Size, Size]


class CylinderSpec(StrictModel):
    type: Literal["cylinder"]
    radius: Size
    height: Size
    segments: Segments = 32


class SphereSpec(StrictModel):
    type: Literal["sphere"]
    radius: Size
    segments: Segments = 24


class CapsuleSpec(StrictModel):
    """``height`` is the total length tip to tip (>= 2 radius)."""

    type: Literal["capsule"]
    radius: Size
    height: Size
    segments: Segments = 24

    @model_validator(mode="after")
    def _long_enough(self) -> CapsuleSpec:
        if self.height < 2 * self.radius:
            msg = f"capsule height {self.height} must be >= 2 * radius = {2 * self.radius}"
            raise ValueError(msg)
        return self


PrimitiveSpec = Annotated[
    BoxSpec | PlaneSpec | CylinderSpec | SphereSpec | CapsuleSpec, Field(discriminator="type")
]
PRIMITIVE_TYPES = ("box", "plane", "cylinder", "sphere", "capsule")


class PartSpec(StrictModel):
    """A run of ``triangles`` consecutive triangles of an object: one instance of ``class``
    (named ``instance``; default ``<object>#<index>``)."""

    class_: Name = Field(alias="class")
    triangles: Annotated[int, Field(ge=1)]
    instance: Name | None = None


class ObjectSpec(StrictModel):
    """One object: exactly one of ``mesh`` (file) or ``primitive``; at most one of
    ``class`` or ``parts``."""

    name: Name
    mesh: str | None = None
    primitive: PrimitiveSpec | None = None
    pose: Pose = Pose()
    scale: tuple[Pos, Pos, Pos] = (1.0, 1.0, 1.0)
    material: MaterialSpec = MaterialSpec()
    class_: Name | None = Field(default=None, alias="class")
    instance: Name | None = None
    parts: tuple[PartSpec, ...] | None = None

    @model_validator(mode="after")
    def _one_shape(self) -> ObjectSpec:
        if (self.mesh is None) == (self.primitive is None):
            msg = (
                "give exactly one of 'mesh' (a model file) or "
                "'primitive' ({type: box|plane|cylinder|sphere|capsule, ...})"
            )
            raise ValueError(msg)
        if self.parts is not None and (self.class_ is not None or self.instance is not None):
            msg = "give either 'class' (and 'instance') or 'parts', not both"
            raise ValueError(msg)
        if self.parts is not None and not self.parts:
            msg = "parts: an empty list; give at least one {class, triangles} or leave it out"
            raise ValueError(msg)
        if self.instance is not None and self.class_ is None:
            msg = f"instance {self.instance!r} without a 'class'; give the object's class too"
            raise ValueError(msg)
        return self


class PerchSpec(StrictModel):
    """A perch placed so that its top touches the goal (or ``pose``), its axis along the
    goal frame's y axis (across the approach). ``radius`` defaults per type (bar: half
    side 0.02 m, pipe 0.05 m, branch 0.03 m). ``supports`` adds posts down to z = 0."""

    type: Literal["bar", "branch", "pipe"]
    length: Size = 1.5
    radius: Size | None = None
    pose: Pose | None = None
    supports: bool = True
    name: Name = "perch"


class SceneFile(StrictModel):
    """A whole scene file. ``allow_external_paths: true`` lets mesh/texture paths be absolute
    or leave the scene's folder (off by default: a scene cannot read arbitrary files)."""

    name: Name
    lights: LightsSpec = LightsSpec()
    objects: tuple[ObjectSpec, ...] = ()
    goal: Pose | None = None
    perch: PerchSpec | None = None
    allow_external_paths: bool = False

    @model_validator(mode="after")
    def _unique_names(self) -> SceneFile:
        seen: dict[str, int] = {}
        names = [o.name for o in self.objects] + ([self.perch.name] if self.perch else [])
        for i, name in enumerate(names):
            if name in seen:
                where = f"objects[{i}]" if i < len(self.objects) else "perch"
                msg = (
                    f"{where}.name = {name!r}: duplicate object name (also objects[{seen[name]}]); "
                    "every object name must be unique"
                )
                raise ValueError(msg)
            seen[name] = i
        return self
