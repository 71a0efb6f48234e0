"""The environment's observation: fixed-shape arrays built from one step's sensor taps.

Keys (docs/guide/closed-loop.md "Observation"):

* ``imu`` (the first IMU): ``(N, 8)`` float32 rows ``valid, dt, ax, ay, az, gx, gy, gz``:
  ``valid`` 1 for a sample and 0 for padding, ``dt`` its time minus the step's end (s,
  <= 0), the specific force (m/s^2) and body rates (rad/s) in the IMU frame. ``N`` is
  ``closed_loop.observation.max_imu_samples`` (default ``ceil(rate / control_rate) + 1``).
* ``events`` (the first event camera): ``count``: ``(2, H, W)`` float32 events per pixel
  and polarity (0: OFF, 1: ON) over the step; ``voxel``: ``(B, H, W)`` float32, each
  event's polarity spread linearly over ``B`` time bins spanning the step.
* ``<name>`` of every frame camera (the last frame: ``(H, W)`` or ``(H, W, 3)`` uint8 as
  published), depth camera (``(H, W)`` float32 metres), range sensor (``sonar``,
  ``altimeter``: ``(1,)`` float32 metres, the last reading) and 2-D laser (``(n_beams,)``
  float32 metres, the last scan); a reading closer than ``min_range`` (REP 117's -inf)
  is ``min_range``, no echo (+inf) is ``max_range``; zeros until the first one.
* ``time``: ``(1,)`` float32, the step's end (s of trajectory time).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from roslan.config.closed_loop import ClosedLoopConfig
from roslan.sensors.base import SensorConfig

__all__ = ["EventPacket", "ObservationBuilder", "event_count_image", "event_voxel_grid"]

F32 = NDArray[np.float32]

RANGE_TYPES = ("sonar", "altimeter", "laser")


def event_count_image(
    x: NDArray[Any], y: NDArray[Any], p: NDArray[Any], shape: tuple[int, int]
) -> F32:
    """(2, H, W) float32 events per pixel: channel 0 OFF (p <= 0), channel 1 ON (p > 0)."""
    h, w = shape
    ch = (np.asarray(p) > 0).astype(np.int64)
    flat = (ch * h + np.asarray(y, dtype=np.int64)) * w + np.asarray(x, dtype=np.int64)
    counts = np.bincount(flat, minlength=2 * h * w)
    return counts.reshape(2, h, w).astype(np.float32)


def event_voxel_grid(
    x: NDArray[Any],
    y: NDArray[Any],
    t: NDArray[Any],
    p: NDArray[Any],
    shape: tuple[int, int],
    bins: int,
    span: tuple[int, int],
) -> F32:
    """(bins, H, W) float32 voxel grid (Zhu et al., CVPR 2019): each event's polarity
    (+-1) split linearly between the two time bins around it; bin centres span ``span``
    (ns, step start to end)."""
    h, w = shape
    grid = np.zeros(bins * h * w, dtype=np.float64)
    if len(x):
        t0, t1 = span
        pos = (np.asarray(t, dtype=np.float64) - t0) / max(t1 - t0, 1) * (bins - 1)
        pos = np.clip(pos, 0.0, bins - 1)
        lo = np.floor(pos).astype(np.int64)
        frac = pos - lo
        hi = np.minimum(lo + 1, bins - 1)
        pol = np.where(np.asarray(p) > 0, 1.0, -1.0)
        pix = np.asarray(y, dtype=np.int64) * w + np.asarray(x, dtype=np.int64)
        np.add.at(grid, lo * h * w + pix, pol * (1.0 - frac))
        np.add.at(grid, hi * h * w + pix, pol * frac)
    return grid.reshape(bins, h, w).astype(np.float32)


@dataclass(frozen=True, eq=False)
class EventPacket:
    """The raw events of one step (``info["events"]``), in time order.

    Attributes:
        x, y: (N,) int32 pixel coordinates (as in events.h5).
        t: (N,) int64 trajectory time, ns.
        p: (N,) int8 polarity, +1 ON / -1 OFF.

    ``packet["x"]`` and ``packet.get("x")`` work too. Not a dict, so that Gymnasium's
    vector environments keep each environment's packet whole (one object per environment).
    """

    x: NDArray[np.int32]
    y: NDArray[np.int32]
    t: NDArray[np.int64]
    p: NDArray[np.int8]

    def __getitem__(self, key: str) -> NDArray[Any]:
        value: NDArray[Any] = getattr(self, key)
        return value

    def get(self, key: str, default: Any = None) -> Any:
        """``packet.get("x")``, as on a mapping (``default`` for an unknown key)."""
        return getattr(self, key) if key in ("x", "y", "t", "p") else default

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, EventPacket):
            return NotImplemented
        return all(
            np.array_equal(getattr(self, k), getattr(other, k)) for k in ("x", "y", "t", "p")
        )

    __hash__ = None  # type: ignore[assignment]

    @classmethod
    def empty(cls) -> EventPacket:
        return cls(
            np.zeros(0, np.int32),
            np.zeros(0, np.int32),
            np.zeros(0, np.int64),
            np.zeros(0, np.int8),
        )


def _concat(taps: Sequence[Mapping[str, Any]], key: str, dtype: Any) -> NDArray[Any]:
    parts = [np.asarray(tp[key]) for tp in taps if key in tp]
    if not parts:
        return np.zeros(0, dtype=dtype)
    return np.concatenate([np.atleast_1d(q) for q in parts]).astype(dtype, copy=False)


def _rows(taps: Sequence[Mapping[str, Any]], key: str) -> NDArray[np.float64]:
    parts = [np.asarray(tp[key], dtype=np.float64).reshape(-1, 3) for tp in taps if key in tp]
    return np.concatenate(parts) if parts else np.zeros((0, 3))


class ObservationBuilder:
    """The observation space of a config and each step's observation (module docstring)."""

    def __init__(self, sensors: Sequence[SensorConfig], closed_loop: ClosedLoopConfig) -> None:
        obs = closed_loop.observation
        self.mode = obs.events
        self.bins = obs.voxel_bins
        self.imu: SensorConfig | None = next((s for s in sensors if s.type == "imu"), None)
        self.events: SensorConfig | None = next(
            (s for s in sensors if s.type == "event_camera"), None
        )
        box: dict[str, spaces.Space[Any]] = {}
        self.n_imu = 0
        if self.imu is not None:
            self.n_imu = obs.max_imu_samples or (
                math.ceil(self.imu.rate / closed_loop.control_rate) + 1
            )
            box["imu"] = spaces.Box(-np.inf, np.inf, (self.n_imu, 8), np.float32)
        self.ev_shape = (0, 0)
        if self.events is not None:
            m = self.events.calibration_cameras()[0].model  # type: ignore[attr-defined]
            self.ev_shape = (int(m.height), int(m.width))
            if self.mode == "count":
                box["events"] = spaces.Box(0.0, np.inf, (2, *self.ev_shape), np.float32)
            else:
                box["events"] = spaces.Box(-np.inf, np.inf, (self.bins, *self.ev_shape), np.float32)
        self.frames: dict[str, tuple[tuple[int, ...], Any]] = {}
        self.ranges: dict[str, tuple[str, float, float]] = {}
        """Range sensors: name -> (tap key, min_range, max_range)."""
        for s in sensors:
            if s.type in ("camera", "depth_camera"):
                m = s.calibration_cameras()[0].model  # type: ignore[attr-defined]
                hw = (int(m.height), int(m.width))
                if s.type == "depth_camera":
                    self.frames[s.name] = (hw, np.float32)
                    box[s.name] = spaces.Box(0.0, np.inf, hw, np.float32)
                else:
                    shape = (*hw, 3) if getattr(s, "encoding", "mono8") == "rgb8" else hw
                    self.frames[s.name] = (shape, np.uint8)
                    box[s.name] = spaces.Box(0, 255, shape, np.uint8)
            elif s.type in RANGE_TYPES:
                c: Any = s
                if s.type == "laser":  # a scan: (n_beams,)
                    n, lo, hi, key = int(c.n_beams), c.range_min, c.range_max, "ranges"
                else:
                    n, lo, hi, key = 1, c.min_range, c.max_range, "range"
                self.frames[s.name] = ((n,), np.float32)
                self.ranges[s.name] = (key, float(lo), float(hi))
                box[s.name] = spaces.Box(0.0, hi, (n,), np.float32)
        box["time"] = spaces.Box(0.0, np.inf, (1,), np.float32)
        self.space = spaces.Dict(box)
        self._last: dict[str, NDArray[Any]] = {}

    def reset(self) -> None:
        """Forget the last frames and ranges (a new episode)."""
        self._last = {
            name: np.zeros(shape, dtype=dtype) for name, (shape, dtype) in self.frames.items()
        }

    def raw_events(self, taps: Mapping[str, Sequence[Mapping[str, Any]]]) -> EventPacket:
        """The step's raw events of the (first) event camera."""
        if self.events is None:
            return EventPacket.empty()
        tp = taps.get(self.events.name, [])
        return EventPacket(
            _concat(tp, "x", np.int32),
            _concat(tp, "y", np.int32),
            _concat(tp, "t", np.int64),
            np.where(_concat(tp, "p", np.int64) > 0, 1, -1).astype(np.int8),
        )

    def build(
        self, taps: Mapping[str, Sequence[Mapping[str, Any]]], span: tuple[int, int]
    ) -> dict[str, NDArray[Any]]:
        """The observation of a step from its taps; ``span``: (start, end) ns."""
        out: dict[str, NDArray[Any]] = {}
        if self.imu is not None:
            tp = taps.get(self.imu.name, [])
            t = _concat(tp, "t", np.int64)
            acc = _rows(tp, "acc")
            gyr = _rows(tp, "gyro")
            n = min(t.shape[0], self.n_imu)
            rows = np.zeros((self.n_imu, 8), dtype=np.float32)
            sl = slice(t.shape[0] - n, t.shape[0])  # the latest samples when too many
            rows[:n, 0] = 1.0
            rows[:n, 1] = (t[sl] - span[1]) * 1e-9
            rows[:n, 2:5] = acc[sl]
            rows[:n, 5:8] = gyr[sl]
            out["imu"] = rows
        if self.events is not None:
            ev = self.raw_events(taps)
            if self.mode == "count":
                out["events"] = event_count_image(ev["x"], ev["y"], ev["p"], self.ev_shape)
            else:
                out["events"] = event_voxel_grid(
                    ev["x"], ev["y"], ev["t"], ev["p"], self.ev_shape, self.bins, span
                )
        for name, (shape, dtype) in self.frames.items():
            tp = taps.get(name, [])
            key, lo, hi = self.ranges.get(name, ("image", 0.0, 0.0))
            last = [q for q in tp if key in q]
            if last:
                value = np.asarray(last[-1][key])
                if name in self.ranges:
                    # REP 117's -inf (closer than min_range) and +inf (no echo) as the
                    # bounds; the last reading of a range sensor, the last scan of a laser
                    r = np.asarray(value, np.float64).reshape(-1)[-shape[0] :]
                    value = np.where(r < lo, lo, np.where(np.isfinite(r), r, hi))
                self._last[name] = np.asarray(value, dtype=dtype).reshape(shape)
            out[name] = self._last[name].copy()
        out["time"] = np.array([span[1] * 1e-9], dtype=np.float32)
        return out
