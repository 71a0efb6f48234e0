"""Shared machinery of the ray-cast (beam) sensors: rays from the pose at each firing
instant, range measurement (limits, noise, dropout, intensity), PointCloud2 packing and
the per-scan ``.npz`` dataset files.

Firing poses. A spinning LiDAR fires ~700k beams per second while it moves; each beam
leaves from the sensor pose at its own instant. ``trajectory.state`` costs ~0.5 us per
instant, so evaluating it at all 69k firing instants of an HDL-32E turn would take
~30 ms, twice the whole per-turn budget. :func:`rays_in_world` therefore evaluates
the closed-form trajectory exactly at knots ``h`` apart (one firing cycle, 46 us, for
the HDL-32E) and, between two knots, uses cubic Hermite interpolation of the
position (exact values *and* velocities at both knots) and of the rotation vector
(exact relative rotation and angular velocities at both knots). Over 46 us that is
within 1e-9 m / 1e-9 rad of the exact pose for the flapping landing trajectories
(``tests/test_lidar_motion.py`` checks it against ``state`` at every instant);
``firing_poses: exact`` evaluates ``state`` at every instant instead.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, NamedTuple

import numpy as np
from numpy.typing import NDArray

from roslan.sensors.base import Message, SimContext, StaticTransform, TopicSpec, sample_times_ns

if TYPE_CHECKING:
    from roslan.io.messages import MessageStore
    from roslan.render.base import BeamCaster
    from roslan.trajectory.generator import Trajectory

__all__ = [
    "POINTCLOUD2",
    "XYZIRT",
    "Measurement",
    "PointCloudSensor",
    "ScanWriter",
    "measure",
    "pointcloud2",
    "rays_in_world",
    "rotvec_log",
]

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]

XYZIRT = np.dtype(
    {
        "names": ["x", "y", "z", "intensity", "ring", "time"],
        "formats": ["<f4", "<f4", "<f4", "<f4", "<u2", "<f4"],
        "offsets": [0, 4, 8, 12, 16, 18],
        "itemsize": 22,
    }
)
"""velodyne_pointcloud's PointXYZIRT wire layout: packed, 22 bytes per point."""

POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"

_POINTFIELD_TYPE = {np.dtype("<f4"): 7, np.dtype("<u2"): 4, np.dtype("<f8"): 8, np.dtype("u1"): 2}


def _cross(a: NDArray[Any], b: NDArray[Any]) -> NDArray[Any]:
    # np.cross on (N,3) is slow for large N; explicit components are 3x faster
    out: NDArray[Any] = np.stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        axis=-1,
    )
    return out


def rotvec_log(R: F64) -> F64:
    """(..., 3) rotation vectors of rotation matrices R (..., 3, 3) with angle < pi."""
    tr = np.trace(R, axis1=-2, axis2=-1)
    cos = np.clip((tr - 1.0) * 0.5, -1.0, 1.0)
    theta = np.arccos(cos)
    w = 0.5 * np.stack(
        [R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]],
        axis=-1,
    )
    sin = np.sin(theta)
    small = theta < 1e-6
    scale = np.where(small, 1.0 + theta**2 / 6.0, theta / np.where(small, 1.0, sin))
    out: F64 = w * scale[..., None]
    return out


def _rotate(rv: NDArray[Any], v: NDArray[Any]) -> NDArray[Any]:
    """Rotate vectors v (N, 3) by rotation vectors rv (N, 3) (Rodrigues)."""
    c1 = _cross(rv, v)
    big = float(np.abs(rv).max(initial=0.0))
    if big < 2e-4:
        # |rv| < 3.5e-4 rad: the 2nd-order term (< 6e-8) is below float32 resolution
        first: NDArray[Any] = v + c1
        return first
    if big < 1e-3:
        # |rv| < 2e-3 rad (the usual case: ~w * 46 us): 2nd-order series, error < 1.5e-9
        small: NDArray[Any] = v + c1 + 0.5 * _cross(rv, c1)
        return small
    theta = np.sqrt(np.einsum("ij,ij->i", rv, rv))
    safe = np.where(theta > 1e-12, theta, 1.0)
    s = np.where(theta > 1e-12, np.sin(theta) / safe, 1.0)
    c = np.where(theta > 1e-12, (1.0 - np.cos(theta)) / (safe * safe), 0.5)
    out: NDArray[Any] = v + c1 * s[:, None] + _cross(rv, c1) * c[:, None]
    return out


