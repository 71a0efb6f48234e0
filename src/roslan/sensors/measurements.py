"""Typed measurements: what each sensor kind hands the closed loop per step, and how the
environment observes it.

Every sensor kind declares, in its :class:`~roslan.sensors.registry.SensorSpec`, its
**step output** (one of the small frozen dataclasses below, which it hands to
:meth:`~roslan.sensors.clock.Clock.tap`) and its **observation** (a factory of an
:class:`Observer` below: the fixed-shape box it adds to the environment's observation and
how a step's measurements fill it). :mod:`roslan.env.observe` only loops over the
observers, so a new kind is observed by its own declaration.

A measurement also reads like the mapping it replaces (``tap["t"]``, ``"acc" in tap``).
Times are trajectory ns (int64).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import Any, NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray

from roslan.config.closed_loop import ClosedLoopConfig
from roslan.errors import ConfigError

__all__ = [
    "MEASUREMENTS",
    "OBSERVERS",
    "Box",
    "CloudScan",
    "EventPacket",
    "EventSamples",
    "Frame",
    "ImuSamples",
    "LaserScan",
    "Measurement",
    "Observer",
    "RangeSamples",
    "event_count_image",
    "event_voxel_grid",
]

F32 = NDArray[np.float32]


def _same(a: Any, b: Any) -> bool:
    """Bit for bit (NaN rows of a cloud included) for arrays, ``==`` otherwise."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        x, y = np.asarray(a), np.asarray(b)
        return x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes()
    return bool(a == b)


class _Record:
    """Mapping-style reads of a measurement dataclass (``m["t"]``, ``"t" in m``)."""

    __slots__ = ()

    def __getitem__(self, key: str) -> Any:
        if key not in self:
            raise KeyError(key)
        return getattr(self, key)

    def __contains__(self, key: object) -> bool:
        return isinstance(key, str) and key in {f.name for f in fields(self)}  # type: ignore[arg-type]

    def get(self, key: str, default: Any = None) -> Any:
        return getattr(self, key) if key in self else default

    def __eq__(self, other: object) -> bool:
        """Same kind, every field equal (arrays element by element)."""
        if type(other) is not type(self):
            return NotImplemented
        return all(
            _same(getattr(self, f.name), getattr(other, f.name))
            for f in fields(self)  # type: ignore[arg-type]
        )

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True, slots=True, eq=False)
class ImuSamples(_Record):
    """An IMU's samples: ``t`` (N,) int64 ns, ``acc`` (N, 3) m/s^2 specific force and
    ``gyro`` (N, 3) rad/s body rates, in the IMU frame."""

    t: NDArray[np.int64]
    acc: NDArray[np.float64]
    gyro: NDArray[np.float64]


@dataclass(frozen=True, slots=True, eq=False)
class EventSamples(_Record):
    """An event camera's events, in time order: ``x``, ``y`` (N,) uint16 pixel column
    and row (row 0 = top), ``t`` (N,) int64 ns, ``p`` (N,) int8 polarity **1 ON, 0 OFF**
    (as ESIM makes them; :class:`EventPacket` turns them into +1 / -1)."""

    x: NDArray[np.uint16]
    y: NDArray[np.uint16]
    t: NDArray[np.int64]
    p: NDArray[np.int8]


@dataclass(frozen=True, slots=True, eq=False)
class Frame(_Record):
    """A frame, depth or stereo camera's frame: ``t`` its stamp (ns), ``image`` as
    published (uint8 ``(H, W)`` / ``(H, W, 3)``, or float32 metres for depth), ``eye``
    ``''`` (``'left'`` / ``'right'`` for a stereo camera's eyes)."""

    t: int
    image: NDArray[Any]
    eye: str = ""


@dataclass(frozen=True, slots=True, eq=False)
class RangeSamples(_Record):
    """A sonar's or altimeter's readings: ``t`` (N,) int64 ns, ``range`` (N,) metres
    (REP 117: -inf closer than ``min_range``, +inf no echo)."""

    t: NDArray[np.int64]
    range: NDArray[np.float64]


