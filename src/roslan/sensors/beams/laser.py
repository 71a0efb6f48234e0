"""2-D scanning laser (``type: laser``), ray cast, published as sensor_msgs/LaserScan.

Beams lie in the sensor's x-y plane at ``angle_min + i * angle_increment``
(counter-clockwise about z, ROS convention), ``i = 0 .. n-1`` with
``n = floor((angle_max - angle_min) / angle_increment) + 1``; the published
``angle_max`` is the last beam's angle. Beam ``i`` fires at ``stamp + i *
time_increment`` from the sensor pose at that instant (a rotating-mirror scanner
moves while it scans); ``time_increment`` defaults to one mirror turn per scan
(``angle_increment / (2 pi rate)``). Defaults follow a Hokuyo UTM-30LX (270 deg,
0.25 deg, 40 Hz, 0.1-30 m).

Ranges follow REP 117: +inf for no return within ``range_max`` (or a dropout),
-inf for a surface closer than ``range_min``; others are the true distance plus
Gaussian noise, clipped to [range_min, range_max]. ``intensities`` =
``intensity_scale * reflectivity * cos(incidence)``.

Dataset file: ``laser_<name>.txt``, one line per scan: ``t r_0 ... r_{n-1}`` (s since
the trajectory start, 9 decimals; m). With ``output.labels`` (LaserScan has no field for
them) also ``laser_<name>_labels.txt``, the same lines with each beam's label in place of
its range: ``t l_0 ... l_{n-1}`` (uint32, SemanticKITTI: class | instance << 16; 0 where
the range is not finite).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import IO, TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, model_validator

from roslan.config.base import FiniteFloat
from roslan.io.text import format_seconds
from roslan.sensors.base import (
    Message,
    SimContext,
    StaticTransform,
    TopicName,
    TopicSpec,
    paced,
    sample_times_ns,
)
from roslan.sensors.beams.base import BeamConfig, Measurement, measure
from roslan.sensors.beams.labels import label_table
from roslan.sensors.beams.rays import firing_times, rays_in_world
from roslan.sensors.measurements import LaserScan

if TYPE_CHECKING:
    from roslan.render.base import BeamCaster

__all__ = ["Laser", "LaserConfig"]

LASERSCAN = "sensor_msgs/msg/LaserScan"
_BEAMS_PER_KNOT = 32  # exact pose every 32 beams, Hermite in between (see beams.py)

PositiveFloat = Annotated[FiniteFloat, Field(gt=0)]
NonNegative = Annotated[FiniteFloat, Field(ge=0)]


class LaserConfig(BeamConfig):
    """``type: laser``: planar scanner. Angles in rad, ranges in m, times in s."""

    type: Literal["laser"]
    rate: PositiveFloat = 40.0
    topic: TopicName = "/scan"
    angle_min: Annotated[FiniteFloat, Field(ge=-math.pi - 1e-9)] = -math.radians(135.0)
    angle_max: Annotated[FiniteFloat, Field(le=math.pi + 1e-9)] = math.radians(135.0)
    angle_increment: PositiveFloat = math.radians(0.25)
    time_increment: NonNegative | None = None
    range_min: NonNegative = 0.1
    range_max: PositiveFloat = 30.0
    noise_sigma: NonNegative = 0.01

    @model_validator(mode="after")
    def _check(self) -> LaserConfig:
        if not self.angle_min < self.angle_max:
            msg = (
                f"angle_min = {self.angle_min} rad must be less than "
                f"angle_max = {self.angle_max} rad"
            )
            raise ValueError(msg)
        if not self.range_min < self.range_max:
            msg = f"range_min = {self.range_min} m must be less than range_max = {self.range_max} m"
            raise ValueError(msg)
        if self.n_beams > 100_000:
            msg = (
                f"angle_increment = {self.angle_increment} rad gives {self.n_beams} beams "
                "(at most 100000)"
            )
            raise ValueError(msg)
        if (self.n_beams - 1) * self.beam_time > 1.0 / self.rate * (1 + 1e-9):
            msg = (
                f"time_increment = {self.beam_time} s: {self.n_beams} beams take longer than "
                f"one scan (1/rate = {1.0 / self.rate} s)"
            )
            raise ValueError(msg)
        return self

    @property
    def n_beams(self) -> int:
        return math.floor((self.angle_max - self.angle_min) / self.angle_increment + 1e-9) + 1

    @property
    def beam_time(self) -> float:
        """Seconds between consecutive beams."""
        if self.time_increment is not None:
            return self.time_increment
        return self.angle_increment / (2.0 * math.pi * self.rate)


class Laser:
    """2-D laser scanner (see module docstring)."""

    def __init__(self, config: LaserConfig) -> None:
        self.config = config
        c = config
        n = c.n_beams
        self.angles = c.angle_min + np.arange(n, dtype=np.float64) * c.angle_increment
        self.T_body_sensor = c.pose.matrix()
        j = min(n, _BEAMS_PER_KNOT)
        k = -(-n // j)
        pad = np.arange(k * j, dtype=np.float64)  # beams padded to whole knots
        ang = c.angle_min + pad * c.angle_increment
        self._grid = (k, j)
        self._dirs = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], axis=1).reshape(
            k, j, 3
        )
        self._frac = np.arange(j, dtype=np.float64) / j
        self._fh: IO[str] | None = None
        self._labels_fh: IO[str] | None = None

    def topics(self) -> list[TopicSpec]:
        return [TopicSpec(self.config.topic, LASERSCAN)]

    def static_transforms(self) -> list[StaticTransform]:
        return []  # base_link -> frame comes from the extrinsics (pipeline)

    def scan(
        self, trajectory: Any, caster: BeamCaster, t0_ns: int, rng: np.random.Generator
    ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
        """One scan from ``t0_ns``: (ranges, intensities), each (n_beams,) float32."""
        m = self.measure_scan(trajectory, caster, t0_ns, rng)
        return m.range.astype(np.float32), m.intensity

    def measure_scan(
        self,
        trajectory: Any,
        caster: BeamCaster,
        t0_ns: int,
        rng: np.random.Generator,
        labels: NDArray[np.uint32] | None = None,
    ) -> Measurement:
        """One scan from ``t0_ns`` as its :class:`~.base.Measurement` (with ``labels``, the
        scene's per-triangle labels, each beam's label too)."""
        c = self.config
        k, j = self._grid
        bt = c.beam_time
        t_knots = t0_ns * 1e-9 + np.arange(k, dtype=np.float64) * (j * bt)
        if bt == 0.0:  # all beams at once: one pose
            t_knots = np.full(k, t0_ns * 1e-9)
        origins, dirs = rays_in_world(
            trajectory,
            self.T_body_sensor,
            t_knots,
            self._frac,
            self._dirs,
            mode=c.firing_poses if bt > 0 else "exact",
            spacing=j * bt,  # a scan of one knot (<= 32 beams) still spans j beam times
        )
        n = c.n_beams
        m = measure(
            caster,
            origins.reshape(-1, 3)[:n],
            dirs.reshape(-1, 3)[:n],
            min_range=c.range_min,
            max_range=c.range_max,
            noise_sigma=c.noise_sigma,
            returns=c,
            rng=rng,
            labels=labels,
            t=firing_times(t_knots, self._frac, j * bt)[:n],
        )
        return m

    def messages(self, ctx: SimContext) -> Iterator[Message]:
        c = self.config
        caster = ctx.raycaster()
        rng = ctx.rng(c.name)
        if ctx.files is not None:  # (no file sink: a run that records nothing)
            self._fh = ctx.files.path(f"laser_{c.name}.txt").open(
                "w", encoding="utf-8", newline="\n"
            )
        table = label_table(ctx, c)
        if ctx.files is not None and table is not None:
            self._labels_fh = ctx.files.path(f"laser_{c.name}_labels.txt").open(
                "w", encoding="utf-8", newline="\n"
            )
        # t r_0 .. r_n: no header line (columns and angles in OUTDIR/README.md)
        angle_max = float(self.angles[-1])
        # a scan sweeps over [t0, t0 + 1/rate): only whole scans within the trajectory
        period, rate = round(1e9 / c.rate), c.rate
        grid = ctx.clock.grid(lambda end: sample_times_ns(rate, end - period), lead_ns=period)
        last = [-1]
        for item in paced(grid, 1, lambda: last[0] + 1):
            if isinstance(item, Message):
                yield item  # wait for the horizon
                continue
            seq, t0 = item[0], int(item[1][0])
            last[0] = t0
            m = self.measure_scan(ctx.trajectory, caster, t0, rng, table)
            ranges, inten = m.range.astype(np.float32), m.intensity
            ctx.clock.tap(c.name, LaserScan(t0, ranges, inten))
            if self._fh is not None:
                txt = " ".join(np.char.mod("%.6f", ranges.astype(np.float64)).tolist())
                self._fh.write(f"{format_seconds([t0])[0]} {txt}\n")
            if self._labels_fh is not None and m.label is not None:
                txt = " ".join(m.label.astype(str).tolist())
                self._labels_fh.write(f"{format_seconds([t0])[0]} {txt}\n")
            stamp = ctx.stamp(t0)

            def build(
                store: Any,
                ranges: NDArray[np.float32] = ranges,
                inten: NDArray[np.float32] = inten,
                stamp: int = stamp,
                seq: int = seq,
            ) -> Any:
                return store.new(
                    LASERSCAN,
                    header=store.header(stamp, c.frame, seq),
                    angle_min=float(c.angle_min),
                    angle_max=angle_max,
                    angle_increment=float(c.angle_increment),
                    time_increment=float(c.beam_time),
                    scan_time=1.0 / c.rate,
                    range_min=float(c.range_min),
                    range_max=float(c.range_max),
                    ranges=ranges,
                    intensities=inten,
                )

            yield Message(t0, c.topic, LASERSCAN, build)

    def close(self, ctx: SimContext) -> None:
        for fh in (self._fh, self._labels_fh):
            if fh is not None:
                fh.close()
        self._fh = self._labels_fh = None
