"""Frame-camera shutters: exposure, rolling-shutter readout and auto-exposure.

**Timing of one frame** (docs/design.md §2). A frame with exposure ``E`` and readout
``R`` on an ``H``-row sensor exposes row ``r`` over ``[t_r, t_r + E]`` with
``t_r = t_start + r * R / H``; the frame's shutter window is
``[t_start, t_start + S]``, ``S = R * (H - 1) / H + E``. The image stamp is the middle
of that window, ``t_start + S / 2``: the middle of the exposure of the middle row
``(H - 1) / 2`` (for a global shutter, ``R = 0``, the middle of the exposure).

**Shared renders.** A frame is rendered at ``n`` instants ``tau_k = t_start +
(k + 1/2) * S / n`` (:func:`shutter_plan`); render ``k`` stands for its cell
``[tau_k - dt/2, tau_k + dt/2]``, ``dt = S / n``. Row ``r`` is the average of the renders
weighted by the overlap of its exposure window with their cells (``E = 0``: the render
whose cell holds ``t_r``). Every render serves all the rows whose windows meet its cell,
so a rolling-shutter frame costs ``n`` renders, not ``H * n``; and only the rows it
serves are rendered (a band, :attr:`ShutterPlan.rows`). With ``R = 0`` the rule is the
midpoint rule of a global shutter: ``n`` renders, equal weights.

**Auto-exposure** (:class:`AutoExposure`, :func:`auto_exposure_sequence`): before the
frames, a metering pass renders the scene's linear luminance at every frame stamp at
low resolution over the central quarter of the view (:func:`meter_view`; independent
of the exposure); a first-order controller in log exposure
then fixes the whole exposure sequence, causally (frame ``k``'s exposure comes from
the frames before it, as a real camera meters its previous frames). Every frame is
then computable on its own from its stamp and its exposure (time-parallel rendering).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Annotated

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, model_validator

from roslan.config.base import FiniteFloat, StrictModel
from roslan.render import FrameRenderer
from roslan.sensors.cameras.model import RenderPlan
from roslan.sensors.cameras.remap import remap_view

__all__ = [
    "BAND_MARGIN",
    "BAND_QUANTUM",
    "METER_DOWNSCALE",
    "METER_FIELD",
    "AutoExposure",
    "AutoExposureLoop",
    "Band",
    "RollingShutterKeys",
    "ShutterPlan",
    "add_band",
    "auto_exposure_sequence",
    "band_extents",
    "band_rows",
    "compose_bands",
    "meter_level",
    "meter_view",
    "render_bands",
    "render_rolling",
    "shutter_plan",
]

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

Positive = Annotated[FiniteFloat, Field(gt=0)]

METER_DOWNSCALE = 8
"""The metering render samples the metered field at 1/8 of the image's resolution."""
METER_FIELD = 0.5
"""Centre-weighted metering: the central ``METER_FIELD`` of the image's width and height
(its central quarter; 40x30 metering pixels for VGA). Fewer scene clusters to draw than
the whole field, and what a camera's centre-weighted metering favours."""


def meter_view(K: F64, width: int, height: int) -> tuple[F64, int, int]:
    """Pinhole intrinsics and size of the metering render of a ``width`` x ``height``
    camera with matrix ``K``: its central :data:`METER_FIELD` at 1/:data:`METER_DOWNSCALE`
    resolution (the lens distortion, small there, is ignored)."""
    fw, fh = width * METER_FIELD, height * METER_FIELD
    w = max(1, round(fw / METER_DOWNSCALE))
    h = max(1, round(fh / METER_DOWNSCALE))
    sx, sy = w / fw, h / fh
    x0, y0 = (width - fw) / 2.0, (height - fh) / 2.0  # the field's corner (pixel edges)
    Km = np.array(
        [
            [K[0, 0] * sx, K[0, 1] * sx, (K[0, 2] + 0.5 - x0) * sx - 0.5],
            [0.0, K[1, 1] * sy, (K[1, 2] + 0.5 - y0) * sy - 0.5],
            [0.0, 0.0, 1.0],
        ]
    )
    return Km, w, h


