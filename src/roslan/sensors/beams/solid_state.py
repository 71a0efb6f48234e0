"""Solid-state LiDAR with a Livox-like non-repetitive rosette (``type: solid_state_lidar``).

Scan model: a Risley prism pair. Two thin wedges counter-rotate at ``prism_rpm``
(Livox Mid-40: 7294 and -4664 rpm, docs/design.md §3); each deflects the beam by a fixed
angle ``delta`` in the direction of its current rotation angle, and the deflections
add (first-order thin-prism model)::

    (u, v)(t) = delta * (cos p1 + cos p2, sin p1 + sin p2),   p_i = 2 pi rpm_i / 60 * t

``u`` (towards +y, left) and ``v`` (towards +z, up) are angles from the sensor's
+x axis, ``delta = fov / 4`` so the pattern fills a cone of full angle ``fov``
(``fov_deg = (horizontal, vertical)``: the u and v axes are scaled to each).
Because the rpm ratio is not a small rational, the rosette does not repeat: each
frame covers new directions, and coverage of the FOV grows with integration time.
``t`` runs from the trajectory start, continuously across frames.

``lines > 1`` (the Avia has 6 emitters) fires that many beams at each instant, the
rosette of line ``l`` rotated by ``2 pi l / lines`` about the axis; ``point_rate``
counts all lines. Each beam leaves from the sensor pose at its own instant, as for the
spinning LiDAR (:mod:`roslan.sensors.beams`).

Output: one sensor_msgs/PointCloud2 per frame (``rate`` Hz) with the same XYZIRT
layout as :mod:`roslan.sensors.beams.lidar` (``ring`` = line, ``time`` = s after the stamp,
in [0, 1/rate)), points in the sensor frame at their own instants; dataset files
``lidar/<name>/NNNNNN.npz``.
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
from roslan.sensors.beams.rays import rays_in_world

if TYPE_CHECKING:
    from roslan.render.base import BeamCaster

__all__ = ["SOLID_STATE_PRESETS", "SolidStateLidar", "SolidStateLidarConfig", "SolidStatePreset"]

_INSTANTS_PER_KNOT = 64


@dataclass(frozen=True)
class SolidStatePreset:
    fov_deg: tuple[float, float]  # full angles (horizontal, vertical)
    point_rate: float  # points/s, all lines
    lines: int
    prism_rpm: tuple[float, float]
    min_range: float
    max_range: float
    noise_sigma: float


SOLID_STATE_PRESETS: dict[str, SolidStatePreset] = {
    # Livox Mid-40: 38.4 deg circular FOV, 100k points/s, 1 m blind zone, 260 m
    # (80 % reflectivity), 2 cm range precision.
    "mid40": SolidStatePreset((38.4, 38.4), 100_000.0, 1, (7294.0, -4664.0), 1.0, 260.0, 0.02),
    # Livox Avia: 70.4 x 77.2 deg, 240k points/s (first return), 6 lines, 1 m blind zone,
    # 450 m (80 %), 2 cm. Its prism speeds are not published: the Mid-40's are used.
    "avia": SolidStatePreset((70.4, 77.2), 240_000.0, 6, (7294.0, -4664.0), 1.0, 450.0, 0.02),
}

PositiveFloat = Annotated[FiniteFloat, Field(gt=0)]
FovAngle = Annotated[FiniteFloat, Field(gt=0, lt=180)]


class SolidStateLidarConfig(BeamConfig):
    """``type: solid_state_lidar``. ``rate`` = frames per second; None takes the preset."""

    type: Literal["solid_state_lidar"]
    rate: PositiveFloat = 10.0
    topic: TopicName = "/livox/lidar"
    preset: Literal["mid40", "avia"] = "mid40"
    fov_deg: tuple[FovAngle, FovAngle] | None = None
    point_rate: Annotated[FiniteFloat, Field(gt=0, le=10_000_000)] | None = None
    lines: Annotated[int, Field(ge=1, le=128)] | None = None
    prism_rpm: tuple[FiniteFloat, FiniteFloat] | None = None
    min_range: Annotated[FiniteFloat, Field(ge=0)] | None = None
    max_range: PositiveFloat | None = None
    noise_sigma: Annotated[FiniteFloat, Field(ge=0)] | None = None

    @model_validator(mode="after")
    def _check(self) -> SolidStateLidarConfig:
        p = self.resolved()
        if not p.min_range < p.max_range:
            msg = f"min_range = {p.min_range} m must be less than max_range = {p.max_range} m"
            raise ValueError(msg)
        if p.prism_rpm[0] == 0 or p.prism_rpm[1] == 0:
            msg = f"prism_rpm = {list(p.prism_rpm)}: both prisms must rotate (non-zero rpm)"
            raise ValueError(msg)
        per_frame = p.point_rate / self.rate / p.lines
        if per_frame < 1:
            msg = (
                f"point_rate = {p.point_rate} points/s over {p.lines} lines at rate {self.rate} Hz "
                "leaves less than one firing per frame"
            )
            raise ValueError(msg)
        return self

    def resolved(self) -> SolidStatePreset:
        """The preset with this config's overrides applied."""
        p = SOLID_STATE_PRESETS[self.preset]
        return SolidStatePreset(
            fov_deg=self.fov_deg if self.fov_deg is not None else p.fov_deg,
            point_rate=self.point_rate if self.point_rate is not None else p.point_rate,
            lines=self.lines if self.lines is not None else p.lines,
            prism_rpm=self.prism_rpm if self.prism_rpm is not None else p.prism_rpm,
            min_range=self.min_range if self.min_range is not None else p.min_range,
            max_range=self.max_range if self.max_range is not None else p.max_range,
            noise_sigma=self.noise_sigma if self.noise_sigma is not None else p.noise_sigma,
        )


