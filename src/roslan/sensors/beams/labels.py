"""Labels of the beam sensors (``output.labels``): which instance and class each ray hit.

One scene lookup serves every beam sensor: the ray caster's hit record gives the triangle
each ray hit (:attr:`~roslan.render.raycast.Hits.triangle`), and the scene's per-triangle
instance and class ids (:func:`roslan.scene.instances.scene_labels`) give its label, in the
SemanticKITTI encoding (:func:`encode`): the class id in the low 16 bits, the instance id in
the high 16. A ray that hit nothing, or whose return the sensor model dropped (beyond the
maximum range, closer than the minimum, dropout), gets 0.

:func:`cast_labelled` is :meth:`BeamCaster.cast_incidence
<roslan.render.base.BeamCaster.cast_incidence>` plus the labels, from one cast: its
distances and echoes are bit for bit those of ``cast_incidence``, so a labelled scan has the
same points as an unlabelled one (tests/sensors/test_beam_labels.py).
"""

from __future__ import annotations

import weakref
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from roslan.scene.instances import scene_labels

if TYPE_CHECKING:
    from roslan.render.base import BeamCaster
    from roslan.scene.model import Scene
    from roslan.sensors.base import SimContext

__all__ = ["LABEL", "cast_labelled", "decode", "encode", "label_table", "triangle_labels"]

LABEL = np.dtype("<u4")
"""The label of one point or reading: ``class | instance << 16`` (SemanticKITTI)."""

U32 = NDArray[np.uint32]
F32 = NDArray[np.float32]

_TABLES: weakref.WeakKeyDictionary[Scene, U32] = weakref.WeakKeyDictionary()


def encode(class_id: ArrayLike, instance_id: ArrayLike) -> U32:
    """SemanticKITTI labels of (class, instance) ids (each 0 .. 65535)."""
    c = np.asarray(class_id, dtype=np.uint32)
    i = np.asarray(instance_id, dtype=np.uint32)
    out: U32 = (c & np.uint32(0xFFFF)) | (i << np.uint32(16))
    return out


def decode(label: ArrayLike) -> tuple[NDArray[np.uint16], NDArray[np.uint16]]:
    """(class ids, instance ids) of SemanticKITTI labels: ``label & 0xFFFF``, ``label >> 16``."""
    a = np.asarray(label, dtype=np.uint32)
    return (a & np.uint32(0xFFFF)).astype(np.uint16), (a >> np.uint32(16)).astype(np.uint16)


def triangle_labels(scene: Scene) -> U32:
    """(F,) the label of every triangle of ``Scene.triangles`` (the caster's triangle
    indices), computed once per scene; read-only."""
    table = _TABLES.get(scene)
    if table is None:
        lab = scene_labels(scene)
        table = encode(lab.triangle_class, lab.triangle_instance)
        table.flags.writeable = False
        _TABLES[scene] = table
    return table


def cast_labelled(
    caster: BeamCaster,
    origins: NDArray[np.floating[Any]],
    directions: NDArray[np.floating[Any]],
    max_range: float,
    table: U32,
    *,
    t: float | ArrayLike | None = None,
) -> tuple[F32, F32, U32]:
    """``caster.cast_incidence(origins, directions, max_range, t=t)`` and the label
    (:data:`LABEL`, 0 for no hit) of each ray, from one :meth:`~BeamCaster.cast`.

    ``table`` is :func:`triangle_labels` of the caster's scene. The echo is formed as
    ``cast_incidence`` forms it (``reflectivity * |n . d|`` in float32, the same order of
    operations; the hit record's normal faces the ray, and ``|-x| = |x|``), so the two give
    the same bits.
    """
    hits = caster.cast(origins, directions, max_range, t=t)
    tri = hits.triangle
    hit = tri >= 0
    if table.shape[0] == 0 or not bool(hit.any()):
        n = tri.shape[0]
        return hits.distance, np.zeros(n, np.float32), np.zeros(n, np.uint32)
    n_, d = hits.normal, hits.directions
    cos = np.abs(n_[:, 0] * d[:, 0] + n_[:, 1] * d[:, 1] + n_[:, 2] * d[:, 2])
    echo = np.where(hit, hits.reflectivity * cos, np.float32(0.0)).astype(np.float32)
    label = np.where(hit, table[np.where(hit, tri, 0)], np.uint32(0)).astype(np.uint32)
    return hits.distance, echo, label


def label_table(ctx: SimContext, config: Any) -> U32 | None:
    """The scene's :func:`triangle_labels` when sensor ``config`` writes labels in this
    run (its config's ``writes_labels``: ``output.labels`` on and its own ``labels`` key
    not false), else None."""
    if not getattr(config, "writes_labels", False):
        return None
    return triangle_labels(ctx.scene)
