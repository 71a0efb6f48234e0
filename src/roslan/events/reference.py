"""The event model of :mod:`roslan.events.model` in plain NumPy array passes.

:class:`NumpyEventGenerator` expands multi-crossings with ``np.repeat``/``cumsum`` and
filters refractory events iterating over the crossing index: the numba kernels' bit-exact
reference (the tests compare them) and the benchmark's baseline.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from roslan.events.model import EMPTY_EVENTS, F64, I64, EventBatch, EventGenerator, log_intensity

__all__ = ["NumpyEventGenerator"]


class NumpyEventGenerator(EventGenerator):
    """The same model in plain NumPy array passes (the kernels' reference, and the
    benchmark's baseline): bit-identical events, several times slower."""

    def update(self, intensity: NDArray[np.floating], t_ns: int) -> EventBatch:
        """Advance to the frame ``intensity`` (H, W) linear luminance at ``t_ns``.

        Returns the events of the interval (times in ``[t_prev, t_ns]``), sorted by time,
        ties by pixel index (then real events before shot noise).
        """
        img = self._frame(intensity)
        L = log_intensity(img, self.params.log_eps).ravel()
        return self.update_log(L, t_ns, intensity=img.ravel())

    def update_log(
        self, L: F64, t_ns: int, *, intensity: NDArray[np.floating] | None = None
    ) -> EventBatch:
        """As :meth:`update` with the log intensity ``L`` (H*W,) float64 given directly.

        ``intensity`` (H*W,) is only needed by the intensity-dependent low-pass.
        """
        p = self.params
        t_ns = int(t_ns)
        if self.t_ns is None:
            self._start(L, t_ns)
            return EventBatch.empty()
        t0 = self.t_ns
        if t_ns <= t0:
            msg = f"frame time {t_ns} ns must be after the previous frame ({t0} ns)"
            raise ValueError(msg)
        dt_ns = t_ns - t0
        if p.cutoff_hz > 0:
            tau = 1.0 / (2.0 * math.pi * p.cutoff_hz)
            a = 1.0 - math.exp(-dt_ns * 1e-9 / tau)  # exact first-order step
            if p.intensity_dependent and intensity is not None:
                # v2e: dim pixels have a slower photoreceptor (bandwidth ~ photocurrent)
                inten = np.asarray(intensity)
                arg = -dt_ns * 1e-9 / tau * (np.clip(inten.astype(np.float64), 0.0, 1.0) + 0.08)
                arg /= 1.08
                if inten.dtype == np.float32:
                    # exp in the frame's precision (as log_intensity): rel. error ~1e-7
                    a_pix = 1.0 - np.exp(arg.astype(np.float32)).astype(np.float64)
                else:
                    a_pix = 1.0 - np.exp(arg)
                self.lp = self.lp + a_pix * (L - self.lp)
            else:
                self.lp = self.lp + a * (L - self.lp)
        else:
            self.lp = L
        S1 = self._signal(self.lp, t_ns)
        parts = [self._crossings(self.signal, S1, t0, dt_ns)]
        if p.shot_noise_rate > 0:
            parts.append(self._shot_noise(t0, dt_ns, S1))
        self.signal = S1
        self.t_ns = t_ns
        return self._sorted(parts, t0, dt_ns)

    def _sorted(
        self, parts: list[tuple[I64, I64, NDArray[np.int8]]], t0: int, dt_ns: int
    ) -> EventBatch:
        """One time sort of the interval's events; ties keep their order in ``parts``."""
        idx = np.concatenate([q[0] for q in parts])
        t = np.concatenate([q[1] for q in parts])
        pol = np.concatenate([q[2] for q in parts])
        n = int(t.shape[0])
        if n == 0:
            return EventBatch.empty()
        if (dt_ns + 1) * n < 2**62:
            # unique keys (time, position): an unstable sort of values is the stable order
            key = (t - t0) * n + np.arange(n, dtype=np.int64)
            key.sort()
            order = key % n
        else:  # pragma: no cover - intervals of years
            order = np.argsort(t, kind="stable")
        idx, t, pol = idx[order], t[order], pol[order]
        return EventBatch(
            t, (idx % self.width).astype(np.uint16), (idx // self.width).astype(np.uint16), pol
        )

    def _crossings(
        self, S0: F64, S1: F64, t0: int, dt_ns: int
    ) -> tuple[I64, I64, NDArray[np.int8]]:
        """Unsorted (pixel-major) events: flat pixel index, time ns, polarity."""
        ref = self.ref
        # only pixels whose first level is reached do any further work (usually few)
        pix = np.flatnonzero((ref + self.c_pos <= S1) | (ref - self.c_neg >= S1))
        if pix.size == 0:
            return EMPTY_EVENTS
        r, s1 = ref[pix], S1[pix]
        up_p = s1 > r
        Cp = np.where(up_p, self.c_pos[pix], self.c_neg[pix])
        sg = np.where(up_p, 1.0, -1.0)
        cnt = np.floor(np.abs(s1 - r) / Cp).astype(np.int64)
        # make the count agree exactly with the definition (level r +- n*C reached, n+1 not)
        cnt -= (cnt > 1) & ((r + sg * (cnt * Cp) - s1) * sg > 0)
        cnt = np.maximum(cnt, 1)
        cnt += (r + sg * ((cnt + 1) * Cp) - s1) * sg <= 0
        total = int(cnt.sum())
        rep = np.repeat(np.arange(pix.size), cnt)  # candidate of each crossing
        idx = pix[rep]
        starts = np.cumsum(cnt) - cnt
        k = np.arange(total, dtype=np.int64) - starts[rep] + 1
        level = r[rep] + sg[rep] * (k * Cp[rep])
        # the reference moves to the last level crossed (dropped events included)
        ref[pix] = r + sg * (cnt * Cp)
        s0 = S0[idx]
        ds = s1[rep] - s0
        with np.errstate(divide="ignore", invalid="ignore"):
            frac = np.where(ds != 0, (level - s0) / ds, 1.0)
        frac = np.clip(frac, 0.0, 1.0)
        t = t0 + np.rint(frac * dt_ns).astype(np.int64)
        pol = up_p[rep].astype(np.int8)
        if self._refractory_ns > 0:
            keep = self._refractory(pix, cnt, starts, t)
            idx, t, pol = idx[keep], t[keep], pol[keep]
        else:
            # last event of each pixel (they are in time order within a pixel)
            self.last_event_ns[pix] = t[starts + cnt - 1]
        return idx, t, pol

    def _refractory(self, pix: I64, cnt: I64, starts: I64, t: I64) -> NDArray[np.bool_]:
        """Keep mask over the pixel-major crossings; iterates over the crossing index only."""
        keep = np.zeros(t.shape[0], dtype=bool)
        R = self._refractory_ns
        last = self.last_event_ns[pix]
        for k in range(int(cnt.max())):
            active = np.flatnonzero(cnt > k)
            j = starts[active] + k
            tk = t[j]
            ok = tk - last[active] >= R
            keep[j[ok]] = True
            last[active[ok]] = tk[ok]
        self.last_event_ns[pix] = last
        self.n_dropped += int(keep.size - keep.sum())
        return keep
