"""Background-noise fit of an event recording: the event-camera keys (``leak_rate``,
``shot_noise_rate``, ``shot_noise_knee``) that reproduce the events of its static pixels.

The model fitted is roslan's (:mod:`roslan.events.model`): per static pixel at linear
intensity ``I`` (its mean APS level / 255),

    OFF rate = S(I) / 2,   ON rate = leak + S(I) / 2,   S(I) = R / (1 + I / I_k)

(shot noise ``S``, both polarities alike; the leak ON only). The leak events are the ON
excess ``N_on - N_off``; since every event resets the pixel's leak clock, the leak rate
reported is the one that yields that excess among the fitted shot events
(:func:`_leak_rate`); ``R`` and the knee ``I_k`` are the Poisson maximum likelihood of
the OFF counts (closed form in ``R`` for each ``I_k``, a bounded 1-D search in ``log I_k``).
Without intensities (a quiet span of a file with no APS frames) the shot noise is taken as
intensity-independent (``shot_noise_intensity_factor: 1``). Hot pixels (counts a Poisson
variable at the fitted pixel rate reaches with probability below ``1e-3 / n``) are
counted, reported and left out of the fit. docs/realism.md shows it on a real DAVIS346.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage, optimize, special

from roslan.errors import RecordingError
from roslan.events.recording import Recording

__all__ = ["DN_BINS", "LevelBin", "NoiseFit", "fit_noise", "fit_static_counts", "static_mask"]

F64 = NDArray[np.float64]
DN_BINS = (0.0, 60.0, 120.0, 200.0, 256.0)
"""APS-level bin edges (8-bit DN) of the fit's table."""
HOT_P = 1e-3
"""Expected number of normal pixels flagged hot, over the whole array."""
KNEE_RANGE = (1e-4, 10.0)
MOVING_FACTOR = 4.0
"""A pixel whose APS std exceeds this many ``std_max`` is moving (:func:`static_mask`)."""


@dataclass(frozen=True)
class LevelBin:
    """Static pixels whose APS level lies in ``[lo, hi)`` DN: ``pixels``, ``on`` and ``off``
    events, rates per pixel (Hz)."""

    lo: float
    hi: float
    pixels: int
    on: int
    off: int
    duration_s: float

    @property
    def rate(self) -> float:
        return (self.on + self.off) / max(self.pixels, 1) / self.duration_s

    @property
    def on_fraction(self) -> float:
        n = self.on + self.off
        return self.on / n if n else float("nan")


@dataclass(frozen=True)
class NoiseFit:
    """The fitted keys and the figures measured on the static pixels."""

    leak_rate: float
    shot_noise_rate: float
    shot_noise_knee: float
    shot_noise_intensity_factor: float
    source: str
    duration_s: float
    pixels: int
    static_pixels: int
    on: int
    off: int
    hot_pixels: int
    hot_events: int
    bins: tuple[LevelBin, ...] = field(default=())

    @property
    def rate(self) -> float:
        """Background events per static (non-hot) pixel per second."""
        return (self.on + self.off) / max(self.static_pixels, 1) / self.duration_s

    def keys(self) -> dict[str, float]:
        """The event-camera keys (``type: event_camera``) reproducing the background."""
        out = {"leak_rate": self.leak_rate, "shot_noise_rate": self.shot_noise_rate}
        if self.shot_noise_knee > 0:
            out["shot_noise_knee"] = self.shot_noise_knee
        else:
            out["shot_noise_intensity_factor"] = self.shot_noise_intensity_factor
        return out

    def report(self) -> str:
        """YAML: the keys, preceded by the measured figures as comments."""
        n = self.on + self.off
        lines = [
            f"# static pixels: {self.static_pixels} of {self.pixels} ({self.source}), "
            f"{self.duration_s:.3f} s",
            f"# background: {n} events, {self.rate:.4g} events/s per pixel, "
            f"ON fraction {self.on / n if n else float('nan'):.3f}",
            f"# hot pixels (left out of the fit, not modelled): {self.hot_pixels} "
            f"({100 * self.hot_pixels / max(self.pixels, 1):.3f} %), {self.hot_events} events",
        ]
        if self.bins:
            lines.append("# APS level (DN)   pixels   events   rate (Hz)   ON fraction")
            for b in self.bins:
                lines.append(
                    f"# {b.lo:5.0f}-{b.hi:<5.0f}  {b.pixels:9d} {b.on + b.off:8d}   "
                    f"{b.rate:9.4g}   {b.on_fraction:.3f}"
                )
        lines += [f"{k}: {v:.4g}" for k, v in self.keys().items()]
        return "\n".join(lines) + "\n"