def rays_in_world(
    trajectory: Trajectory,
    T_body_sensor: F64,
    t_knots: F64,
    frac: F64,
    d_sensor: NDArray[np.floating[Any]],
    mode: Literal["interpolated", "exact"] = "interpolated",
) -> tuple[NDArray[np.floating[Any]], NDArray[np.floating[Any]]]:
    """World rays of beams fired on a knots x fractions time grid.

    Beam ``(k, j)`` fires at ``t_knots[k] + frac[j] * h`` (``h`` = knot spacing) along
    sensor-frame direction ``d_sensor[k, j]``: a spinning LiDAR's columns x lasers, a
    solid-state LiDAR's blocks x points.

    Args:
        trajectory: anything with ``state(t_seconds) -> State`` (closed form).
        T_body_sensor: (4, 4) sensor extrinsics in base_link.
        t_knots: (K,) equally spaced instants, trajectory seconds (K >= 1).
        frac: (J,) firing offsets within a knot interval as fractions in [0, 1].
        d_sensor: (K, J, 3) unit beam directions in the sensor frame.
        mode: ``interpolated`` (exact state at the knots + cubic Hermite between them, see
            the module docstring) or ``exact`` (``state`` at every firing instant).

    Returns:
        origins and unit directions, each (K, J, 3), world frame; float32 (float64 in
        exact mode).
    """
    R_bs = T_body_sensor[:3, :3]
    t_bs = T_body_sensor[:3, 3]
    n_k, n_j = d_sensor.shape[:2]
    h = float(t_knots[1] - t_knots[0]) if n_k > 1 else 0.0
    if mode == "exact":
        t = (t_knots[:, None] + frac[None, :] * h).reshape(-1)
        st = trajectory.state(t)
        R_ws = st.R_world_body @ R_bs
        origins = st.position + st.R_world_body @ t_bs
        dirs = np.einsum("nij,nj->ni", R_ws, d_sensor.reshape(-1, 3))
        return origins.reshape(n_k, n_j, 3), dirs.reshape(n_k, n_j, 3)
    if h == 0.0:
        h = 1e-3  # a single knot interval of arbitrary length: the ends are exact anyway
    tk = np.concatenate([t_knots, [t_knots[-1] + h]])
    st = trajectory.state(tk)
    R_wb = st.R_world_body
    R_ws = R_wb @ R_bs  # (K+1, 3, 3)
    p = st.position + R_wb @ t_bs  # (K+1, 3) sensor origin
    lever = _cross(st.omega_body, np.broadcast_to(t_bs, st.omega_body.shape))
    v = st.velocity + (R_wb @ lever[:, :, None])[:, :, 0]
    # angular velocity of the sensor in the world frame, times h
    w_w = (R_wb @ st.omega_body[:, :, None])[:, :, 0] * h
    r_rel = rotvec_log(R_ws[:-1].transpose(0, 2, 1) @ R_ws[1:])  # (K, 3) in frame k
    r_rel_w = (R_ws[:-1] @ r_rel[:, :, None])[:, :, 0]  # the same, world frame
    f = frac[:, None]
    f2, f3 = f * f, f * f * f
    # cubic Hermite basis (J, 1) of the interval fractions
    h10 = f3 - 2 * f2 + f
    h01 = -2 * f3 + 3 * f2
    h11 = f3 - f2
    basis = np.concatenate([h10, h01, h11], axis=1)  # (J, 3); h00 = 1 - h01 folded in
    # origin = p_k + h01 (p_k+1 - p_k) + h10 h v_k + h11 h v_k+1: one batched matmul
    terms = np.stack([h * v[:-1], p[1:] - p[:-1], h * v[1:]], axis=1)  # (K, 3, 3)
    # float32 like Embree's rays (7.6e-6 m resolution at 100 m from the origin)
    offsets = basis.astype(np.float32)[None] @ terms.astype(np.float32)  # (K, J, 3)
    origins32 = p[:-1, None, :].astype(np.float32) + offsets
    # rotation since knot k, as a Hermite curve of its (world-frame) rotation vector
    rterms = np.stack([w_w[:-1], r_rel_w, w_w[1:]], axis=1).astype(np.float32)
    rho = basis.astype(np.float32)[None] @ rterms  # (K, J, 3)
    d0 = d_sensor.astype(np.float32, copy=False) @ R_ws[:-1].transpose(0, 2, 1).astype(np.float32)
    directions = _rotate(rho.reshape(-1, 3), d0.reshape(-1, 3)).reshape(n_k, n_j, 3)
    return origins32, directions


