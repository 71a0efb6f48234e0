"""Object classes: the fixed class table of the built-in scenes and the labels of an object.

Id 0 is nothing (sky, or an object without a class); id 1, ``noise``, marks the event
camera's noise events (shot noise, leak events), which no surface caused. Every other id
names what a person would draw a box around. The ids are fixed: a class keeps its id in
every scene and every release (new classes are appended). A scene file's own class names
that are not in this table get the ids after it, in order of first appearance
(:func:`scene_classes`). docs/guide/scenes.md ("Classes and instances") lists the table;
tests/test_docs_facts.py checks that it equals :data:`BUILTIN_CLASSES`.

:class:`PartLabels` is what an object carries: its triangles cut into consecutive runs
(parts), each with a class name and an instance key. Parts (of one object or of several)
with the same key are one instance, e.g. a forklift's body and its wheels, or a column and
its foot guard.
"""

from __future__ import annotations

import colorsys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

__all__ = [
    "BUILTIN_CLASSES",
    "NOISE_CLASS",
    "NOISE_CLASS_ID",
    "UNLABELLED",
    "UNLABELLED_ID",
    "ClassInfo",
    "PartLabels",
    "class_color",
    "scene_class_table",
]

UNLABELLED = "unlabelled"
UNLABELLED_ID = 0
NOISE_CLASS = "noise"
NOISE_CLASS_ID = 1

BUILTIN_CLASSES: tuple[tuple[int, str, str], ...] = (
    (0, UNLABELLED, "nothing: the sky, or an object without a class"),
    (1, NOISE_CLASS, "event-camera noise (shot noise, leak events): caused by no surface"),
    (2, "ground", "the warehouse floor, the refinery's gravel, the empty scene's plane"),
    (3, "wall", "each hall wall"),
    (4, "roof", "the hall roof"),
    (5, "roof_beam", "the roof trusses and purlins (one instance)"),
    (6, "lamp", "each ceiling lamp"),
    (7, "column", "each steel hall column with its hazard-striped foot"),
    (8, "rack", "each pallet rack: frame and beams"),
    (9, "box", "each cardboard box on a rack"),
    (10, "pallet", "each pallet: on a rack or in a loose stack"),
    (11, "floor_marking", "the painted floor lines"),
    (12, "landing_marker", "the warehouse landing marker"),
    (13, "barrel", "each barrel or drum"),
    (14, "crate", "each crate (a crate and the smaller one on it are two)"),
    (15, "forklift", "the forklift: body, wheels, mast and forks"),
    (16, "tank", "each storage tank and each horizontal bullet tank"),
    (17, "stairs", "each tank's stair steps"),
    (18, "bund", "each tank's concrete bund wall"),
    (19, "distillation_column", "each distillation column shell"),
    (20, "platform", "each column platform with its railing, each tank-roof walkway"),
    (21, "ladder", "each caged ladder"),
    (22, "pipe_rack", "the pipe rack's steelwork"),
    (23, "pipe", "each pipe on the rack, each pipe run with its elbows"),
    (24, "pipe_support", "each pipe-run support post"),
    (25, "flare_stack", "the flare stack"),
    (26, "guy_wire", "each flare guy wire"),
    (27, "building", "the control building"),
    (28, "valve", "each valve"),
    (29, "perch", "a perch (bar, branch or pipe) with its posts"),
)
"""(id, name, what it covers) of every class of the built-in scenes, ids fixed."""

_BUILTIN_IDS = {name: cid for cid, name, _ in BUILTIN_CLASSES}


@dataclass(frozen=True)
class ClassInfo:
    """One row of a scene's class table: ``color`` sRGB 0-255 for label images."""

    id: int
    name: str
    color: tuple[int, int, int]


def class_color(class_id: int) -> tuple[int, int, int]:
    """A fixed, well-spread sRGB colour per class id (0: black; golden-ratio hues)."""
    if class_id == UNLABELLED_ID:
        return (0, 0, 0)
    if class_id == NOISE_CLASS_ID:
        return (255, 255, 255)
    h = (class_id * 0.618033988749895) % 1.0
    v = 0.95 if class_id % 2 else 0.75
    r, g, b = colorsys.hsv_to_rgb(h, 0.75, v)
    return (round(255 * r), round(255 * g), round(255 * b))


def scene_class_table(names: Iterable[str]) -> tuple[ClassInfo, ...]:
    """The class table of a scene whose objects use ``names`` (in object order): every
    built-in class, then each other name once, in order of first appearance."""
    rows = [ClassInfo(cid, name, class_color(cid)) for cid, name, _ in BUILTIN_CLASSES]
    known = dict(_BUILTIN_IDS)
    for name in names:
        if name not in known:
            cid = len(rows)
            known[name] = cid
            rows.append(ClassInfo(cid, name, class_color(cid)))
    return tuple(rows)


@dataclass(frozen=True)
class PartLabels:
    """The labels of one object's triangles: consecutive runs (parts) in face order.

    Attributes:
        classes: class name of each part.
        triangles: number of triangles of each part (they add up to the object's).
        instances: instance key of each part; None means the object's own name (one part)
            or ``<object>#<k>`` (part k of several). Equal keys are one instance.
    """

    classes: tuple[str, ...]
    triangles: tuple[int, ...]
    instances: tuple[str | None, ...]

    @classmethod
    def whole(cls, name: str, triangles: int, instance: str | None = None) -> PartLabels:
        """One class, one instance for all ``triangles``."""
        return cls((name,), (int(triangles),), (instance,))

    @classmethod
    def each(
        cls, name: str, counts: Sequence[int], instances: Sequence[str | None] | None = None
    ) -> PartLabels:
        """One instance of class ``name`` per run of ``counts`` triangles."""
        keys = tuple(instances) if instances is not None else (None,) * len(counts)
        return cls((name,) * len(counts), tuple(int(c) for c in counts), keys)

    def __add__(self, other: PartLabels) -> PartLabels:
        """The parts of ``self`` then those of ``other`` (labels of a merged mesh)."""
        return PartLabels(
            self.classes + other.classes,
            self.triangles + other.triangles,
            self.instances + other.instances,
        )

    @property
    def n_triangles(self) -> int:
        return int(sum(self.triangles))

    def keys(self, object_name: str) -> tuple[str, ...]:
        """The instance key of every part, defaults resolved."""
        if len(self.classes) == 1:
            return (self.instances[0] or object_name,)
        return tuple(k or f"{object_name}#{i}" for i, k in enumerate(self.instances))
