"""Spinning multi-beam LiDAR (Velodyne HDL-32E, VLP-16 or a generic one), ray cast.

Timing model (docs/design.md §3): a column (firing cycle) starts every ``P`` seconds
(HDL-32E: 46.08 us); within it laser ``l`` (firing order) fires at ``l * dt``
(1.152 us). Laser ``l`` of column ``c`` of the turn that starts at ``t0`` fires at
``t0 + c * P + l * dt``. The head turns clockwise seen from above (as a Velodyne
does), at ``rate`` turns per second, pointing along +x at ``t0``: the beam's azimuth
is ``-2 pi rate (c P + l dt)`` - each laser at the azimuth of its own instant.

Every beam leaves from the sensor pose at its own firing instant along the
closed-form trajectory (see :mod:`roslan.sensors.beams.rays`), so the cloud carries
the motion distortion a real spinning LiDAR has.

Output convention (velodyne_pointcloud XYZIRT): one sensor_msgs/PointCloud2 per
turn, header stamp = the turn's first firing instant, frame = the sensor frame;
each point is expressed in the sensor frame *at its own firing instant* (raw, not
de-skewed, as velodyne_pointcloud publishes it); ``time`` = seconds after the
header stamp, in [0, 1/rate); ``ring`` = 0 for the lowest beam upwards (velodyne's
ring numbering, not the firing order); ``intensity`` = ``intensity_scale *
reflectivity * cos(incidence)``. Unorganized clouds hold the returns in firing
order; ``organized: true`` gives ``height = rings`` rows (ring order) by
``width = azimuth steps`` columns with NaN x/y/z for no return.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, model_validator

from roslan.config.base import FiniteFloat
from roslan.sensors.base import (
    TopicName,
)
from roslan.sensors.beams.base import (
    BeamConfig,
    BeamDraws,
    PointCloudSensor,
    draw_beams,
    measure,
)
from roslan.sensors.beams.pointcloud import XYZIRT, XYZIRTL
from roslan.sensors.beams.rays import firing_times, rays_in_world

if TYPE_CHECKING:
    from roslan.render.base import BeamCaster

__all__ = [
    "HDL32E_ELEVATIONS_DEG",
    "LIDAR_PRESETS",
    "SCAN_CHUNK_BEAMS",
    "Lidar",
    "LidarConfig",
    "LidarPreset",
    "LidarSpec",
]


# fmt: off
HDL32E_ELEVATIONS_DEG = (
    -30.67, -9.33, -29.33, -8.00, -28.00, -6.67, -26.67, -5.33,
    -25.33, -4.00, -24.00, -2.67, -22.67, -1.33, -21.33, 0.00,
    -20.00, 1.33, -18.67, 2.67, -17.33, 4.00, -16.00, 5.33,
    -14.67, 6.67, -13.33, 8.00, -12.00, 9.33, -10.67, 10.67,
)
"""HDL-32E beam elevations (deg) of laser ids 0..31, i.e. in firing order."""
# fmt: on


@dataclass(frozen=True)
class LidarPreset:
    """Datasheet facts of a spinning LiDAR model."""

    elevations_deg: tuple[float, ...]  # firing order
    firing_interval: float  # s between consecutive lasers of a cycle
    cycle_time: float  # s per firing cycle (one azimuth column)
    rate_range: tuple[float, float]  # Hz
    min_range: float  # m
    max_range: float  # m
    noise_sigma: float  # m, 1-sigma range noise


LIDAR_PRESETS: dict[str, LidarPreset] = {
    # Velodyne HDL-32E user manual: laser id 0..31 fire in order, 1.152 us apart,
    # 46.08 us per cycle, 5-20 Hz, 0.05-100 m, accuracy < 2 cm.
    "hdl32e": LidarPreset(
        elevations_deg=HDL32E_ELEVATIONS_DEG,
        firing_interval=1.152e-6,
        cycle_time=46.08e-6,
        rate_range=(5.0, 20.0),
        min_range=0.05,
        max_range=100.0,
        noise_sigma=0.02,
    ),
    # Velodyne VLP-16: 16 lasers 2.304 us apart + 18.43 us recharge = 55.296 us,
    # 5-20 Hz, up to 100 m, accuracy +-3 cm. (Min range: not a datasheet figure.)
    "vlp16": LidarPreset(
        elevations_deg=(-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15),
        firing_interval=2.304e-6,
        cycle_time=55.296e-6,
        rate_range=(5.0, 20.0),
        min_range=0.05,
        max_range=100.0,
        noise_sigma=0.03,
    ),
}

PositiveFloat = Annotated[FiniteFloat, Field(gt=0)]


@dataclass(frozen=True)
class LidarSpec:
    """Resolved parameters of a configured LiDAR (SI units, radians)."""

    elevations: NDArray[np.float64]  # (L,) rad, firing order
    firing_interval: float  # s
    column_period: float  # s between columns
    azimuth_steps: int
    rate: float  # Hz
    min_range: float
    max_range: float
    noise_sigma: float

    @property
    def n_lasers(self) -> int:
        return int(self.elevations.shape[0])

    @property
    def rings(self) -> NDArray[np.uint16]:
        """(L,) ring number of each laser (firing order): rank of its elevation, 0 lowest."""
        order = np.argsort(self.elevations, kind="stable")
        ring = np.empty(self.n_lasers, np.uint16)
        ring[order] = np.arange(self.n_lasers, dtype=np.uint16)
        return ring

    def firing_offsets(self) -> NDArray[np.float64]:
        """(steps, L) firing instant of each beam after the turn start, s."""
        c = np.arange(self.azimuth_steps, dtype=np.float64)[:, None]
        lz = np.arange(self.n_lasers, dtype=np.float64)[None, :]
        out: NDArray[np.float64] = c * self.column_period + lz * self.firing_interval
        return out


class LidarConfig(BeamConfig):
    """``type: lidar``: a spinning multi-beam LiDAR. ``rate`` = turns per second.

    ``preset: hdl32e | vlp16`` takes the datasheet geometry and timing; ``custom``
    needs ``elevations_deg`` (firing order) and ``azimuth_steps`` or ``cycle_time``.
    ``None`` values take the preset's figure.
    """

    type: Literal["lidar"]
    rate: PositiveFloat = 10.0
    topic: TopicName = "/velodyne_points"
    preset: Literal["hdl32e", "vlp16", "custom"] = "hdl32e"
    elevations_deg: tuple[FiniteFloat, ...] | None = None
    azimuth_steps: Annotated[int, Field(ge=1, le=100_000)] | None = None
    firing_interval: Annotated[FiniteFloat, Field(ge=0)] | None = None
    cycle_time: PositiveFloat | None = None
    min_range: Annotated[FiniteFloat, Field(ge=0)] | None = None
    max_range: PositiveFloat | None = None
    noise_sigma: Annotated[FiniteFloat, Field(ge=0)] | None = None
    organized: bool = False

    @model_validator(mode="after")
    def _check(self) -> LidarConfig:
        self.spec()  # raises ValueError naming the key
        return self

    def spec(self) -> LidarSpec:
        """Resolve preset + overrides; ValueError (naming the key) if inconsistent."""
        p = LIDAR_PRESETS.get(self.preset)
        if p is None:
            if self.elevations_deg is None:
                msg = (
                    "elevations_deg: required with preset: custom "
                    "(beam elevations, deg, in firing order)"
                )
                raise ValueError(msg)
            if self.azimuth_steps is None and self.cycle_time is None:
                msg = "preset: custom needs azimuth_steps (per turn) or cycle_time (s per column)"
                raise ValueError(msg)
            elev = self.elevations_deg
        else:
            if self.elevations_deg is not None:
                msg = f"elevations_deg: only for preset: custom (preset {self.preset} has its own)"
                raise ValueError(msg)
            lo, hi = p.rate_range
            if not lo <= self.rate <= hi:
                msg = f"rate = {self.rate} Hz: preset {self.preset} spins at {lo:g}-{hi:g} Hz"
                raise ValueError(msg)
            elev = p.elevations_deg
        if not elev or any(not -90.0 < e < 90.0 for e in elev):
            msg = f"elevations_deg = {list(elev)}: need at least one angle, each in (-90, 90) deg"
            raise ValueError(msg)
        n = len(elev)
        turn = 1.0 / self.rate
        cycle = self.cycle_time if self.cycle_time is not None else (p.cycle_time if p else None)
        if self.azimuth_steps is not None:
            steps = self.azimuth_steps
            period = turn / steps
        else:
            assert cycle is not None
            steps = math.floor(turn / cycle + 1e-9)
            period = cycle
            if steps < 1:
                msg = f"cycle_time = {cycle} s is longer than one turn (1/rate = {turn} s)"
                raise ValueError(msg)
        if cycle is not None and cycle > period * (1 + 1e-9):
            msg = (
                f"azimuth_steps = {steps} at rate {self.rate} Hz leaves {period * 1e6:.3f} us per "
                f"column, less than cycle_time = {cycle * 1e6:.3f} us"
            )
            raise ValueError(msg)
        if self.firing_interval is not None:
            dt = self.firing_interval
        elif p is not None:
            dt = p.firing_interval
        else:
            dt = (cycle if cycle is not None else period) / n
        if (n - 1) * dt > period * (1 + 1e-9):
            msg = (
                f"firing_interval = {dt} s: {n} lasers take {(n - 1) * dt * 1e6:.3f} us, more than "
                f"one column ({period * 1e6:.3f} us)"
            )
            raise ValueError(msg)
        rmin = self.min_range if self.min_range is not None else (p.min_range if p else 0.0)
        rmax = self.max_range if self.max_range is not None else (p.max_range if p else 100.0)
        if not rmin < rmax:
            msg = f"min_range = {rmin} m must be less than max_range = {rmax} m"
            raise ValueError(msg)
        noise = self.noise_sigma if self.noise_sigma is not None else (p.noise_sigma if p else 0.0)
        return LidarSpec(
            elevations=np.deg2rad(np.asarray(elev, dtype=np.float64)),
            firing_interval=float(dt),
            column_period=float(period),
            azimuth_steps=int(steps),
            rate=float(self.rate),
            min_range=float(rmin),
            max_range=float(rmax),
            noise_sigma=float(noise),
        )


SCAN_CHUNK_BEAMS = 1 << 20
"""Beams a scan casts and packs at a time (whole columns): a scan's working memory (rays,
hits, the range model) stays within a few hundred MB however many points it has; only its
packed cloud (22 bytes a point) is whole. A scan of at most this many beams is one chunk."""


class Lidar(PointCloudSensor):
    """Spinning LiDAR sensor (see module docstring for timing and output conventions)."""

    def __init__(self, config: LidarConfig) -> None:
        self.config = config
        self.spec = config.spec()
        s = self.spec
        self.ring = s.rings
        self.frac = np.arange(s.n_lasers, dtype=np.float64) * (s.firing_interval / s.column_period)
        self._laser_of_ring = np.argsort(self.ring)
        self.chunk_columns = max(1, SCAN_CHUNK_BEAMS // s.n_lasers)
        """Columns per chunk of :meth:`scan`."""
        self.T_body_sensor = config.pose.matrix()

    def columns(self, c0: int, c1: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Firing offsets (cols, L) after the turn start (s) and unit sensor-frame beam
        directions (cols, L, 3) of columns ``c0 .. c1 - 1``."""
        s = self.spec
        c = np.arange(c0, c1, dtype=np.float64)[:, None]
        lz = np.arange(s.n_lasers, dtype=np.float64)[None, :]
        offsets: NDArray[np.float64] = c * s.column_period + lz * s.firing_interval
        az = -2.0 * math.pi * s.rate * offsets  # clockwise from +x
        el = s.elevations[None, :]
        ce = np.cos(el)
        d = np.stack(
            [ce * np.cos(az), ce * np.sin(az), np.broadcast_to(np.sin(el), az.shape)], axis=-1
        )
        return offsets, d

    @property
    def offsets(self) -> NDArray[np.float64]:
        """(steps, L) firing instant of each beam after the turn start, s."""
        return self.columns(0, self.spec.azimuth_steps)[0]

    @property
    def directions(self) -> NDArray[np.float64]:
        """(steps, L, 3) unit beam directions in the sensor frame."""
        return self.columns(0, self.spec.azimuth_steps)[1]

    # ------------------------------------------------------------------ interface
    def cloud_layout(self) -> tuple[int, bool]:
        """Organized: one row per ring, NaN where nothing returned (not dense)."""
        return (self.spec.n_lasers, False) if self.config.organized else (1, True)

    def draw(self, rng: np.random.Generator) -> BeamDraws:
        """The random draws of one scan's beams (:func:`~.base.draw_beams`)."""
        n = self.spec.azimuth_steps * self.spec.n_lasers
        return draw_beams(rng, n, self.spec.noise_sigma, self.config)

    def scan(
        self,
        trajectory: Any,
        caster: BeamCaster,
        t0_ns: int,
        rng: np.random.Generator | BeamDraws,
        *,
        labels: NDArray[np.uint32] | None = None,
    ) -> NDArray[Any]:
        """One turn starting at ``t0_ns``: structured :data:`XYZIRT` points, or
        :data:`XYZIRTL` with ``labels`` (the scene's per-triangle labels,
        :func:`~roslan.sensors.beams.labels.triangle_labels`).

        Returns (n_returns,) in firing order, or (rings * steps,) row-major by ring
        when ``organized`` (NaN x/y/z, zero intensity and label where there is no return).
        The turn is cast and packed :data:`SCAN_CHUNK_BEAMS` beams (whole columns) at a time.
        """
        s = self.spec
        steps, n_l = s.azimuth_steps, s.n_lasers
        draws = rng if isinstance(rng, BeamDraws) else self.draw(rng)
        t_knots = t0_ns * 1e-9 + np.arange(steps, dtype=np.float64) * s.column_period
        organized = bool(self.config.organized)
        layout = XYZIRT if labels is None else XYZIRTL
        pts = np.empty(steps * n_l, layout)  # pages are only committed as they are written
        grid = pts.reshape(n_l, steps)  # organized: rows = rings (lowest first)
        ring = self.ring
        filled = 0
        # chunks use the whole turn's knot spacing (one chunk: rays_in_world's own)
        spacing = float(t_knots[1] - t_knots[0]) if steps > self.chunk_columns else None
        for c0 in range(0, steps, self.chunk_columns):
            c1 = min(steps, c0 + self.chunk_columns)
            offsets, d_sensor = self.columns(c0, c1)
            origins, dirs = rays_in_world(
                trajectory,
                self.T_body_sensor,
                t_knots[c0:c1],
                self.frac,
                d_sensor,
                mode=self.config.firing_poses,
                spacing=spacing,
            )
            b0, b1 = c0 * n_l, c1 * n_l
            m = measure(
                caster,
                origins.reshape(-1, 3),
                dirs.reshape(-1, 3),
                min_range=s.min_range,
                max_range=s.max_range,
                noise_sigma=s.noise_sigma,
                returns=self.config,
                rng=BeamDraws(*(None if a is None else a[b0:b1] for a in draws)),
                labels=labels,
                t=firing_times(t_knots[c0:c1], self.frac, spacing),
            )
            del origins, dirs
            d32 = d_sensor.reshape(-1, 3).astype(np.float32)
            off32 = offsets.reshape(-1).astype(np.float32)
            rings = np.tile(ring, c1 - c0)
            if organized:
                r = np.where(m.valid, m.range, np.nan).astype(np.float32)
                block = np.empty(b1 - b0, layout)
                _pack(block, d32, r, m.intensity, rings, off32, m.label)
                lor = self._laser_of_ring
                grid[:, c0:c1] = block.reshape(c1 - c0, n_l)[:, lor].T
                continue
            sel: Any = slice(None) if bool(m.valid.all()) else np.flatnonzero(m.valid)
            r = m.range[sel].astype(np.float32)
            k = r.shape[0]
            lab = None if m.label is None else m.label[sel]
            _pack(
                pts[filled : filled + k], d32[sel], r, m.intensity[sel], rings[sel], off32[sel], lab
            )
            filled += k
        return pts if organized else pts[:filled]


def _pack(
    out: NDArray[Any],
    d32: NDArray[np.float32],
    r: NDArray[np.float32],
    intensity: NDArray[np.float32],
    ring: NDArray[np.uint16],
    time: NDArray[np.float32],
    label: NDArray[np.uint32] | None = None,
) -> None:
    """Fill the :data:`XYZIRT` (with ``label``: :data:`XYZIRTL`) points ``out`` (a view):
    sensor-frame xyz = direction x range."""
    out["x"] = d32[:, 0] * r
    out["y"] = d32[:, 1] * r
    out["z"] = d32[:, 2] * r
    out["intensity"] = intensity
    out["ring"] = ring
    out["time"] = time
    if label is not None:
        out["label"] = label