class Measurement(NamedTuple):
    """Ranges of N beams after the sensor model.

    Attributes:
        range: (N,) float64 measured range, m (noise added, within [min, max]); +inf for
            no return (miss, beyond max range, dropout), -inf for a surface closer than
            the minimum range (REP 117).
        valid: (N,) bool, a finite return.
        intensity: (N,) float32 ``scale * reflectivity * cos(incidence)``, 0 without return.
    """

    range: F64
    valid: NDArray[np.bool_]
    intensity: F32


def measure(
    caster: BeamCaster,
    origins: NDArray[np.floating[Any]],
    directions: NDArray[np.floating[Any]],
    *,
    min_range: float,
    max_range: float,
    noise_sigma: float,
    dropout: float,
    rng: np.random.Generator,
    intensity_scale: float = 1.0,
) -> Measurement:
    """Cast the beams and apply the range sensor model (see :class:`Measurement`).

    The random draws (one normal and one uniform per beam) do not depend on what is
    hit, so a seed gives the same noise stream whatever the scene.
    """
    n = origins.shape[0]
    dist, echo = caster.cast_incidence(origins, directions, max_range)
    noise = rng.standard_normal(n) if noise_sigma > 0 else None
    keep = rng.random(n) >= dropout if dropout > 0 else None
    true = dist.astype(np.float64)
    hit = np.isfinite(true)
    too_close = hit & (true < min_range)
    valid = hit & ~too_close
    if keep is not None:
        valid &= keep
        too_close &= keep
    r = true
    if noise is not None:
        r = np.clip(r + noise_sigma * noise, min_range, max_range)
    r[~valid] = np.inf
    r[too_close] = -np.inf
    inten = np.where(valid, np.float32(intensity_scale) * echo, np.float32(0.0)).astype(np.float32)
    return Measurement(r, valid, inten)


def pointcloud2(
    store: MessageStore,
    stamp_ns: int,
    frame_id: str,
    points: NDArray[Any],
    *,
    height: int = 1,
    seq: int = 0,
    is_dense: bool = True,
) -> Any:
    """sensor_msgs/PointCloud2 of a structured array (fields and offsets from its dtype).

    ``points`` is (height * width,) of a little-endian structured dtype such as
    :data:`XYZIRT`; its bytes are the message data as they are (no per-point Python).
    """
    dt = points.dtype
    assert dt.names is not None
    assert dt.fields is not None
    PointField = store.types["sensor_msgs/msg/PointField"]
    fields = []
    for name in dt.names:
        fdt, off = dt.fields[name][0], dt.fields[name][1]
        fields.append(PointField(name=name, offset=off, datatype=_POINTFIELD_TYPE[fdt], count=1))
    width = points.shape[0] // max(height, 1) if height else 0
    data = np.ascontiguousarray(points).view(np.uint8).reshape(-1)  # no copy
    return store.new(
        "sensor_msgs/msg/PointCloud2",
        header=store.header(stamp_ns, frame_id, seq),
        height=height,
        width=width,
        fields=fields,
        is_bigendian=False,
        point_step=dt.itemsize,
        row_step=dt.itemsize * width,
        data=data,
        is_dense=is_dense,
    )


