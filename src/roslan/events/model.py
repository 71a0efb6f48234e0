"""ESIM-class per-pixel event generation with v2e-style non-idealities.

The model, per pixel, between two samples ``(t0, S0)`` and ``(t1, S1)`` of the signal

    S(t) = LP[log(eps + I)](t) + leak_rate * C+ * t

(``LP`` the optional photoreceptor low-pass, the leak a slow drift of the memorised
reference expressed as a drift of the signal) which is linear in between:

* the memorised reference ``ref`` emits ``n+ = max k: ref + k*C+ <= S1`` ON events at the
  levels ``ref + k*C+`` (k = 1..n+) or ``n- = max k: ref - k*C- >= S1`` OFF events; each at
  the instant the linear signal crosses its level: ``t0 + (level - S0) / (S1 - S0) * (t1 - t0)``
  (rounded to integer ns, clipped to ``[t0, t1]``), and ``ref`` moves to the last level;
* the refractory period drops an event closer than ``refractory`` to the pixel's last
  *emitted* event, but the reference still advances (ESIM);
* thresholds ``C+``/``C-`` carry a per-pixel mismatch fixed at construction;
* shot noise (v2e's form, evaluated at ``I`` rather than v2e's ``(DN + 20) / 275``):
  Poisson events at uniform random instants, ON and OFF each at
  ``shot_noise_rate / 2 * (1 - (1 - f) * clip(I, 0, 1)) * C_nominal / C`` Hz per pixel (``I``
  the photoreceptor's linear intensity, ``f = shot_noise_intensity_factor``: dark pixels
  are the noisiest; a pixel with a low threshold fires more); an event sets the reference
  to the present signal (no follow-up event undoes it);
* the leak's initial phase (``leak_phase``): ``steady`` starts every reference a uniform
  random fraction of ``C+`` below the signal (the leak's steady state, as if the sensor had
  been running; roslan's choice), ``zero`` at the signal (a global reset at t = 0: no leak
  event before ``1 / leak_rate``; what v2e does).

docs/event-model.md gives the equations, the defaults, the sources and the tests that
measure each of them.

:class:`EventGenerator` runs the per-pixel update as numba kernels (``_kernels``: one fused
pass over the pixels, then one over the few pixels that cross a level, then one over those
that cross several) with ``log``/``exp`` in NumPy, in the frame's precision (float32 for
the renderer's float32 frames: :func:`log_intensity`); one sort of packed integer keys
orders the interval's events.
:class:`roslan.events.reference.NumpyEventGenerator` is the same model in NumPy array
passes: the kernels' bit-exact reference and the benchmark's baseline.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from types import ModuleType

__all__ = [
    "EMPTY_EVENTS",
    "EVENT_PRESETS",
    "EventBatch",
    "EventGenerator",
    "EventModelParams",
    "log_intensity",
]

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

EMPTY_EVENTS: tuple[I64, I64, NDArray[np.int8]] = (
    np.zeros(0, np.int64),
    np.zeros(0, np.int64),
    np.zeros(0, np.int8),
)

_NO_LEAK: F64 = np.zeros(0)

MIN_THRESHOLD = 0.01
"""Smallest contrast threshold a mismatched pixel may get (log units)."""

LEAK_PHASES = ("steady", "zero")
"""Initial phases of the leak (:attr:`EventModelParams.leak_phase`)."""


@dataclass(frozen=True, slots=True)
class EventModelParams:
    """Parameters of the pixel model.

    Attributes:
        threshold_pos, threshold_neg: nominal contrast thresholds C+ / C- (log intensity).
        threshold_sigma: std of the fixed per-pixel threshold mismatch (log intensity).
        refractory: refractory period, s (0: none).
        cutoff_hz: photoreceptor low-pass 3 dB cutoff, Hz (0: no filter).
        intensity_dependent: scale the low-pass bandwidth with pixel intensity (v2e).
        leak_rate: leak events per pixel, Hz (ON events of a static scene).
        leak_jitter: relative per-pixel std of the leak rate.
        shot_noise_rate: shot-noise events per pixel, Hz (both polarities together) of a
            pixel at zero intensity and nominal thresholds (v2e's ``shot_noise_rate_hz``,
            which v2e evaluates at ``(DN + 20) / 275``: its darkest pixel fires at 0.9455 of
            it, roslan's black pixel at all of it; docs/event-model.md).
        shot_noise_intensity_factor: the shot-noise rate of a pixel at intensity 1 relative
            to one at 0 (linear in between; v2e's 0.25).
        shot_noise_knee: 0 for v2e's linear intensity dependence above; > 0 for
            ``shot_noise_rate / (1 + I / shot_noise_knee)`` instead (the rate halves at
            ``I = shot_noise_knee``): the steep fall with light of a real DAVIS346
            (docs/realism.md); ``shot_noise_intensity_factor`` is then unused.
        leak_phase: ``steady`` (references start a uniform random fraction of ``C+`` below
            the signal) or ``zero`` (at the signal).
        log_eps: eps of ``L = log(eps + I)``, I linear luminance in [0, 1].
    """

    threshold_pos: float = 0.2
    threshold_neg: float = 0.2
    threshold_sigma: float = 0.0
    refractory: float = 0.0
    cutoff_hz: float = 0.0
    intensity_dependent: bool = False
    leak_rate: float = 0.0
    leak_jitter: float = 0.1
    shot_noise_rate: float = 0.0
    shot_noise_intensity_factor: float = 0.25
    shot_noise_knee: float = 0.0
    leak_phase: str = "steady"
    log_eps: float = 1e-3

    def __post_init__(self) -> None:
        if self.leak_phase not in LEAK_PHASES:
            msg = f"leak_phase = {self.leak_phase!r}: allowed {', '.join(LEAK_PHASES)}"
            raise ValueError(msg)

    def with_overrides(self, **kw: float | bool | str | None) -> EventModelParams:
        """A copy with every non-None keyword replaced."""
        return replace(self, **{k: v for k, v in kw.items() if v is not None})  # type: ignore[arg-type]


EVENT_PRESETS: dict[str, EventModelParams] = {
    # the ideal ESIM pixel
    "clean": EventModelParams(),
    # v2e-like defaults: mismatch, 0.5 ms refractory, 300 Hz photoreceptor, some noise
    "realistic": EventModelParams(
        threshold_pos=0.2,
        threshold_neg=0.2,
        threshold_sigma=0.03,
        refractory=5e-4,
        cutoff_hz=300.0,
        intensity_dependent=True,
        leak_rate=0.1,
        leak_jitter=0.1,
        shot_noise_rate=0.2,
    ),
}


class EventBatch(NamedTuple):
    """Events sorted by time: ``t`` (N,) int64 ns, ``x``, ``y`` (N,) uint16 pixel column/row
    (row 0 = top), ``p`` (N,) int8 polarity (1 ON, 0 OFF)."""

    t: I64
    x: NDArray[np.uint16]
    y: NDArray[np.uint16]
    p: NDArray[np.int8]

    @property
    def size(self) -> int:
        """Number of events."""
        return int(self.t.shape[0])

    @staticmethod
    def empty() -> EventBatch:
        return EventBatch(
            np.zeros(0, np.int64),
            np.zeros(0, np.uint16),
            np.zeros(0, np.uint16),
            np.zeros(0, np.int8),
        )

    @staticmethod
    def concatenate(batches: list[EventBatch]) -> EventBatch:
        if not batches:
            return EventBatch.empty()
        if len(batches) == 1:
            return batches[0]
        return EventBatch(
            np.concatenate([b.t for b in batches]),
            np.concatenate([b.x for b in batches]),
            np.concatenate([b.y for b in batches]),
            np.concatenate([b.p for b in batches]),
        )

    def slice(self, a: int, b: int) -> EventBatch:
        return EventBatch(self.t[a:b], self.x[a:b], self.y[a:b], self.p[a:b])


def log_intensity(intensity: NDArray[np.floating], eps: float) -> F64:
    """``log(eps + I)`` as float64, I (H, W) linear luminance (negative values clipped to 0).

    Evaluated in the frame's precision: float32 for a float32 frame (the renderer's; the
    log's error, <= 1 ulp of |L| < 8, i.e. <= 4.8e-7, is 2.4e-6 of a 0.2 contrast threshold
    and of the order of the frame's own rounding), float64 for any other dtype.
    """
    a = np.asarray(intensity)
    if a.dtype == np.float32:
        return np.log(np.maximum(a, np.float32(0.0)) + np.float32(eps)).astype(np.float64)
    return np.log(eps + np.maximum(a.astype(np.float64, copy=False), 0.0))


@functools.cache
def _kernels() -> ModuleType:
    """The numba kernels, imported (and compiled or loaded from numba's cache) on first use."""
    from roslan.events import _kernels as k

    return k


def _kernel_input(a: NDArray[Any]) -> NDArray[np.floating]:
    """(H*W,) intensity as a contiguous float32 or float64 array for the kernels (the
    precision of ``log``/``exp``: see :func:`log_intensity`)."""
    if a.dtype != np.float32 and a.dtype != np.float64:
        a = a.astype(np.float64)
    return np.ascontiguousarray(a)


class EventGenerator:
    """Stateful per-pixel event generator for an ``height x width`` sensor.

    Feed it linear-luminance frames in increasing time with :meth:`update`; the first
    call initialises the pixels and returns no events.

    Args:
        width, height: sensor size, px.
        params: the pixel model.
        rng: random stream (threshold mismatch, leak rates and phases, shot noise).
    """

    def __init__(
        self, width: int, height: int, params: EventModelParams, rng: np.random.Generator
    ) -> None:
        self.width = int(width)
        self.height = int(height)
        self.params = params
        n = self.width * self.height
        self.n_pixels = n
        p = params
        # Draw every per-pixel quantity once, in a fixed order (determinism).
        noise = rng.standard_normal((2, n))
        self.c_pos: F64 = np.maximum(p.threshold_pos + p.threshold_sigma * noise[0], MIN_THRESHOLD)
        self.c_neg: F64 = np.maximum(p.threshold_neg + p.threshold_sigma * noise[1], MIN_THRESHOLD)
        jitter = rng.standard_normal(n)
        phase = rng.random(n)
        if p.leak_rate > 0:
            rate = np.maximum(p.leak_rate * (1.0 + p.leak_jitter * jitter), 0.0)
            self.leak_slope: F64 | None = rate * self.c_pos  # log units per second
            # desynchronises the pixels' leak: its steady state from t = 0
            steady = p.leak_phase == "steady"
            self._leak_phase: F64 = phase * self.c_pos if steady else np.zeros(n)
        else:
            self.leak_slope = None
            self._leak_phase = np.zeros(n)
        # shot noise: per-pixel rate factors of the threshold (nominal / actual), and their
        # maximum, the bound of the thinning
        self._shot_on: F64 = p.threshold_pos / self.c_pos
        self._shot_off: F64 = p.threshold_neg / self.c_neg
        self._shot_max = float(max(self._shot_on.max(), self._shot_off.max())) if n else 1.0
        self._rng = rng
        self._refractory_ns = round(p.refractory * 1e9)
        self.ref: F64 = np.zeros(n)
        self.signal: F64 = np.zeros(n)  # S at the last sample
        self.lp: F64 = np.zeros(n)  # low-passed log intensity at the last sample
        self.last_event_ns: I64 = np.full(n, np.iinfo(np.int64).min // 2, dtype=np.int64)
        self.t_ns: int | None = None
        self.n_dropped = 0
        # reused (H*W,) log / exp buffers per precision (float32 frames: float32)
        self._bufs: dict[np.dtype[Any], tuple[NDArray[np.floating], NDArray[np.floating]]] = {}

    def _frame(self, intensity: NDArray[np.floating]) -> NDArray[np.floating]:
        """``intensity`` as an array, checked against the sensor's (H, W)."""
        img = np.asarray(intensity)
        if img.shape != (self.height, self.width):
            msg = f"frame shape {img.shape} != sensor ({self.height}, {self.width})"
            raise ValueError(msg)
        return img

    # ------------------------------------------------------------------ API
    def update(self, intensity: NDArray[np.floating], t_ns: int) -> EventBatch:
        """Advance to the frame ``intensity`` (H, W) linear luminance at ``t_ns``.

        Returns the events of the interval (times in ``[t_prev, t_ns]``), sorted by time,
        ties by pixel index (then real events before shot noise).
        """
        img = self._frame(intensity)
        if self.t_ns is None:
            L = log_intensity(img, self.params.log_eps).ravel()
            return self.update_log(L, t_ns, intensity=img.ravel())
        flat = _kernel_input(img.ravel())
        want_exp = self._mode(flat) == 2
        s = self._exp_scale(int(t_ns)) if want_exp else 0.0
        lbuf, ebuf = self._buffers(flat.dtype)
        eps = flat.dtype.type(self.params.log_eps)  # float32 arithmetic for float32 frames
        _kernels().log_exp_args(flat, eps, s, lbuf, ebuf, True, want_exp)
        np.log(lbuf, out=lbuf)
        return self._step(lbuf, flat, int(t_ns), ebuf)

    def _start(self, L: F64, t_ns: int) -> None:
        """The first frame: the pixels' state (low-pass, signal, reference) starts at it."""
        self.lp = L.astype(np.float64, copy=True)
        self.signal = self._signal(self.lp, t_ns)
        self.ref = self.signal - self._leak_phase
        self.t_ns = t_ns

    def update_log(
        self, L: F64, t_ns: int, *, intensity: NDArray[np.floating] | None = None
    ) -> EventBatch:
        """As :meth:`update` with the log intensity ``L`` (H*W,) float64 given directly.

        ``intensity`` (H*W,) is only needed by the intensity-dependent low-pass.
        """
        t_ns = int(t_ns)
        if self.t_ns is None:
            self._start(L, t_ns)
            self._cand = np.empty(self.n_pixels, np.int64)
            self._flag = np.empty(self.n_pixels, np.uint8)
            self._dense = False
            self._sig_next = np.empty(self.n_pixels)  # the signal is double-buffered
            self._idx = self._t = self._key = np.empty(0, np.int64)
            self._p = np.empty(0, np.int8)
            return EventBatch.empty()
        flat = None if intensity is None else _kernel_input(np.asarray(intensity).ravel())
        ebuf = self._buffers(np.dtype(np.float64))[1]
        if flat is not None and self._mode(flat) == 2:
            s = self._exp_scale(t_ns)
            lbuf, ebuf = self._buffers(flat.dtype)
            _kernels().log_exp_args(flat, 0.0, s, lbuf, ebuf, False, True)
        return self._step(np.ascontiguousarray(L, dtype=np.float64), flat, t_ns, ebuf)

    # ------------------------------------------------------------------ internals
    def _buffers(self, dtype: np.dtype[Any]) -> tuple[NDArray[np.floating], NDArray[np.floating]]:
        """Reused (H*W,) buffers of the log and exp arguments (then values) in ``dtype``."""
        b = self._bufs.get(dtype)
        if b is None:
            b = self._bufs[dtype] = (np.empty(self.n_pixels, dtype), np.empty(self.n_pixels, dtype))
        return b

    def _mode(self, intensity: NDArray[np.floating] | None) -> int:
        """Low-pass mode of the kernel: 0 none, 1 fixed bandwidth, 2 intensity-dependent."""
        p = self.params
        if p.cutoff_hz <= 0:
            return 0
        return 2 if (p.intensity_dependent and intensity is not None) else 1

    def _exp_scale(self, t_ns: int) -> float:
        """``-dt / tau`` of the intensity-dependent low-pass (raises on a non-increasing t)."""
        tau = 1.0 / (2.0 * math.pi * self.params.cutoff_hz)
        return -self._dt(t_ns) * 1e-9 / tau

    def _dt(self, t_ns: int) -> int:
        t0 = self.t_ns
        assert t0 is not None
        if t_ns <= t0:
            msg = f"frame time {t_ns} ns must be after the previous frame ({t0} ns)"
            raise ValueError(msg)
        return t_ns - t0

    def _step(
        self,
        L: NDArray[np.floating],
        intensity: NDArray[np.floating] | None,
        t_ns: int,
        E: NDArray[np.floating],
    ) -> EventBatch:
        """One interval with the kernels: ``L`` (H*W,) log intensity (float32 or float64,
        upcast exactly), ``E`` (H*W,) the exp argument of the intensity-dependent low-pass
        (mode 2; exponentiated here in place, in its own precision)."""
        p = self.params
        k = _kernels()
        t0 = self.t_ns
        assert t0 is not None
        dt_ns = self._dt(t_ns)
        mode = self._mode(intensity)
        a = 0.0
        if mode == 2:
            np.exp(E, out=E)
        elif mode == 1:
            tau = 1.0 / (2.0 * math.pi * p.cutoff_hz)
            a = 1.0 - math.exp(-dt_ns * 1e-9 / tau)  # exact first-order step
        leak = self.leak_slope if self.leak_slope is not None else _NO_LEAK
        lp0 = self.lp.copy() if self.flag_noise else None
        s0, s1 = self.signal, self._sig_next
        k.pixel_step(
            L, E, mode, a, self.lp, leak, t_ns * 1e-9, self.ref, self.c_pos,
            self.c_neg, s1, self._flag,
        )  # fmt: skip
        # the last interval's candidate density picks the compaction (same result)
        m = k.compact(self._flag, self._cand, self._dense)
        self._dense = 32 * m > self.n_pixels
        # first crossings (one per candidate; dropped ones kept as p = -1), then the
        # pixels with more, resumed in grown buffers when full
        idx, t, pol = self._scratch(m)
        args = (s0, s1, self.ref, self.c_pos, self.c_neg, self.last_event_ns, t0, dt_ns)
        mm, n, dropped = k.emit_first(self._cand, m, *args, self._refractory_ns, idx, t, pol, 0)
        j = 0
        while True:
            idx, t, pol = self._scratch(n, keep=n)
            j, n, d = k.emit_more(self._cand, j, mm, *args, self._refractory_ns, idx, t, pol, n)
            dropped += d
            if j == mm:
                break
            self._scratch(2 * idx.shape[0] + 1024, keep=n)  # full: grow and go on
        self.n_dropped += int(dropped)
        n_real = int(n)
        shot_ties = False
        if p.shot_noise_rate > 0:
            # shot noise (drawn after the crossings moved ``ref``) placed after them
            draws = self._shot_draws(dt_ns)
            if draws is not None:
                sidx, traw, u, v = draws
                idx, t, pol = self._scratch(n + sidx.shape[0], keep=n)
                expl = np.exp(self.lp[sidx])  # NumPy's exp, as the reference's
                n, shot_ties = k.shot_noise(
                    sidx, traw, u, v, expl, p.log_eps, p.shot_noise_intensity_factor,
                    p.shot_noise_knee, self._shot_max, self._shot_on, self._shot_off, s1, self.ref,
                    self.last_event_ns, t0, idx, t, pol, n,
                )  # fmt: skip
                # two shot events of one pixel at one ns (practically never): keys would tie
                shot_ties = bool(shot_ties)
        self.signal, self._sig_next = s1, s0
        self.t_ns = t_ns
        n_out = n - int(dropped)
        self.last_noise = np.zeros(0, dtype=bool)
        if n_out == 0:
            return EventBatch.empty()
        idx, t, pol = idx[:n], t[:n], pol[:n]
        out = EventBatch(
            np.empty(n_out, np.int64), np.empty(n_out, np.uint16), np.empty(n_out, np.uint16),
            np.empty(n_out, np.int8),
        )  # fmt: skip
        # (outputs are NumPy's allocations: numba's own page-fault on every call)
        ib = max(self.n_pixels - 1, 1).bit_length()
        if not shot_ties and (dt_ns + 1) << (ib + 2) < 2**62:
            # the sorted keys hold the events themselves (no gather); dropped ones sort last
            key = self._key[:n]
            k.pack_keys(t, idx, pol, n_real, t0, ib, key)
            shot_keys = np.sort(key[n_real:]) if lp0 is not None else None
            key.sort()
            k.unpack_keys(key[:n_out], t0, ib, self.width, *out)
            if lp0 is not None and shot_keys is not None:
                shot = np.isin(key[:n_out], shot_keys, assume_unique=False)
                self.last_noise = self._noise(out, shot, lp0)
            return out
        # the reference's stable time order: real events by pixel (then identical), shot
        # noise by position (sorted by pixel, ties in draw order)
        kept = np.flatnonzero(pol >= 0)
        pos = np.arange(n)
        shot_ev = pos >= n_real
        order = kept[np.lexsort((np.where(shot_ev, pos, idx)[kept], shot_ev[kept], t[kept]))]
        k.gather_events(order, idx, t, pol, self.width, *out)
        if lp0 is not None:
            self.last_noise = self._noise(out, shot_ev[order], lp0)
        return out

    def _noise(self, out: EventBatch, shot: NDArray[np.bool_], lp0: F64) -> NDArray[np.bool_]:
        """Which events of ``out`` are noise: shot noise (``shot``) and leak events, i.e.
        crossings whose pixel's low-passed log intensity did not move in the direction
        of their polarity over the interval (the leak's drift alone crossed the
        threshold)."""
        pix = out.y.astype(np.int64) * self.width + out.x
        d = self.lp[pix] - lp0[pix]
        leak = np.where(out.p > 0, d <= 0.0, d >= 0.0)
        return np.asarray(shot | leak, dtype=bool)

    flag_noise: bool = False
    """Compute :attr:`last_noise` at every step (the event camera's labels)."""
    last_noise: NDArray[np.bool_] = np.zeros(0, dtype=bool)
    """After a step with :attr:`flag_noise`: which of its events are noise (shot noise,
    leak events; :meth:`_noise`), aligned with the returned batch."""

    def _scratch(self, n: int, keep: int = 0) -> tuple[I64, I64, NDArray[np.int8]]:
        """Reused event buffers of at least ``n`` events (grown by doubling, the first
        ``keep`` events copied over)."""
        if self._idx.shape[0] < n:
            cap = max(n, 2 * self._idx.shape[0])
            idx, t, p = np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty(cap, np.int8)
            idx[:keep], t[:keep], p[:keep] = self._idx[:keep], self._t[:keep], self._p[:keep]
            self._idx, self._t, self._p = idx, t, p
            self._key = np.empty(cap, np.int64)
        return self._idx, self._t, self._p

    def _signal(self, lp: F64, t_ns: int) -> F64:
        if self.leak_slope is None:
            return lp.copy() if lp.dtype == np.float64 else lp.astype(np.float64)
        return lp + self.leak_slope * (t_ns * 1e-9)

    def _shot_draws(self, dt_ns: int) -> tuple[I64, I64, F64, F64] | None:
        """The interval's shot-noise candidates: pixels, times after ``t0`` (ns), polarity
        and acceptance uniforms; None when there are none."""
        rng = self._rng
        lam = self.params.shot_noise_rate * self._shot_max * self.n_pixels * dt_ns * 1e-9
        m = int(rng.poisson(lam))
        if m == 0:
            return None
        idx = rng.integers(0, self.n_pixels, m)
        traw = rng.integers(0, dt_ns, m)
        return idx, traw, rng.random(m), rng.random(m)

    def _shot_noise(self, t0: int, dt_ns: int, s1: F64) -> tuple[I64, I64, NDArray[np.int8]]:
        """The interval's shot-noise events (pixel-sorted, ties in draw order), each setting
        its pixel's reference to the present signal ``s1`` (v2e: no follow-up event).

        Thinning of a Poisson process: candidates at the bound rate ``shot_noise_rate *
        max(C_nominal / C)`` per pixel (uniform pixel, instant in ``(t0, t1]``, polarity),
        each kept with probability ``g(I) * (C_nominal / C) / max(C_nominal / C)``, ``g(I) =
        1 - (1 - f) * clip(I, 0, 1)`` (or ``1 / (1 + clip(I, 0, 1) / knee)`` with a knee)
        (``I = exp(lp) - eps``, the photoreceptor's present linear
        intensity): ON and OFF events at ``rate / 2 * (1 - (1 - f) I) * C_nominal / C``.
        """
        p = self.params
        draws = self._shot_draws(dt_ns)
        if draws is None:
            return EMPTY_EVENTS
        idx, traw, u, v = draws
        t = t0 + 1 + traw  # in (t0, t1]
        on = u < 0.5
        inten = np.clip(np.exp(self.lp[idx]) - p.log_eps, 0.0, 1.0)
        if p.shot_noise_knee > 0:
            g = 1.0 / (1.0 + inten / p.shot_noise_knee)
        else:
            g = 1.0 - (1.0 - p.shot_noise_intensity_factor) * inten
        ratio = np.where(on, self._shot_on[idx], self._shot_off[idx])
        keep = v * self._shot_max < g * ratio
        order = np.argsort(idx[keep], kind="stable")
        idx, t, pol = idx[keep][order], t[keep][order], on[keep][order].astype(np.int8)
        self.ref[idx] = s1[idx]
        np.maximum.at(self.last_event_ns, idx, t)
        return idx, t, pol
