"""The noise model measures what it is configured to: static scenes over many pixels
recover the shot-noise rate, the leak rate and their intensity dependence within
statistical error, for both generators, with and without threshold mismatch."""

from __future__ import annotations

import numpy as np
import pytest

from roslan.events.model import EventBatch, EventGenerator, EventModelParams
from roslan.events.reference import NumpyEventGenerator

H, W = 80, 200  # 16000 pixels; 4 intensity bands of 50 columns
LEVELS = np.array([0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0])
T_NS, STEP_NS = 10_000_000_000, 10_000_000  # 10 s static scene at 100 Hz


def static_run(gen: EventGenerator, eps: float) -> EventBatch:
    inten = np.repeat(LEVELS, W // LEVELS.size)[None, :].repeat(H, 0).ravel()
    L = np.log(eps + inten)
    out = [gen.update_log(L, t, intensity=inten) for t in range(0, T_NS + 1, STEP_NS)]
    return EventBatch.concatenate(out)


def band_counts(ev: EventBatch, pol: int) -> np.ndarray:
    sel = ev.p == pol
    return np.bincount(ev.x[sel].astype(np.int64) // (W // LEVELS.size), minlength=LEVELS.size)


GENERATORS = [EventGenerator, NumpyEventGenerator]


@pytest.mark.parametrize("gen_cls", GENERATORS, ids=["numba", "numpy"])
@pytest.mark.parametrize("sigma", [0.0, 0.04], ids=["equal", "mismatch"])
@pytest.mark.parametrize("knee", [0.0, 0.2], ids=["linear", "knee"])
def test_shot_noise_rate_intensity_and_threshold_dependence(
    gen_cls: type[EventGenerator], sigma: float, knee: float
) -> None:
    rate, f = 2.0, 0.25
    p = EventModelParams(
        threshold_pos=0.2, threshold_neg=0.3, threshold_sigma=sigma, shot_noise_rate=rate,
        shot_noise_intensity_factor=f, shot_noise_knee=knee, refractory=1e-3,
    )  # fmt: skip
    gen = gen_cls(W, H, p, np.random.default_rng(3))
    ev = static_run(gen, p.log_eps)
    # independent expectation per band and polarity: rate/2 g(I) C_nom / C, g(I) v2e's
    # line 1 - (1 - f) I, or 1 / (1 + I / knee)
    band = np.arange(H * W) % W // (W // LEVELS.size)
    g = 1.0 / (1.0 + LEVELS / knee) if knee else 1.0 - (1.0 - f) * LEVELS
    T = T_NS * 1e-9
    for pol, nominal, c in ((1, 0.2, gen.c_pos), (0, 0.3, gen.c_neg)):
        expect = rate / 2 * T * g * np.bincount(band, weights=nominal / c)
        got = band_counts(ev, pol)
        # Poisson counts (~10000-40000 per cell): within 4 sigma (2-4 %)
        assert np.all(np.abs(got - expect) <= 4 * np.sqrt(expect)), (pol, got, expect)
    # no follow-up events: a static scene has nothing else (every event is shot noise),
    # and nothing is dropped (the refractory period does not apply to shot noise)
    assert gen.n_dropped == 0
    # darker pixels are noisier: the I = 0 band over the I = 1 band is 1 / f
    tot = band_counts(ev, 0) + band_counts(ev, 1)
    if sigma == 0:
        assert tot[0] / tot[-1] == pytest.approx(1 / g[-1], rel=0.06)
    else:
        # mismatch raises the mean rate (E[C_nom / C] > 1): the measured rate says so
        assert tot.sum() > rate * T * H * W * g.mean() * 1.01


@pytest.mark.parametrize("gen_cls", GENERATORS, ids=["numba", "numpy"])
@pytest.mark.parametrize("sigma", [0.0, 0.04], ids=["equal", "mismatch"])
def test_leak_rate_is_configured_and_intensity_independent(
    gen_cls: type[EventGenerator], sigma: float
) -> None:
    rate = 0.7
    p = EventModelParams(threshold_sigma=sigma, leak_rate=rate, leak_jitter=0.1)
    gen = gen_cls(W, H, p, np.random.default_rng(4))
    ev = static_run(gen, p.log_eps)
    assert np.all(ev.p == 1)  # the leak drifts the reference down: ON events only
    T = T_NS * 1e-9
    per_band = H * W / LEVELS.size * rate * T  # 28000 events per band
    # steady phase: per pixel floor(phase + rate_i T), expectation rate_i T; the jitter
    # (10 %: 0.7 events per pixel) and the phase (<= 0.5) give a std of ~0.2 % per band
    np.testing.assert_allclose(band_counts(ev, 1), per_band, rtol=0.01)


@pytest.mark.parametrize("gen_cls", GENERATORS, ids=["numba", "numpy"])
def test_leak_phase_zero_first_event_after_one_period(gen_cls: type[EventGenerator]) -> None:
    rate = 0.7
    p = EventModelParams(threshold_sigma=0.03, leak_rate=rate, leak_phase="zero")
    gen = gen_cls(W, H, p, np.random.default_rng(4))
    ev = static_run(gen, p.log_eps)
    assert gen.leak_slope is not None
    r_pix = gen.leak_slope / gen.c_pos  # each pixel's leak rate, Hz
    idx = ev.y.astype(np.int64) * W + ev.x
    counts = np.bincount(idx, minlength=H * W)
    T = T_NS * 1e-9
    # a reset at t = 0: floor(rate_i T) events, the first one period after the start
    # (within a frame step and float rounding)
    np.testing.assert_array_equal(counts, np.floor(r_pix * T + 1e-9))
    first = np.full(H * W, np.iinfo(np.int64).max)
    np.minimum.at(first, idx, ev.t)
    has = counts > 0
    lag = first[has] * 1e-9 - 1.0 / r_pix[has]
    assert np.all((lag > -1e-6) & (lag <= STEP_NS * 1e-9 + 1e-6))
    # steady: the first events spread over the first period (about half before 1/(2 r))
    steady = gen_cls(W, H, p.with_overrides(leak_phase="steady"), np.random.default_rng(4))
    ev_s = static_run(steady, p.log_eps)
    early = np.unique(
        ev_s.y[ev_s.t < 0.5e9 / rate].astype(np.int64) * W + ev_s.x[ev_s.t < 0.5e9 / rate]
    )
    assert 0.45 < early.size / (H * W) < 0.55


def test_leak_phase_rejects_unknown() -> None:
    with pytest.raises(ValueError, match="leak_phase = 'random': allowed steady, zero"):
        EventModelParams(leak_phase="random")


def test_config_leak_phase_key() -> None:
    from pydantic import ValidationError

    from roslan.sensors.cameras import EventCameraConfig

    base = {"type": "event_camera", "name": "dvs", "rate": 25.0, "topic": "/dvs"}
    assert EventCameraConfig.model_validate(base).model_params().leak_phase == "steady"
    cfg = EventCameraConfig.model_validate({**base, "leak_phase": "zero"})
    assert cfg.model_params().leak_phase == "zero"
    with pytest.raises(ValidationError, match="leak_phase"):
        EventCameraConfig.model_validate({**base, "leak_phase": "random"})