def rosette_directions(t: NDArray[np.float64], spec: SolidStatePreset) -> NDArray[np.float64]:
    """(N, lines, 3) unit sensor-frame beam directions at instants ``t`` (s), see module doc."""
    w1, w2 = (2.0 * math.pi * r / 60.0 for r in spec.prism_rpm)
    p1 = w1 * t[:, None]
    p2 = w2 * t[:, None]
    rot = 2.0 * math.pi * np.arange(spec.lines) / spec.lines  # line offsets
    # unit-amplitude pattern (|.| <= 2), rotated per line
    a = np.cos(p1 + rot) + np.cos(p2 + rot)
    b = np.sin(p1 + rot) + np.sin(p2 + rot)
    half_h, half_v = (math.radians(f) / 2.0 for f in spec.fov_deg)
    u = a * (half_h / 2.0)
    v = b * (half_v / 2.0)
    theta = np.hypot(u, v)
    s = np.where(theta > 0, np.sin(theta) / np.where(theta > 0, theta, 1.0), 1.0)
    return np.stack([np.cos(theta), s * u, s * v], axis=-1)


class SolidStateLidar(PointCloudSensor):
    """Livox-like solid-state LiDAR (see module docstring)."""

    def __init__(self, config: SolidStateLidarConfig) -> None:
        self.config = config
        self.spec = config.resolved()
        s = self.spec
        self.firing_dt = s.lines / s.point_rate  # s between instants
        self.instants = math.floor(1.0 / (config.rate * self.firing_dt) + 1e-9)
        self.T_body_sensor = config.pose.matrix()

    def read_span_ns(self) -> int:
        """A frame's firing instants padded to whole knots (:meth:`scan`), and the knot
        after them (interpolated poses), ns."""
        j = min(self.instants, _INSTANTS_PER_KNOT)
        k = -(-self.instants // j)
        return int(max(round(1e9 / self.config.rate), math.ceil(k * j * self.firing_dt * 1e9) + 1))

    def draw(self, rng: np.random.Generator) -> BeamDraws:
        """The random draws of one scan's beams (:func:`~.base.draw_beams`)."""
        return draw_beams(rng, self.instants * self.spec.lines, self.spec.noise_sigma, self.config)

    def scan(
        self,
        trajectory: Any,
        caster: BeamCaster,
        t0_ns: int,
        rng: np.random.Generator | BeamDraws,
        *,
        labels: NDArray[np.uint32] | None = None,
    ) -> NDArray[Any]:
        """One frame from ``t0_ns``: (n_returns,) :data:`XYZIRT` points in firing order
        (:data:`XYZIRTL` with ``labels``, the scene's per-triangle labels)."""
        s = self.spec
        j = min(self.instants, _INSTANTS_PER_KNOT)
        k = -(-self.instants // j)
        off = np.arange(k * j, dtype=np.float64) * self.firing_dt  # padded to whole knots
        t0 = t0_ns * 1e-9
        d_s = rosette_directions(t0 + off, s)  # (k*j, lines, 3)
        d_grid = d_s.reshape(k, j * s.lines, 3)
        frac = np.repeat(np.arange(j, dtype=np.float64) / j, s.lines)
        t_knots = t0 + np.arange(k, dtype=np.float64) * (j * self.firing_dt)
        origins, dirs = rays_in_world(
            trajectory, self.T_body_sensor, t_knots, frac, d_grid, mode=self.config.firing_poses
        )
        n = self.instants * s.lines
        m = measure(
            caster,
            origins.reshape(-1, 3)[:n],
            dirs.reshape(-1, 3)[:n],
            min_range=s.min_range,
            max_range=s.max_range,
            noise_sigma=s.noise_sigma,
            returns=self.config,
            rng=rng,
            labels=labels,
            t=np.repeat(t0 + off[: self.instants], s.lines),
        )
        sel = np.flatnonzero(m.valid)
        d_flat = d_s.reshape(-1, 3)[:n]
        pts = np.empty(sel.shape[0], XYZIRT if m.label is None else XYZIRTL)
        xyz = d_flat[sel] * m.range[sel, None]
        pts["x"], pts["y"], pts["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
        pts["intensity"] = m.intensity[sel]
        pts["ring"] = (sel % s.lines).astype(np.uint16)
        pts["time"] = off[sel // s.lines]
        if m.label is not None:
            pts["label"] = m.label[sel]
        return pts
