"""A moving pose track for the tests of the scene at a time (a constant twist)."""

from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class Sliding:
    """A test track: the t = 0 pose moved at constant velocity ``v``, turning at a
    constant rate ``w`` about the world z axis through the object's origin."""

    start: np.ndarray
    v: np.ndarray
    w: float

    @property
    def is_static(self) -> bool:
        return False

    def at(self, t: float) -> np.ndarray:
        T = self.start.copy()
        c, s = np.cos(self.w * t), np.sin(self.w * t)
        Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        T[:3, :3] = Rz @ self.start[:3, :3]
        T[:3, 3] = self.start[:3, 3] + self.v * t
        return T

    def twist(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        return self.v.copy(), np.array([0.0, 0.0, self.w])