def static_mask(
    frames: NDArray[np.uint8], std_max: float = 2.0, margin: int = 3
) -> NDArray[np.bool_]:
    """(H, W) pixels whose APS level varies by less than ``std_max`` DN (std over the
    frames (K, H, W)) and lies more than ``margin`` px from any moving pixel (std over
    ``MOVING_FACTOR * std_max``): the edges of moving things fire before their APS level
    moves, while isolated pixels of larger read noise are no motion."""
    if frames.shape[0] < 2:
        msg = f"{frames.shape[0]} APS frame(s): at least 2 are needed to find static pixels"
        raise RecordingError(msg)
    std = frames.astype(np.float64).std(axis=0)
    still = std < std_max
    if margin > 0:
        near = ndimage.binary_dilation(
            std >= MOVING_FACTOR * std_max, structure=np.ones((2 * margin + 1,) * 2, bool)
        )
        still &= ~near
    return np.asarray(still, dtype=bool)


def _shot_shape(level: F64 | None, knee: float) -> F64 | None:
    return None if level is None else 1.0 / (1.0 + level / knee)


def _fit_shot(off: F64, level: F64 | None, T: float) -> tuple[float, float]:
    """``(R, knee)`` maximising the Poisson likelihood of the OFF counts (knee 0: none)."""
    n_off = float(off.sum())
    if level is None or n_off == 0:
        return 2.0 * n_off / (off.size * T), 0.0

    def nll(log_knee: float) -> float:
        g = 1.0 / (1.0 + level / math.exp(log_knee))
        return -(float(off @ np.log(g)) - n_off * math.log(float(g.sum())))

    lo, hi = (math.log(v) for v in KNEE_RANGE)
    grid = np.linspace(lo, hi, 41)
    best = grid[int(np.argmin([nll(float(v)) for v in grid]))]
    step = grid[1] - grid[0]
    res = optimize.minimize_scalar(
        nll, bounds=(max(lo, best - step), min(hi, best + step)), method="bounded"
    )
    knee = math.exp(float(res.x))
    g = 1.0 / (1.0 + level / knee)
    return 2.0 * n_off / (T * float(g.sum())), knee


def fit_static_counts(
    on: NDArray[np.integer],
    off: NDArray[np.integer],
    duration_s: float,
    level: F64 | None = None,
    *,
    source: str = "",
    pixels: int | None = None,
) -> NoiseFit:
    """Fit the static pixels' ON / OFF counts (n,) over ``duration_s`` s; ``level`` (n,)
    their linear intensities in [0, 1] (APS DN / 255), or None (intensity-independent)."""
    if duration_s <= 0:
        msg = f"duration {duration_s} s: the static span must be longer than 0"
        raise RecordingError(msg)
    if on.size == 0:
        msg = "no static pixels to fit (lower --margin or raise --aps-std, or name a --quiet-span)"
        raise RecordingError(msg)
    on_f, off_f = on.astype(np.float64), off.astype(np.float64)
    keep = np.ones(on.size, bool)
    for _ in range(2):  # fit, flag hot pixels against it, refit without them
        fit = _fit_arrays(
            on_f[keep], off_f[keep], duration_s, None if level is None else level[keep]
        )
        leak, R, knee = fit
        g = np.ones(on.size) if level is None or knee == 0 else 1.0 / (1.0 + level / knee)
        mu = (leak + R * g) * duration_s
        p_tail = special.pdtrc(on_f + off_f - 1.0, mu)  # P(N >= k), k >= 1
        keep = ~((on_f + off_f >= 1) & (p_tail < HOT_P / on.size))
    leak, R, knee = _fit_arrays(
        on_f[keep], off_f[keep], duration_s, None if level is None else level[keep]
    )
    bins: list[LevelBin] = []
    if level is not None:
        dn = level * 255.0
        for lo, hi in itertools.pairwise(DN_BINS):
            b = keep & (dn >= lo) & (dn < hi)
            bins.append(
                LevelBin(lo, hi, int(b.sum()), int(on[b].sum()), int(off[b].sum()), duration_s)
            )
    hot = ~keep
    return NoiseFit(
        leak_rate=leak,
        shot_noise_rate=R,
        shot_noise_knee=knee,
        shot_noise_intensity_factor=1.0,
        source=source,
        duration_s=duration_s,
        pixels=on.size if pixels is None else pixels,
        static_pixels=int(keep.sum()),
        on=int(on[keep].sum()),
        off=int(off[keep].sum()),
        hot_pixels=int(hot.sum()),
        hot_events=int(on[hot].sum() + off[hot].sum()),
        bins=tuple(bins),
    )