class ScanWriter:
    """Dataset files of a point-cloud sensor, streamed one scan at a time.

    ``lidar/<name>/NNNNNN.npz`` per scan with 1-D arrays ``x y z intensity`` (float32,
    m, sensor frame at each point's firing instant), ``ring`` (uint16) and ``time``
    (float32, s after the scan stamp), plus ``stamp`` (int64 trajectory ns) - and
    ``lidar/<name>/timestamps.txt`` with lines ``t <name>/NNNNNN.npz`` (t in seconds since
    the trajectory start, 9 decimals; the path relative to ``lidar/``). Organized clouds
    are stored without their NaN (no return) entries.
    """

    def __init__(self, folder: Path, index: Path) -> None:
        self.folder = folder
        self.index = index
        self._fh: Any = None
        self.count = 0

    def write(self, t_ns: int, points: NDArray[Any]) -> None:
        if self._fh is None:
            self.folder.mkdir(parents=True, exist_ok=True)
            self._fh = self.index.open("w", encoding="utf-8")
        name = f"{self.count:06d}.npz"
        ok = ~np.isnan(points["x"])  # organized clouds carry NaN rows for no return
        arrays = {k: np.ascontiguousarray(points[k][ok]) for k in points.dtype.names or ()}
        tmp = self.folder / (name + ".part")
        with tmp.open("wb") as fh:
            np.savez_compressed(fh, stamp=np.asarray(t_ns, np.int64), **arrays)  # type: ignore[arg-type]
        tmp.replace(self.folder / name)
        sec, nsec = divmod(int(t_ns), 1_000_000_000)
        self._fh.write(f"{sec}.{nsec:09d} {self.folder.name}/{name}\n")
        self.count += 1

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None


class PointCloudSensor:
    """The stream shared by the point-cloud sensors (``lidar``, ``solid_state_lidar``):
    one :meth:`scan` every ``1 / config.rate`` s from t = 0, each a PointCloud2 on
    ``config.topic`` in ``config.frame`` stamped at the scan start, and its
    :class:`ScanWriter` files in ``lidar/<name>/``. Subclasses provide ``config`` and
    ``scan``, and :meth:`cloud_layout` for organized clouds."""

    config: Any
    _writer: ScanWriter | None = None

    def scan(
        self, trajectory: Any, caster: BeamCaster, t0_ns: int, rng: np.random.Generator
    ) -> NDArray[Any]:  # pragma: no cover - every subclass has one
        raise NotImplementedError

    def cloud_layout(self) -> tuple[int, bool]:
        """(PointCloud2 height, is_dense): unorganized by default."""
        return 1, True

    def topics(self) -> list[TopicSpec]:
        return [TopicSpec(self.config.topic, POINTCLOUD2)]

    def static_transforms(self) -> list[StaticTransform]:
        return []  # base_link -> frame comes from the extrinsics (pipeline)

    def messages(self, ctx: SimContext) -> Iterator[Message]:
        cfg = self.config
        caster = ctx.raycaster()
        rng = ctx.rng(cfg.name)
        index = ctx.path(f"lidar/{cfg.name}/timestamps.txt")
        self._writer = ScanWriter(index.parent, index)
        height, dense = self.cloud_layout()
        # a scan fires over [t0, t0 + 1/rate): only whole scans that end within the
        # trajectory (and so within the ground-truth record) are produced
        last_start = ctx.trajectory.duration_ns - round(1e9 / cfg.rate)
        for seq, t0 in enumerate(sample_times_ns(cfg.rate, last_start).tolist()):
            pts = self.scan(ctx.trajectory, caster, t0, rng)
            self._writer.write(t0, pts)
            stamp = ctx.stamp(t0)

            def build(
                store: Any, pts: NDArray[Any] = pts, stamp: int = stamp, seq: int = seq
            ) -> Any:
                return pointcloud2(
                    store, stamp, cfg.frame, pts, height=height, seq=seq, is_dense=dense
                )

            yield Message(t0, cfg.topic, POINTCLOUD2, build)

    def close(self, ctx: SimContext) -> None:
        if self._writer is not None:
            self._writer.close()
