"""Shared machinery of the ray-cast (beam) sensors: the range sensor model (limits, noise,
dropout, intensity), the per-scan ``.npz`` dataset files and the point-cloud sensor base
(rays: :mod:`roslan.sensors.beams.rays`; packing: :mod:`roslan.sensors.beams.pointcloud`).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal, NamedTuple

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from roslan.config.base import FiniteFloat
from roslan.io.files import save_npz
from roslan.io.ordered import OrderedPool, Turn
from roslan.sensors.base import (
    LabelsKey,
    Message,
    SensorConfig,
    SimContext,
    StaticTransform,
    TopicSpec,
    paced,
    sample_times_ns,
)
from roslan.sensors.beams.labels import cast_labelled, label_table
from roslan.sensors.beams.pointcloud import POINTCLOUD2, pointcloud2
from roslan.sensors.measurements import CloudScan

if TYPE_CHECKING:
    from roslan.render.base import BeamCaster

__all__ = [
    "BeamConfig",
    "BeamDraws",
    "Measurement",
    "PointCloudSensor",
    "ScanWriter",
    "draw_beams",
    "measure",
]

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]


class BeamConfig(SensorConfig, LabelsKey):
    """Keys of the return model every scanning beam sensor (lidar, solid_state_lidar,
    laser) shares."""

    dropout: Annotated[FiniteFloat, Field(ge=0, lt=1)] = 0.0
    """Probability that a return is lost."""
    intensity_scale: Annotated[FiniteFloat, Field(ge=0)] = 255.0
    """intensity = scale x reflectivity x cos(incidence)."""
    intensity_step: Annotated[FiniteFloat, Field(ge=0)] = 1.0
    """Quantization step of the intensity: the sensors report integer codes (8-bit on
    the HDL-32E, Livox and most 2-D scanners); 0 keeps it continuous."""
    firing_poses: Literal["interpolated", "exact"] = "interpolated"
    """Sensor pose of each firing: interpolated between knots, or the trajectory's
    closed form at every firing instant (:mod:`roslan.sensors.beams.rays`)."""


class Measurement(NamedTuple):
    """Ranges of N beams after the sensor model.

    Attributes:
        range: (N,) float64 measured range, m (noise added, within [min, max]); +inf for
            no return (miss, beyond max range, dropout), -inf for a surface closer than
            the minimum range (REP 117).
        valid: (N,) bool, a finite return.
        intensity: (N,) float32 ``intensity_scale * reflectivity * cos(incidence)``
            rounded to a multiple of ``intensity_step`` (unless 0), 0 without return.
        label: (N,) uint32 label of the surface each beam returned from (the SemanticKITTI
            encoding, :mod:`roslan.sensors.beams.labels`; 0 without return), or None when
            the cast was not labelled.
    """

    range: F64
    valid: NDArray[np.bool_]
    intensity: F32
    label: NDArray[np.uint32] | None = None


class BeamDraws(NamedTuple):
    """The random draws of N beams (:func:`draw_beams`), made before the cast.

    Attributes:
        noise: (N,) standard normal range noise, or None without noise.
        uniform: (N,) uniform [0, 1) dropout draws, or None without dropout.
    """

    noise: F64 | None
    uniform: F64 | None


def draw_beams(
    rng: np.random.Generator, n: int, noise_sigma: float, returns: BeamConfig
) -> BeamDraws:
    """The draws :func:`measure` makes for ``n`` beams, in its order: ``n`` normals (if
    ``noise_sigma`` > 0), then ``n`` uniforms (if ``returns.dropout`` > 0). They do not
    depend on what is hit, so a scan's draws can be made in time order on the sensor's
    thread and the scan cast on any other."""
    noise = rng.standard_normal(n) if noise_sigma > 0 else None
    uniform = rng.random(n) if returns.dropout > 0 else None
    return BeamDraws(noise, uniform)


def measure(
    caster: BeamCaster,
    origins: NDArray[np.floating[Any]],
    directions: NDArray[np.floating[Any]],
    *,
    min_range: float,
    max_range: float,
    noise_sigma: float,
    returns: BeamConfig,
    rng: np.random.Generator | BeamDraws,
    labels: NDArray[np.uint32] | None = None,
    t: float | NDArray[np.float64] | None = None,
) -> Measurement:
    """Cast the beams and apply the range sensor model (see :class:`Measurement`):
    limits, noise, and the dropout and intensity keys of ``returns``; with ``labels``
    (:func:`~roslan.sensors.beams.labels.triangle_labels` of the scene) also the label of
    each return, from the same cast (the ranges and intensities are the same bits).

    The random draws (one normal and one uniform per beam) do not depend on what is
    hit, so a seed gives the same noise stream whatever the scene; ``rng`` is the
    generator to draw them from, or the draws themselves (:func:`draw_beams`). ``t``: the
    beams' firing instants (trajectory s, scalar or (N,); :func:`~.rays.firing_times`),
    the scene each is cast against (a static scene is the same at every instant).
    """
    n = origins.shape[0]
    label = None
    if labels is None:
        dist, echo = caster.cast_incidence(origins, directions, max_range, t=t)
    else:
        dist, echo, label = cast_labelled(caster, origins, directions, max_range, labels, t=t)
    draws = rng if isinstance(rng, BeamDraws) else draw_beams(rng, n, noise_sigma, returns)
    dropout = returns.dropout
    for a, used in ((draws.noise, noise_sigma > 0), (draws.uniform, dropout > 0)):
        if used and (a is None or a.shape != (n,)):
            msg = f"beam draws {None if a is None else a.shape} for {n} beams"
            raise ValueError(msg)
    noise = draws.noise if noise_sigma > 0 else None
    keep = draws.uniform >= dropout if draws.uniform is not None and dropout > 0 else None
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
    scale = np.float32(returns.intensity_scale)
    inten = np.where(valid, scale * echo, np.float32(0.0)).astype(np.float32)
    if returns.intensity_step > 0:  # the sensor's integer (e.g. 8-bit) intensity codes
        step = np.float32(returns.intensity_step)
        np.multiply(np.rint(inten / step), step, out=inten)
    if label is not None:
        label[~valid] = 0  # no return: no label
    return Measurement(r, valid, inten, label)


class ScanWriter:
    """Dataset files of a point-cloud sensor, streamed one scan at a time.

    ``lidar/<name>/NNNNNN.npz`` per scan with 1-D arrays ``x y z intensity`` (float32,
    m, sensor frame at each point's firing instant), ``ring`` (uint16) and ``time``
    (float32, s after the scan stamp), plus ``stamp`` (int64 trajectory ns) - and
    ``lidar/<name>/timestamps.txt`` with lines ``t <name>/NNNNNN.npz`` (t in seconds since
    the trajectory start, 9 decimals; the path relative to ``lidar/``). Organized clouds
    are stored without their NaN (no return) entries. A labelled scan (``output.labels``)
    adds ``label`` (uint32, SemanticKITTI: class | instance << 16), one per point.
    """

    def __init__(self, folder: Path, index: Path) -> None:
        self.folder = folder
        self.index = index
        self._fh: Any = None
        self.count = 0

    def write(self, t_ns: int, points: NDArray[Any]) -> None:
        """The next scan's file and index line."""
        self.write_file(self.count, t_ns, points)
        self.listed(self.count, t_ns)

    def write_file(self, count: int, t_ns: int, points: NDArray[Any]) -> None:
        """Scan number ``count``'s ``.npz`` file (any thread; then :meth:`listed`)."""
        self.folder.mkdir(parents=True, exist_ok=True)
        name = f"{count:06d}.npz"
        ok = ~np.isnan(points["x"])  # organized clouds carry NaN rows for no return
        keep = slice(None) if bool(ok.all()) else np.flatnonzero(ok)
        del ok
        # one field at a time (a strided view, or a copy of the returns of one field):
        # a 12.8 M-point scan's file costs no second copy of its cloud
        arrays = {k: _Field(points, k, keep) for k in points.dtype.names or ()}
        tmp = self.folder / (name + ".part")
        with tmp.open("wb") as fh:
            save_npz(fh, {"stamp": np.asarray(t_ns, np.int64), **arrays})
        tmp.replace(self.folder / name)

    def listed(self, count: int, t_ns: int) -> None:
        """Scan number ``count``'s line in ``timestamps.txt`` (in scan order, after its
        file is written)."""
        if self._fh is None:
            self._fh = self.index.open("w", encoding="utf-8")
        sec, nsec = divmod(int(t_ns), 1_000_000_000)
        self._fh.write(f"{sec}.{nsec:09d} {self.folder.name}/{count:06d}.npz\n")
        self.count = count + 1

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None


class _Field:
    """One field of a cloud for :func:`~roslan.io.files.save_npz`, made when written."""

    def __init__(self, points: NDArray[Any], name: str, keep: Any) -> None:
        self.points, self.name, self.keep = points, name, keep

    def __call__(self) -> NDArray[Any]:
        out: NDArray[Any] = self.points[self.name][self.keep]
        return out


class PointCloudSensor:
    """The stream shared by the point-cloud sensors (``lidar``, ``solid_state_lidar``):
    one :meth:`scan` every ``1 / config.rate`` s from t = 0, each a PointCloud2 on
    ``config.topic`` in ``config.frame`` stamped at the scan start, and its
    :class:`ScanWriter` files in ``lidar/<name>/``. Subclasses provide ``config`` and
    ``scan``, and :meth:`cloud_layout` for organized clouds."""

    config: Any
    _writer: ScanWriter | None = None

    def scan(
        self,
        trajectory: Any,
        caster: BeamCaster,
        t0_ns: int,
        rng: np.random.Generator | BeamDraws,
        *,
        labels: NDArray[np.uint32] | None = None,
    ) -> NDArray[Any]:  # pragma: no cover - every subclass has one
        """One scan from ``t0_ns``: :data:`~.pointcloud.XYZIRT` points, or
        :data:`~.pointcloud.XYZIRTL` with ``labels`` (the scene's
        :func:`~roslan.sensors.beams.labels.triangle_labels`)."""
        raise NotImplementedError

    def cloud_layout(self) -> tuple[int, bool]:
        """(PointCloud2 height, is_dense): unorganized by default."""
        return 1, True

    def topics(self) -> list[TopicSpec]:
        return [TopicSpec(self.config.topic, POINTCLOUD2)]

    def static_transforms(self) -> list[StaticTransform]:
        return []  # base_link -> frame comes from the extrinsics (pipeline)

    def messages(self, ctx: SimContext) -> Iterator[Message]:
        """One cloud per scan. Each scan's random draws are made here, in time order
        (:meth:`draw`); the scan itself (rays, cast, range model, packing, its ``.npz``
        file) runs on the sensor's pool (``ctx.sensor_threads`` threads; the cast of one
        scan beside the file of the previous), and the scans come back in order."""
        cfg = self.config
        caster = ctx.raycaster()
        rng = ctx.rng(cfg.name)
        writer: ScanWriter | None = None
        if ctx.files is not None:  # (no file sink: a run that records nothing)
            index = ctx.files.path(f"lidar/{cfg.name}/timestamps.txt")
            writer = self._writer = ScanWriter(index.parent, index)
        height, dense = self.cloud_layout()
        table = label_table(ctx, cfg)
        pool: OrderedPool[tuple[int, int, NDArray[Any]]] = OrderedPool(
            ctx.sensor_threads, f"{cfg.name}-scans"
        )

        def task(turn: Turn, seq: int, t0: int, draws: BeamDraws) -> tuple[int, int, NDArray[Any]]:
            pts = self.scan(ctx.trajectory, caster, t0, draws, labels=table)
            if writer is not None:
                writer.write_file(seq, t0, pts)
            return seq, t0, pts

        def emit(done: list[tuple[int, int, NDArray[Any]]]) -> Iterator[Message]:
            for seq, t0, pts in done:
                if writer is not None:
                    writer.listed(seq, t0)
                ctx.clock.tap(cfg.name, CloudScan(t0, pts))
                stamp = ctx.stamp(t0)

                def build(
                    store: Any, pts: NDArray[Any] = pts, stamp: int = stamp, seq: int = seq
                ) -> Any:
                    return pointcloud2(
                        store, stamp, cfg.frame, pts, height=height, seq=seq, is_dense=dense
                    )

                yield Message(t0, cfg.topic, POINTCLOUD2, build)

        # a scan fires over [t0, t0 + 1/rate): only whole scans that end within the
        # trajectory (and so within the ground-truth record) are produced
        period, rate = round(1e9 / cfg.rate), cfg.rate
        grid = ctx.clock.grid(
            lambda end: sample_times_ns(rate, end - period), lead_ns=self.read_span_ns()
        )
        last = [-1]
        try:
            for item in paced(grid, 1, lambda: last[0] + 1):
                if isinstance(item, Message):
                    yield from emit(pool.finish())  # every scan submitted, then wait
                    yield item
                    continue
                seq, t0 = item[0], int(item[1][0])
                last[0] = t0
                yield from emit(pool.submit(task, seq, t0, self.draw(rng)))
            yield from emit(pool.finish())
        finally:
            pool.close()  # a failed or abandoned run: no write into its folder after this

    def read_span_ns(self) -> int:
        """How far past its start a scan reads the trajectory (ns): its sweep, ``1 / rate``
        (a scanner whose firing poses pad past it says so)."""
        rate: float = self.config.rate
        return round(1e9 / rate)

    def draw(self, rng: np.random.Generator) -> BeamDraws:  # pragma: no cover - overridden
        """The random draws of one scan (:func:`draw_beams`)."""
        raise NotImplementedError

    def close(self, ctx: SimContext) -> None:
        if self._writer is not None:
            self._writer.close()