def _fit_arrays(on: F64, off: F64, T: float, level: F64 | None) -> tuple[float, float, float]:
    """``(leak, R, knee)`` of the ON / OFF counts."""
    R, knee = _fit_shot(off, level, T)
    g = np.ones(on.size) if level is None or knee == 0 else 1.0 / (1.0 + level / knee)
    return _leak_rate(float(on.sum() - off.sum()) / T, R * g), R, knee


def _leak_rate(excess: float, shot: F64) -> float:
    """The configured leak rate whose events come at ``excess`` per second over pixels of
    shot-noise rates ``shot`` (n,) Hz. Any event resets the pixel, so its leak clock restarts
    at each shot event: a pixel leaking every ``1 / r`` s fires ``s / (exp(s / r) - 1)`` leak
    events per second among shot events at ``s`` Hz (``r`` as ``s -> 0``)."""
    if excess <= 0:
        return 0.0

    def measured(r: float) -> float:
        with np.errstate(over="ignore"):
            x = np.where(shot > 0, shot / np.expm1(shot / r), r)
        return float(x.sum()) - excess

    hi = excess / shot.size
    while measured(hi) < 0:
        hi *= 2.0
    return float(optimize.brentq(measured, excess / shot.size * 1e-3, hi, rtol=1e-10))


def fit_noise(
    rec: Recording,
    *,
    quiet_span: tuple[float, float] | None = None,
    std_max: float = 2.0,
    margin: int = 3,
) -> NoiseFit:
    """Fit ``rec``'s background: from its first to its last APS frame on the pixels the
    frames show static (:func:`static_mask`), or over ``quiet_span`` (s from the first
    event) on every
    pixel. Intensities come from the mean APS frame where the recording has frames."""
    H, W = rec.height, rec.width
    if quiet_span is not None:
        t0, t1 = quiet_span
        if not 0 <= t0 < t1:
            msg = f"--quiet-span {t0} {t1}: need 0 <= T0 < T1 (s from the first event)"
            raise RecordingError(msg)
        a, b = np.searchsorted(rec.t_ns, [round(t0 * 1e9), round(t1 * 1e9)])
        mask = np.ones((H, W), bool)
        T = min(t1, rec.duration_s) - t0
        source = f"quiet span {t0:g}-{t1:g} s"
    else:
        if rec.frames is None:
            msg = (
                f"{rec.path}: no APS frames to find static pixels in; name a quiet span "
                "(--quiet-span T0 T1, s from the first event)"
            )
            raise RecordingError(msg)
        mask = static_mask(rec.frames, std_max, margin)
        # the span the frames vouch for (a recording's ends can hold bursts of its start
        # and stop: the real DAVIS346 of docs/realism.md fires ~100 events in its last 40 ms)
        assert rec.frame_t_ns is not None
        f0, f1 = max(int(rec.frame_t_ns[0]), 0), int(rec.frame_t_ns[-1])
        a, b = np.searchsorted(rec.t_ns, [f0, f1 + 1])
        T = (f1 - f0) * 1e-9
        source = (
            f"APS std < {std_max:g} DN, {margin} px from moving pixels, over the frames' "
            f"{f0 * 1e-9:.3f}-{f1 * 1e-9:.3f} s"
        )
    if T <= 0:
        msg = f"{rec.path}: the span holds no time (recording {rec.duration_s:.3f} s long)"
        raise RecordingError(msg)
    idx = rec.y[a:b] * W + rec.x[a:b]
    pol = rec.p[a:b]
    on = np.bincount(idx[pol == 1], minlength=H * W)
    off = np.bincount(idx[pol == 0], minlength=H * W)
    m = mask.ravel()
    level = None
    if rec.frames is not None:
        level = np.clip(rec.frames.astype(np.float64).mean(axis=0).ravel() / 255.0, 0.0, 1.0)[m]
    return fit_static_counts(on[m], off[m], T, level, source=source, pixels=H * W)