class AutoExposure(StrictModel):
    """``auto_exposure:`` of a frame or stereo camera.

    The controller drives the mean image level ``m`` (mean over the metering image, the
    central quarter of the view, of ``clip(gain * E / exposure_time * L, 0, 1)``, ``L``
    the linear luminance) to
    ``target``: ``E_{k+1} = clip(E_k * (target / m_k) ** a, min_exposure, max_exposure)``
    with ``a = 1 - exp(-1 / (rate * time_constant))``. In an unsaturated scene the log
    error then decays as ``exp(-t / time_constant)``: after a step of scene brightness
    the log error ``ln(m / target)`` is ``exp(-1)`` (37 %) of its value at the step after
    one time constant, ``exp(-n)`` after ``n``.
    """

    target: Annotated[FiniteFloat, Field(gt=0, lt=1)] = 0.18
    """Target mean level, linear (0.18: middle grey, sRGB code ~118)."""
    min_exposure: Positive = 1e-4
    """Shortest exposure (s)."""
    max_exposure: Positive = 0.01
    """Longest exposure (s)."""
    time_constant: Positive = 0.1
    """Time constant of the adaptation (s)."""

    @model_validator(mode="after")
    def _bounds(self) -> AutoExposure:
        if self.max_exposure < self.min_exposure:
            msg = (
                f"max_exposure = {self.max_exposure}: must be >= min_exposure = "
                f"{self.min_exposure} (s)"
            )
            raise ValueError(msg)
        return self

    def rate_per_frame(self, rate: float) -> float:
        """The controller's gain ``a`` per frame at ``rate`` frames/s."""
        return 1.0 - math.exp(-1.0 / (rate * self.time_constant))


def meter_level(lum: F32, scale: float) -> float:
    """Mean image level of linear luminance ``lum`` at brightness ``scale``
    (``gain * E / exposure_time``): the mean of ``clip(scale * lum, 0, 1)``."""
    return float(np.clip(lum * np.float32(scale), 0.0, 1.0).mean(dtype=np.float64))


def auto_exposure_sequence(
    meter: Callable[[int, float], float],
    n: int,
    initial: float,
    ae: AutoExposure,
    rate: float,
) -> F64:
    """Exposures (s) of ``n`` frames: frame 0 at ``initial`` (clipped to the bounds),
    frame ``k + 1`` from frame ``k``'s level ``meter(k, E_k)`` (see :class:`AutoExposure`).
    A black frame (level 0) opens to ``max_exposure``."""
    loop = AutoExposureLoop(initial, ae, rate)
    out = np.empty(n, dtype=np.float64)
    for k in range(n):  # one scalar per frame: the frames' metering is vectorized
        out[k] = loop.exposure
        loop.update(meter(k, loop.exposure))
    return out


class AutoExposureLoop:
    """The auto-exposure control loop one frame at a time (causal: frame ``k + 1``'s
    exposure from frame ``k``'s metered level), :func:`auto_exposure_sequence`'s steps."""

    def __init__(self, initial: float, ae: AutoExposure, rate: float) -> None:
        self.a = ae.rate_per_frame(rate)
        self.ae = ae
        self.exposure = min(max(float(initial), ae.min_exposure), ae.max_exposure)
        """The next frame's exposure (s)."""

    def update(self, level: float) -> None:
        """The exposure after a frame metered at ``level`` (its exposure's)."""
        ae, e = self.ae, self.exposure
        e = ae.max_exposure if level <= 0.0 else e * (ae.target / level) ** self.a
        self.exposure = min(max(e, ae.min_exposure), ae.max_exposure)


@dataclass(frozen=True)
class ShutterPlan:
    """The renders of one frame and how its rows combine them.

    Attributes:
        instants_ns: (n,) render instants (trajectory ns).
        weights: (H, n) float32 weight of render ``k`` in row ``r`` (rows sum to 1), or
            None for a global shutter (every render weighs ``1 / n`` everywhere).
        rows: (n, 2) first and last + 1 row that render ``k`` serves (weight > 0).
        start_ns: the shutter window's start ``t_start`` (ns).
    """

    instants_ns: I64
    weights: F32 | None
    rows: I64
    start_ns: int

    @property
    def global_shutter(self) -> bool:
        return self.weights is None