@dataclass(frozen=True, slots=True, eq=False)
class LaserScan(_Record):
    """A 2-D laser's scan: ``t`` its start (ns), ``ranges`` and ``intensities`` (n_beams,)
    float32 (REP 117 ranges)."""

    t: int
    ranges: NDArray[np.float32]
    intensities: NDArray[np.float32]


@dataclass(frozen=True, slots=True, eq=False)
class CloudScan(_Record):
    """A LiDAR's scan: ``t`` its start (ns), ``points`` the cloud's structured array
    (``x``, ``y``, ``z``, ``intensity``, ``ring``, ``time``; sensor frame; NaN rows of an
    organized cloud are no return)."""

    t: int
    points: NDArray[Any]


Measurement = ImuSamples | EventSamples | Frame | RangeSamples | LaserScan | CloudScan
"""What a sensor taps: one of the step outputs above."""

MEASUREMENTS: dict[str, type[Any]] = {
    c.__name__: c for c in (ImuSamples, EventSamples, Frame, RangeSamples, LaserScan, CloudScan)
}
"""The step-output classes by name (``SensorSpec.measurement``)."""


# ------------------------------------------------------------------ observation helpers
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
    (ON +1, OFF -1, whatever the input's coding: ``p > 0`` is ON) split linearly between
    the two time bins around it; bin centres span ``span`` (ns, step start to end)."""
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
        p: (N,) int8 polarity, +1 ON / -1 OFF (the tap's 1 / 0, recoded).

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

    @classmethod
    def of(cls, samples: Sequence[EventSamples]) -> EventPacket:
        """One step's event samples as one packet (polarity recoded to +1 / -1)."""
        if not samples:
            return cls.empty()
        p = np.concatenate([s.p for s in samples])
        return cls(
            np.concatenate([s.x for s in samples]).astype(np.int32),
            np.concatenate([s.y for s in samples]).astype(np.int32),
            np.concatenate([s.t for s in samples]).astype(np.int64, copy=False),
            np.where(p > 0, 1, -1).astype(np.int8),
        )


# ------------------------------------------------------------------ observers
class Box(NamedTuple):
    """The fixed shape an observer adds to the observation (a ``gymnasium.spaces.Box``)."""

    low: float
    high: float
    shape: tuple[int, ...]
    dtype: Any


class Observer(Protocol):
    """One entry of the environment's observation, made from one sensor's measurements."""

    key: str
    """The observation key (``imu``, ``events``, or the sensor's name)."""
    sensor: str
    """The name of the sensor it reads (the taps' key)."""
    box: Box

    def reset(self) -> None:
        """A new episode: forget what was kept from earlier steps."""
        ...

    def observe(self, samples: Sequence[Any], span: tuple[int, int]) -> NDArray[Any]:
        """The entry of one step from its measurements (``span``: start, end ns)."""
        ...


class _Latest:
    """The latest value of a sensor, kept until the next one (zeros before the first)."""

    def __init__(self, key: str, sensor: str, box: Box) -> None:
        self.key, self.sensor, self.box = key, sensor, box
        self.last: NDArray[Any] = np.zeros(box.shape, box.dtype)

    def reset(self) -> None:
        self.last = np.zeros(self.box.shape, self.box.dtype)

    def update(self, samples: Sequence[Any]) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    def observe(self, samples: Sequence[Any], span: tuple[int, int]) -> NDArray[Any]:
        if samples:
            self.update(samples)
        return self.last.copy()


class ImuObserver:
    """``imu`` (the first IMU): ``(N, 8)`` float32 rows ``valid, dt, ax, ay, az, gx, gy,
    gz``: ``valid`` 1 for a sample and 0 for padding, ``dt`` its time minus the step's end
    (s, <= 0); the latest ``N`` samples of the step."""

    def __init__(self, sensor: str, n: int) -> None:
        self.key, self.sensor, self.n = "imu", sensor, n
        self.box = Box(-np.inf, np.inf, (n, 8), np.float32)

    def reset(self) -> None:
        pass

    def observe(self, samples: Sequence[ImuSamples], span: tuple[int, int]) -> NDArray[Any]:
        rows = np.zeros((self.n, 8), dtype=np.float32)
        if not samples:
            return rows
        t = np.concatenate([s.t for s in samples]).astype(np.int64, copy=False)
        k = min(t.shape[0], self.n)
        sl = slice(t.shape[0] - k, t.shape[0])  # the latest samples when too many
        rows[:k, 0] = 1.0
        rows[:k, 1] = (t[sl] - span[1]) * 1e-9
        rows[:k, 2:5] = np.concatenate([np.reshape(s.acc, (-1, 3)) for s in samples])[sl]
        rows[:k, 5:8] = np.concatenate([np.reshape(s.gyro, (-1, 3)) for s in samples])[sl]
        return rows


class EventObserver:
    """``events`` (the first event camera): ``count``: ``(2, H, W)`` float32 events per
    pixel and polarity (0: OFF, 1: ON) over the step; ``voxel``: ``(B, H, W)`` float32,
    each event's polarity (+1 ON, -1 OFF) spread linearly over ``B`` time bins."""

    def __init__(self, sensor: str, shape: tuple[int, int], mode: str, bins: int) -> None:
        self.key, self.sensor, self.shape = "events", sensor, shape
        self.mode, self.bins = mode, bins
        if mode == "count":
            self.box = Box(0.0, np.inf, (2, *shape), np.float32)
        else:
            self.box = Box(-np.inf, np.inf, (bins, *shape), np.float32)

    def reset(self) -> None:
        pass

    def packet(self, samples: Sequence[EventSamples]) -> EventPacket:
        """The step's raw events (``info["events"]``)."""
        return EventPacket.of(samples)

    def observe(self, samples: Sequence[EventSamples], span: tuple[int, int]) -> NDArray[Any]:
        ev = self.packet(samples)
        if self.mode == "count":
            return event_count_image(ev.x, ev.y, ev.p, self.shape)
        return event_voxel_grid(ev.x, ev.y, ev.t, ev.p, self.shape, self.bins, span)


class FrameObserver(_Latest):
    """``<name>`` of a frame or depth camera: the last frame, ``(H, W)`` or ``(H, W, 3)``
    uint8 as published (depth: ``(H, W)`` float32 metres); of a stereo camera: both eyes,
    ``(2, ...)`` left then right."""

    def __init__(self, sensor: str, box: Box, eyes: tuple[str, ...] = ("",)) -> None:
        super().__init__(sensor, sensor, box)
        self.eyes = eyes

    def update(self, samples: Sequence[Frame]) -> None:
        if self.eyes == ("",):
            self.last = np.asarray(samples[-1].image, self.box.dtype).reshape(self.box.shape)
            return
        for f in samples:
            i = self.eyes.index(f.eye)
            self.last[i] = np.asarray(f.image, self.box.dtype).reshape(self.box.shape[1:])


class RangeObserver(_Latest):
    """``<name>`` of a range sensor (``(1,)``, the last reading) or 2-D laser
    (``(n_beams,)``, the last scan), float32 metres; REP 117's -inf (closer than the
    minimum) is the minimum, no echo (+inf) the maximum."""

    def __init__(self, sensor: str, n: int, lo: float, hi: float, field: str) -> None:
        super().__init__(sensor, sensor, Box(0.0, hi, (n,), np.float32))
        self.lo, self.hi, self.field = lo, hi, field

    def update(self, samples: Sequence[Any]) -> None:
        n = self.box.shape[0]
        r = np.asarray(getattr(samples[-1], self.field), np.float64).reshape(-1)[-n:]
        value = np.where(r < self.lo, self.lo, np.where(np.isfinite(r), r, self.hi))
        self.last = value.astype(np.float32)


class CloudObserver(_Latest):
    """``<name>`` of a LiDAR: its last scan as ``(n_beams, 4)`` float32 rows ``valid, x,
    y, z`` (sensor frame, m; ``n_beams`` the beams of one scan): the returns in firing
    order (organized clouds: row-major by ring), then zero rows (``valid`` 0)."""

    def __init__(self, sensor: str, n: int) -> None:
        super().__init__(sensor, sensor, Box(-np.inf, np.inf, (n, 4), np.float32))

    def update(self, samples: Sequence[CloudScan]) -> None:
        pts = samples[-1].points
        ok = np.isfinite(pts["x"])
        k = min(int(ok.sum()), self.box.shape[0])
        rows = np.zeros(self.box.shape, np.float32)
        sel = np.flatnonzero(ok)[:k]
        rows[:k, 0] = 1.0
        rows[:k, 1], rows[:k, 2], rows[:k, 3] = pts["x"][sel], pts["y"][sel], pts["z"][sel]
        self.last = rows


# ------------------------------------------------------------------ per-kind factories
def _hw(config: Any, eye: int = 0) -> tuple[int, int]:
    m = config.calibration_cameras()[eye].model
    return int(m.height), int(m.width)


def _imu(config: Any, loop: ClosedLoopConfig, first: bool) -> Observer | None:
    if not first:
        return None  # only the first IMU is observed
    obs = loop.observation
    ratio = config.rate / loop.control_rate
    default = math.ceil(ratio) + 1
    # the most samples one step can hold (a step of a whole number of sample periods holds
    # exactly that many; otherwise one more, as the sample instants fall)
    need = default - 1 if abs(ratio - round(ratio)) < 1e-9 else default
    n = obs.max_imu_samples or default
    if n < need:
        msg = (
            f"closed_loop.observation.max_imu_samples = {n}: a control step "
            f"({loop.control_rate:g} Hz) holds up to {need} samples of the IMU "
            f"'{config.name}' ({config.rate:g} Hz), which would be dropped; allowed: at "
            f"least {need} (or null: {default})"
        )
        raise ConfigError(msg)
    return ImuObserver(config.name, n)


def _events(config: Any, loop: ClosedLoopConfig, first: bool) -> Observer | None:
    if not first:
        return None  # only the first event camera is observed
    obs = loop.observation
    return EventObserver(config.name, _hw(config), obs.events, obs.voxel_bins)


def _camera(config: Any, loop: ClosedLoopConfig, first: bool) -> Observer:
    hw = _hw(config)
    shape = (*hw, 3) if getattr(config, "encoding", "mono8") == "rgb8" else hw
    return FrameObserver(config.name, Box(0, 255, shape, np.uint8))


def _stereo(config: Any, loop: ClosedLoopConfig, first: bool) -> Observer:
    hw = _hw(config)
    shape = (2, *hw, 3) if getattr(config, "encoding", "mono8") == "rgb8" else (2, *hw)
    return FrameObserver(config.name, Box(0, 255, shape, np.uint8), ("left", "right"))


def _depth(config: Any, loop: ClosedLoopConfig, first: bool) -> Observer:
    return FrameObserver(config.name, Box(0.0, np.inf, _hw(config), np.float32))


def _range(config: Any, loop: ClosedLoopConfig, first: bool) -> Observer:
    return RangeObserver(config.name, 1, float(config.min_range), float(config.max_range), "range")


def _laser(config: Any, loop: ClosedLoopConfig, first: bool) -> Observer:
    lo, hi = float(config.range_min), float(config.range_max)
    return RangeObserver(config.name, int(config.n_beams), lo, hi, "ranges")


def _lidar(config: Any, loop: ClosedLoopConfig, first: bool) -> Observer:
    spec = config.spec()
    return CloudObserver(config.name, int(spec.azimuth_steps) * int(spec.n_lasers))


def _solid_state(config: Any, loop: ClosedLoopConfig, first: bool) -> Observer:
    spec = config.resolved()
    instants = math.floor(1.0 / (config.rate * spec.lines / spec.point_rate) + 1e-9)
    return CloudObserver(config.name, instants * int(spec.lines))


class ObserverFactory(Protocol):
    def __call__(self, config: Any, loop: ClosedLoopConfig, first: bool) -> Observer | None: ...


OBSERVERS: dict[str, ObserverFactory] = {
    "imu": _imu,
    "events": _events,
    "camera": _camera,
    "stereo": _stereo,
    "depth": _depth,
    "range": _range,
    "laser": _laser,
    "lidar": _lidar,
    "solid_state": _solid_state,
}
"""Observation factories by name (``SensorSpec.observation``): ``(config, closed_loop,
first)`` -> the :class:`Observer` of that sensor (``first``: it is the first of its type in
the config), or None (not observed)."""
