"""The environment's observation: fixed-shape arrays built from one step's sensor taps.

Generic: every sensor kind declares its observation in its
:class:`~roslan.sensors.registry.SensorSpec` (an :class:`~roslan.sensors.measurements.
Observer`: its box and how a step's typed measurements fill it); this module only
gathers them, adds ``time`` and any constant entries (:meth:`ObservationBuilder.constant`).

Keys (docs/guide/closed-loop.md "Observation"):

* ``imu`` (the first IMU): ``(N, 8)`` float32 rows ``valid, dt, ax, ay, az, gx, gy, gz``:
  ``valid`` 1 for a sample and 0 for padding, ``dt`` its time minus the step's end (s,
  <= 0), the specific force (m/s^2) and body rates (rad/s) in the IMU frame. ``N`` is
  ``closed_loop.observation.max_imu_samples`` (default ``ceil(rate / control_rate) + 1``).
* ``events`` (the first event camera): ``count``: ``(2, H, W)`` float32 events per pixel
  and polarity (0: OFF, 1: ON) over the step; ``voxel``: ``(B, H, W)`` float32, each
  event's polarity spread linearly over ``B`` time bins spanning the step.
* ``<name>`` of every frame camera (the last frame: ``(H, W)`` or ``(H, W, 3)`` uint8 as
  published), stereo camera (both eyes' last frames, ``(2, ...)``, left then right),
  depth camera (``(H, W)`` float32 metres), range sensor (``sonar``, ``altimeter``:
  ``(1,)`` float32 metres, the last reading), 2-D laser (``(n_beams,)`` float32 metres,
  the last scan) and LiDAR (``(n_beams, 4)`` float32 rows ``valid, x, y, z`` of the last
  scan, sensor frame); a reading closer than ``min_range`` (REP 117's -inf) is
  ``min_range``, no echo (+inf) is ``max_range``; zeros until the first one.
* ``time``: ``(1,)`` float32, the step's end (s of trajectory time).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from roslan.config.closed_loop import ClosedLoopConfig
from roslan.sensors.base import SensorConfig
from roslan.sensors.measurements import (
    EventPacket,
    Observer,
    event_count_image,
    event_voxel_grid,
)
from roslan.sensors.registry import sensor_spec

__all__ = ["EventPacket", "ObservationBuilder", "event_count_image", "event_voxel_grid"]

F32 = NDArray[np.float32]


def _space(o: Observer) -> spaces.Box:
    b = o.box
    return spaces.Box(b.low, b.high, b.shape, b.dtype)


class ObservationBuilder:
    """The observation space of a config and each step's observation (module docstring)."""

    def __init__(self, sensors: Sequence[SensorConfig], closed_loop: ClosedLoopConfig) -> None:
        seen: Counter[str] = Counter()
        self.observers: list[Observer] = []
        for s in sensors:
            o = sensor_spec(s.type).observer(s, closed_loop, seen[s.type] == 0)
            seen[s.type] += 1
            if o is not None:
                self.observers.append(o)
        self._constants: dict[str, NDArray[Any]] = {}
        self._boxes: dict[str, spaces.Space[Any]] = {o.key: _space(o) for o in self.observers}
        self._boxes["time"] = spaces.Box(0.0, np.inf, (1,), np.float32)
        self.space = spaces.Dict(self._boxes)
        self._events = next((o for o in self.observers if hasattr(o, "packet")), None)

    def constant(self, key: str, value: Any, low: float = -np.inf, high: float = np.inf) -> None:
        """Add an entry that holds ``value`` (float32) in every step's observation, or
        give an existing one a new value of the same shape (a new episode's: the space
        does not change)."""
        v = np.asarray(value, dtype=np.float32)
        old = self._constants.get(key)
        if old is not None:
            if old.shape != v.shape:
                msg = f"constant observation {key!r}: shape {v.shape}, registered {old.shape}"
                raise ValueError(msg)
            self._constants[key] = v
            return
        self._constants[key] = v
        self._boxes[key] = spaces.Box(low, high, v.shape, np.float32)
        self.space = spaces.Dict(self._boxes)

    @property
    def ev_shape(self) -> tuple[int, int]:
        """(H, W) of the observed event camera ((0, 0): none)."""
        shape: tuple[int, int] = getattr(self._events, "shape", (0, 0))
        return shape

    def image(self) -> NDArray[np.uint8] | None:
        """The latest uint8 frame of the first observed image sensor (None: none yet)."""
        for o in self.observers:
            last = getattr(o, "last", None)
            if last is not None and last.dtype == np.uint8 and last.ndim >= 2:
                frame: NDArray[np.uint8] = last[0] if o.box.shape[0] == 2 else last
                return frame
        return None

    def reset(self) -> None:
        """Forget the last frames and ranges (a new episode)."""
        for o in self.observers:
            o.reset()

    def raw_events(self, taps: Mapping[str, Sequence[Any]]) -> EventPacket:
        """The step's raw events of the (first) event camera."""
        ev: Any = self._events
        if ev is None:
            return EventPacket.empty()
        packet: EventPacket = ev.packet(taps.get(ev.sensor, []))
        return packet

    def build(
        self, taps: Mapping[str, Sequence[Any]], span: tuple[int, int]
    ) -> dict[str, NDArray[Any]]:
        """The observation of a step from its taps; ``span``: (start, end) ns."""
        out = {o.key: o.observe(taps.get(o.sensor, []), span) for o in self.observers}
        for key, value in self._constants.items():
            out[key] = value.copy()
        out["time"] = np.array([span[1] * 1e-9], dtype=np.float32)
        return out