def shutter_plan(
    stamp_ns: int, exposure: float, readout: float, samples: int, height: int
) -> ShutterPlan:
    """Render instants and row weights of the frame stamped ``stamp_ns`` (see the module
    docstring): exposure ``exposure`` s, readout ``readout`` s, ``samples`` renders over
    the window (1 when both are 0), ``height`` rows."""
    span = readout * (height - 1) / height + exposure
    n = 1 if span <= 0.0 else int(samples)
    span_ns = span * 1e9
    offs = ((np.arange(n) + 0.5) / n - 0.5) * span_ns
    instants = (stamp_ns + np.round(offs)).astype(np.int64)
    start = stamp_ns - 0.5 * span_ns  # float ns: the weights need no rounding
    if readout <= 0.0:
        rows = np.tile(np.array([0, height], dtype=np.int64), (n, 1))
        return ShutterPlan(instants, None, rows, round(start))
    dt = span_ns / n
    edges = np.arange(n + 1, dtype=np.float64) * dt  # cell edges, relative to t_start
    t_r = np.arange(height, dtype=np.float64) * (readout * 1e9 / height)
    if exposure > 0.0:
        e_ns = exposure * 1e9
        lo = np.maximum(t_r[:, None], edges[None, :-1])
        hi = np.minimum(t_r[:, None] + e_ns, edges[None, 1:])
        w = np.clip(hi - lo, 0.0, None) / e_ns
    else:
        cell = np.minimum((t_r // dt).astype(np.int64), n - 1)
        w = np.zeros((height, n), dtype=np.float64)
        w[np.arange(height), cell] = 1.0
    w /= w.sum(axis=1, keepdims=True)
    used = w > 0.0
    first = np.argmax(used, axis=0)
    last = height - np.argmax(used[::-1], axis=0)
    rows = np.stack([first, last], axis=1).astype(np.int64)
    rows[~used.any(axis=0)] = 0  # a cell no row reaches (cannot happen for n <= span)
    return ShutterPlan(instants, w.astype(np.float32), rows, round(start))


BAND_QUANTUM = 32
"""Band renders are a multiple of this many rows high (few render-target sizes)."""
BAND_MARGIN = 2
"""Extra render rows above and below a band (the edge filter and bilinear taps)."""


def band_rows(lo: float, hi: float, height: int) -> tuple[int, int]:
    """Render rows ``[a, b)`` covering rows ``lo..hi`` (inclusive, fractional) of a
    ``height``-row render, with :data:`BAND_MARGIN` and quantized to
    :data:`BAND_QUANTUM` rows."""
    a = max(math.floor(lo) - BAND_MARGIN, 0)
    b = min(math.ceil(hi) + 1 + BAND_MARGIN, height)
    h = min(-(-(b - a) // BAND_QUANTUM) * BAND_QUANTUM, height)
    a = max(min(a, height - h), 0)
    return a, a + h


class RollingShutterKeys(StrictModel):
    """``readout_time`` of frame, stereo and depth cameras."""

    readout_time: Annotated[FiniteFloat, Field(ge=0)] = 0.0
    """Rolling shutter: time (s) from the first row's exposure start to the last row's
    (0: global shutter). Row ``r`` starts ``r * readout_time / H`` after row 0."""

    def _check_readout(self, rate: float) -> None:
        period = 1.0 / rate
        if self.readout_time >= period:
            msg = (
                f"readout_time = {self.readout_time}: must be shorter than the frame period "
                f"1 / rate = {period:.6g} s"
            )
            raise ValueError(msg)


@dataclass(frozen=True)
class Band:
    """One render of a rolling-shutter frame, before the lens remap (:func:`add_band`).

    Attributes:
        k: the render's index in the :class:`ShutterPlan`.
        r0, r1: the output rows ``[r0, r1)`` it serves.
        a: the first row of the virtual pinhole view that ``img`` holds.
        img: (rows, W) luminance or (rows, W, 3) linear RGB of the virtual view.
    """

    k: int
    r0: int
    r1: int
    a: int
    img: F32


def band_extents(plan: RenderPlan, shutter: ShutterPlan) -> list[tuple[int, int, int, int, int]]:
    """``(k, r0, r1, a, b)`` of every render that serves a row: output rows ``[r0, r1)``
    from rows ``[a, b)`` of the virtual pinhole view (:func:`band_rows`)."""
    out = []
    for k in range(shutter.instants_ns.shape[0]):
        r0, r1 = (int(v) for v in shutter.rows[k])
        if r1 <= r0:
            continue
        if plan.identity:
            a, b = band_rows(r0, r1 - 1, plan.height)
        else:
            ys = plan.mapy[r0:r1]
            a, b = band_rows(float(ys.min()), float(ys.max()), plan.height)
        out.append((k, r0, r1, a, b))
    return out


def render_bands(
    renderer: FrameRenderer,
    plan: RenderPlan,
    T_world_optical: F64,
    shutter: ShutterPlan,
    mono: bool,
    near: float,
    supersampling: int = 1,
    samples: int | None = None,
) -> Iterator[Band]:
    """The renders of a rolling-shutter frame, one :class:`Band` each, in plan order:
    render ``k`` (optical pose ``T_world_optical[k]``) covers only the rows it serves, as
    a band of the virtual pinhole view (principal point moved up by the band's first
    row), with ``samples`` MSAA samples per pixel (None: the renderer's). Only these
    renders touch the renderer; each array is fresh."""
    for k, r0, r1, a, b in band_extents(plan, shutter):
        K = plan.K.copy()
        K[1, 2] -= a
        res = renderer.render(
            T_world_optical[k],
            K,
            plan.width,
            b - a,
            color=not mono,
            depth=False,
            luminance=mono,
            samples=samples,
            near=near,
            supersampling=supersampling,
            t=float(shutter.instants_ns[k]) * 1e-9,
        )
        img = res.luminance if mono else res.color
        assert img is not None
        yield Band(k, r0, r1, a, img)


def add_band(plan: RenderPlan, shutter: ShutterPlan, band: Band, out: F32, mono: bool) -> None:
    """Add ``band``, remapped through the lens maps, with its row weights to ``out``
    ((H, W) luminance or (H, W, 3) linear RGB at the output size)."""
    assert shutter.weights is not None
    r0, r1, a = band.r0, band.r1, band.a
    img = np.asarray(remap_view(plan, band.img, rows=(r0, r1), first_row=a), dtype=np.float32)
    w = shutter.weights[r0:r1, band.k]
    out[r0:r1] += img * (w[:, None] if mono else w[:, None, None])


def compose_bands(
    plan: RenderPlan, shutter: ShutterPlan, bands: Iterable[Band], out: F32, mono: bool
) -> F32:
    """A rolling-shutter frame from its renders (:func:`render_bands`) into ``out``."""
    out.fill(0.0)
    for band in bands:
        add_band(plan, shutter, band, out, mono)
    return out


def render_rolling(
    renderer: FrameRenderer,
    plan: RenderPlan,
    T_world_optical: F64,
    shutter: ShutterPlan,
    out: F32,
    mono: bool,
    near: float,
    supersampling: int = 1,
    samples: int | None = None,
) -> F32:
    """A rolling-shutter frame into ``out`` ((H, W) luminance or (H, W, 3) linear RGB at
    the output size): each render of :func:`render_bands` (``samples``: their MSAA
    samples, None: the renderer's) remapped and added with its row weights as soon as it
    is drawn (one band in memory at a time)."""
    assert shutter.weights is not None
    bands = render_bands(
        renderer, plan, T_world_optical, shutter, mono, near, supersampling, samples
    )
    return compose_bands(plan, shutter, bands, out, mono)
