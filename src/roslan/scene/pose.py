"""Where a scene object is at a time: the pose seam of "the scene at t".

An object keeps its geometry in its own model frame (``SceneObject.local_vertices``,
scaled by ``SceneObject.scale``) and a :class:`PoseTrack`: its pose ``T_world_object``
as a function of trajectory time. Every object is constant today
(:class:`ConstantPose`); a moving object is one more :class:`PoseTrack`
(keyframes, a twist), and every consumer that already asks for
:meth:`Scene.at(t) <roslan.scene.model.Scene.at>` sees it move.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

__all__ = ["ConstantPose", "PoseTrack"]

F64 = NDArray[np.float64]


class PoseTrack(Protocol):
    """An object's pose over trajectory time."""

    @property
    def is_static(self) -> bool:
        """True when :meth:`at` is the same matrix at every time."""
        ...

    def at(self, t: float) -> F64:
        """(4, 4) float64 ``T_world_object`` at time ``t`` (s)."""
        ...

    def twist(self, t: float) -> tuple[F64, F64]:
        """World-frame linear velocity of the object's origin (3,) m/s and angular
        velocity (3,) rad/s at time ``t``."""
        ...


@dataclass(frozen=True, eq=False)
class ConstantPose:
    """A pose that does not change: ``at(t)`` is ``matrix`` for every ``t``."""

    matrix: F64

    @property
    def is_static(self) -> bool:
        return True

    def at(self, t: float) -> F64:
        return self.matrix

    def twist(self, t: float) -> tuple[F64, F64]:
        return np.zeros(3), np.zeros(3)
