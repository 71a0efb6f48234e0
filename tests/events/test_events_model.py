"""The ESIM pixel model against plain-loop references and analytic cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from roslan.events import (
    EVENT_PRESETS,
    EventBatch,
    EventGenerator,
    EventModelParams,
    log_intensity,
)
from roslan.events.reference import NumpyEventGenerator
from roslan.events.sampling import AdaptiveSampler, motion_field, pixel_rays


def reference_esim(
    frames: np.ndarray, times: list[int], c_pos: np.ndarray, c_neg: np.ndarray, refractory_ns: int
) -> list[tuple[int, int, int, int]]:
    """Per-pixel ESIM update written plainly: loops over pixels and crossings."""
    T, H, W = frames.shape
    n = H * W
    ref = [float(v) for v in frames[0].ravel()]
    last = [None] * n
    out: list[tuple[int, int, int, int]] = []
    for k in range(1, T):
        prev = frames[k - 1].ravel()
        cur = frames[k].ravel()
        t0, dt = times[k - 1], times[k] - times[k - 1]
        interval = []
        for i in range(n):
            s0, s1, r = float(prev[i]), float(cur[i]), ref[i]
            if s1 > r:
                sgn, C = 1.0, float(c_pos[i])
            else:
                sgn, C = -1.0, float(c_neg[i])
            j = 1
            while (r + sgn * (j * C) - s1) * sgn <= 0:
                level = r + sgn * (j * C)
                frac = (level - s0) / (s1 - s0) if s1 != s0 else 1.0
                frac = min(max(frac, 0.0), 1.0)
                t = t0 + round(frac * dt)
                if last[i] is None or t - last[i] >= refractory_ns:
                    interval.append((t, i % W, i // W, 1 if sgn > 0 else 0))
                    last[i] = t
                j += 1
            ref[i] = r + sgn * ((j - 1) * C)
        interval.sort(key=lambda e: e[0])  # stable: pixel order within equal times
        out.extend(interval)
    return out


def run_generator(gen: EventGenerator, frames: np.ndarray, times: list[int]) -> EventBatch:
    batches = [
        gen.update_log(f.ravel().astype(np.float64), t) for f, t in zip(frames, times, strict=True)
    ]
    return EventBatch.concatenate(batches)


def as_tuples(b: EventBatch) -> list[tuple[int, int, int, int]]:
    return list(zip(b.t.tolist(), b.x.tolist(), b.y.tolist(), b.p.tolist(), strict=True))


@pytest.mark.parametrize(
    ("sigma", "refractory"), [(0.0, 0.0), (0.05, 0.0), (0.05, 2e-3), (0.0, 5e-4)]
)
def test_vectorized_equals_plain_reference(sigma: float, refractory: float) -> None:
    rng = np.random.default_rng(42)
    H, W, T = 5, 7, 30
    # random walk in log intensity with occasional big jumps (multi-crossings)
    steps = rng.normal(0, 0.15, (T, H, W)) + (rng.random((T, H, W)) < 0.1) * rng.normal(
        0, 1.0, (T, H, W)
    )
    frames = np.cumsum(steps, axis=0)
    times = np.cumsum(rng.integers(100_000, 3_000_000, T)).tolist()
    params = EventModelParams(
        threshold_pos=0.2, threshold_neg=0.25, threshold_sigma=sigma, refractory=refractory
    )
    gen = EventGenerator(W, H, params, np.random.default_rng(1))
    got = run_generator(gen, frames, times)
    want = reference_esim(frames, times, gen.c_pos, gen.c_neg, round(refractory * 1e9))
    assert len(want) > 100
    assert as_tuples(got) == want
    assert np.all(np.diff(got.t) >= 0)
    if refractory > 0:
        assert gen.n_dropped > 0


NOISY = EventModelParams(
    threshold_pos=0.2,
    threshold_neg=0.25,
    threshold_sigma=0.05,
    refractory=1e-3,
    cutoff_hz=200.0,
    intensity_dependent=True,
    leak_rate=3.0,
    shot_noise_rate=20.0,
)


def assert_same_state(a: EventGenerator, b: EventGenerator) -> None:
    for name in ("ref", "lp", "signal", "last_event_ns"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.n_dropped == b.n_dropped


@pytest.mark.parametrize(
    "params",
    [
        EVENT_PRESETS["clean"],
        EVENT_PRESETS["realistic"],
        NOISY,
        NOISY.with_overrides(intensity_dependent=False, leak_rate=0.0),
        NOISY.with_overrides(shot_noise_knee=0.05),
    ],
    ids=["clean", "realistic", "noisy", "fixed-lowpass", "shot-knee"],
)
@pytest.mark.parametrize("dtype", [np.float32, np.float64, np.uint8])
def test_kernels_equal_numpy_reference(params: EventModelParams, dtype: type) -> None:
    """The numba kernels and the NumPy array passes give bit-identical events and state,
    through :meth:`update` (linear frames of any dtype) and :meth:`update_log`."""
    rng = np.random.default_rng(11)
    H, W, T = 24, 31, 40
    # textured frames, a random walk in log intensity with big jumps; some pixels over 1
    # and some exactly 0 (clipped low-pass rate, log(eps))
    L = np.cumsum(rng.normal(0, 0.25, (T, H, W)) * (1 + 4 * (rng.random((T, H, W)) < 0.05)), 0)
    frames = np.exp(L + np.log(rng.uniform(0.02, 0.8, (H, W))))
    frames[:, 0, :5] = 0.0
    if dtype == np.uint8:
        frames = np.clip(frames * 100, 0, 255)
    frames = frames.astype(dtype)
    times = np.cumsum(rng.integers(50_000, 4_000_000, T)).tolist()
    ref = NumpyEventGenerator(W, H, params, np.random.default_rng(5))
    fast = EventGenerator(W, H, params, np.random.default_rng(5))
    want = [ref.update(f, t) for f, t in zip(frames, times, strict=True)]
    got = [fast.update(f, t) for f, t in zip(frames, times, strict=True)]
    for g, w in zip(got, want, strict=True):
        for u, v in zip(g, w, strict=True):
            assert u.dtype == v.dtype
            np.testing.assert_array_equal(u, v)
    assert sum(b.size for b in want) > 1000
    assert_same_state(fast, ref)
    # update_log with the intensity beside it
    ref = NumpyEventGenerator(W, H, params, np.random.default_rng(5))
    fast = EventGenerator(W, H, params, np.random.default_rng(5))
    for f, t in zip(frames, times, strict=True):
        Lf = np.log(params.log_eps + f.astype(np.float64).ravel())
        w = ref.update_log(Lf, t, intensity=f.ravel())
        g = fast.update_log(Lf, t, intensity=f.ravel())
        for u, v in zip(g, w, strict=True):
            np.testing.assert_array_equal(u, v)
    assert_same_state(fast, ref)


def test_float32_frames_log_precision_and_events() -> None:
    """float32 frames (the renderer's) take log/exp in float32: L within 1 ulp of |L| < 8
    (4.8e-7, vs C = 0.2) of the float64 log, and the events of the float64 path except
    where a sample lies within that error of a level (none here) or a crossing time is
    ill-conditioned (a few ns, more only where the signal barely changes)."""
    rng = np.random.default_rng(4)
    H, W, T, eps = 30, 40, 25, 1e-3
    base = rng.uniform(0.0, 1.2, (H, W))
    frames = np.stack([base * np.exp(0.6 * np.sin(0.3 * k + 3 * base)) for k in range(T)])
    f32 = frames.astype(np.float32)
    exact = np.log(eps + f32.astype(np.float64))  # the float32 frame's own values
    err = np.abs(log_intensity(f32, eps) - exact)
    assert 0 < err.max() <= 4.8e-7
    np.testing.assert_array_equal(log_intensity(f32.astype(np.float64), eps), exact)
    times = np.cumsum(rng.integers(1_000_000, 5_000_000, T)).tolist()
    params = EVENT_PRESETS["realistic"].with_overrides(shot_noise_rate=0.0, leak_rate=0.0)
    g32 = EventGenerator(W, H, params, np.random.default_rng(1))
    g64 = EventGenerator(W, H, params, np.random.default_rng(1))
    a = EventBatch.concatenate([g32.update(f, t) for f, t in zip(f32, times, strict=True)])
    b = EventBatch.concatenate(
        [g64.update(f.astype(np.float64), t) for f, t in zip(f32, times, strict=True)]
    )
    assert a.size == b.size > 1000
    assert np.abs(g32.lp - g64.lp).max() <= 1e-6
    pa = np.lexsort((a.t, a.y, a.x))
    pb = np.lexsort((b.t, b.y, b.x))
    for u, v in ((a.x, b.x), (a.y, b.y), (a.p, b.p)):
        np.testing.assert_array_equal(u[pa], v[pb])
    dt = np.abs(a.t[pa] - b.t[pb])
    assert dt.max() > 0  # float32 is not float64: the comparison is not vacuous
    assert np.median(dt) <= 2
    assert dt.max() < 100_000  # ns, vs steps of 1-5 ms


def test_kernels_shot_noise_ties_keep_stable_order() -> None:
    """Shot-noise events of one pixel at one ns (forced by a 1 ns interval) keep the
    reference's order: the fallback sort by position."""
    params = EventModelParams(shot_noise_rate=2e9, refractory=2e-9)
    ref = NumpyEventGenerator(2, 1, params, np.random.default_rng(2))
    fast = EventGenerator(2, 1, params, np.random.default_rng(2))
    ties = 0
    for t in range(0, 200):
        # real crossings (some dropped by the refractory period) beside the shot noise
        L = np.array([0.9 * math.sin(t / 7), 0.0])
        w = ref.update_log(L, t)
        g = fast.update_log(L, t)
        for u, v in zip(g, w, strict=True):
            np.testing.assert_array_equal(u, v)
        key = w.t * 2 + w.x
        ties += int(np.any((key[1:] == key[:-1]) & (w.p[1:] != w.p[:-1])))
    assert ties > 10
    assert ref.n_dropped > 0
    assert_same_state(fast, ref)


def test_uniform_ramp_counts_and_times() -> None:
    H, W, C, a = 3, 4, 0.15, 2.5  # L(t) = L0 + a t, a in log units per second
    eps = 1e-3
    L0 = np.log(eps + np.linspace(0.05, 0.5, H * W)).reshape(H, W)
    rng = np.random.default_rng(3)
    times = np.concatenate([[0], np.cumsum(rng.integers(1_000_000, 20_000_000, 40))]).astype(
        np.int64
    )
    gen = EventGenerator(W, H, EventModelParams(threshold_pos=C, threshold_neg=C, log_eps=eps), rng)
    batches = []
    for t in times:
        L = L0 + a * (t * 1e-9)
        batches.append(gen.update(np.exp(L) - eps, int(t)))
    ev = EventBatch.concatenate(batches)
    dL = a * times[-1] * 1e-9
    n_expected = math.floor(dL / C)
    counts = np.bincount(ev.y.astype(int) * W + ev.x, minlength=H * W)
    assert np.all(counts == n_expected)
    assert np.all(ev.p == 1)
    # the k-th event of every pixel at t = k C / a
    for pix in range(H * W):
        sel = (ev.y.astype(int) * W + ev.x) == pix
        tk = ev.t[sel]
        want = np.arange(1, n_expected + 1) * C / a * 1e9
        assert np.max(np.abs(tk - want)) <= 1  # ns: rounding


def test_descending_ramp_negative_events() -> None:
    gen = EventGenerator(
        2, 2, EventModelParams(threshold_pos=0.1, threshold_neg=0.3), np.random.default_rng(0)
    )
    gen.update_log(np.zeros(4), 0)
    ev = gen.update_log(np.full(4, -1.0), 1_000_000)
    assert ev.size == 4 * 3
    assert np.all(ev.p == 0)
    # levels -0.3, -0.6, -0.9 crossed at 0.3, 0.6, 0.9 ms
    assert sorted(set(ev.t.tolist())) == [300_000, 600_000, 900_000]


def test_refractory_period_limits_rate() -> None:
    # a fast ramp: 1 crossing every 0.1 ms; refractory 1 ms keeps ~1 in 10, reference still advances
    R = 1e-3
    gen = EventGenerator(
        1,
        1,
        EventModelParams(threshold_pos=0.1, threshold_neg=0.1, refractory=R),
        np.random.default_rng(0),
    )
    gen.update_log(np.zeros(1), 0)
    times = np.arange(1, 101) * 100_000  # 10 ms in 0.1 ms steps
    batches = [
        gen.update_log(np.array([0.1 * k + 0.05]), int(t)) for k, t in enumerate(times, start=1)
    ]
    ev = EventBatch.concatenate(batches)
    assert np.all(np.diff(ev.t) >= R * 1e9)
    assert 9 <= ev.size <= 11
    # the reference advanced through the dropped events: stop the ramp, no burst follows
    after = gen.update_log(np.array([0.1 * 100 + 0.05]), int(times[-1] + 5_000_000))
    assert after.size == 0
    assert gen.n_dropped == 100 - ev.size


def test_threshold_mismatch_statistics() -> None:
    sigma = 0.04
    gen = EventGenerator(
        200,
        150,
        EventModelParams(threshold_pos=0.3, threshold_neg=0.2, threshold_sigma=sigma),
        np.random.default_rng(7),
    )
    assert abs(gen.c_pos.mean() - 0.3) < 3 * sigma / math.sqrt(gen.n_pixels) * 3
    assert abs(gen.c_pos.std() - sigma) < 0.02 * sigma * 5
    assert abs(gen.c_neg.mean() - 0.2) < 3 * sigma / math.sqrt(gen.n_pixels) * 3
    assert abs(np.corrcoef(gen.c_pos, gen.c_neg)[0, 1]) < 0.02
    # fixed per pixel: a ramp of dL gives floor(dL / C_pixel) events in each pixel
    gen.update_log(np.zeros(gen.n_pixels), 0)
    ev = gen.update_log(np.full(gen.n_pixels, 1.7), 10_000_000)
    counts = np.bincount(ev.y.astype(int) * 200 + ev.x, minlength=gen.n_pixels)
    np.testing.assert_array_equal(counts, np.floor(1.7 / gen.c_pos))


def test_noise_rates_and_determinism() -> None:
    p = EventModelParams(shot_noise_rate=2.0, leak_rate=1.0, threshold_sigma=0.03)

    def run(seed: int) -> EventBatch:
        g = EventGenerator(64, 48, p, np.random.default_rng(seed))
        out = []
        L = np.full(64 * 48, np.log(0.3))
        for t in range(0, 2_000_000_001, 10_000_000):
            out.append(g.update_log(L, t))
        return EventBatch.concatenate(out)

    a, b, c = run(5), run(5), run(6)
    for u, v in zip(a, b, strict=True):
        np.testing.assert_array_equal(u, v)
    assert a.size != c.size or not np.array_equal(a.t, c.t)
    n_pix, T = 64 * 48, 2.0
    # static scene: leak ~1 ON event / pixel / s, shot noise 2 * (1 - 0.75 * 0.3) = 1.55
    # (less the leak a shot event's reset delays; test_events_noise measures each alone)
    rate = a.size / (n_pix * T)
    assert 2.0 < rate < 2.6
    assert np.all(np.diff(a.t) >= 0)


def test_lowpass_delays_response() -> None:
    fast = EventGenerator(1, 1, EventModelParams(), np.random.default_rng(0))
    slow = EventGenerator(1, 1, EventModelParams(cutoff_hz=50.0), np.random.default_rng(0))
    for g in (fast, slow):
        g.update_log(np.zeros(1), 0)
    tf, ts = [], []
    for t in range(100_000, 50_000_001, 100_000):
        tf += fast.update_log(np.full(1, 1.1), t).t.tolist()
        ts += slow.update_log(np.full(1, 1.1), t).t.tolist()
    assert len(tf) == len(ts) == 5
    tau = 1 / (2 * math.pi * 50)
    # first-order step response 1 - exp(-t/tau) reaches 0.2 at t = -tau ln(1 - 0.2/1.1)
    assert abs(ts[0] * 1e-9 - (-tau * math.log(1 - 0.2 / 1.1))) < 2e-4
    assert ts[-1] > tf[-1]


def test_motion_field_matches_finite_difference() -> None:
    rng = np.random.default_rng(0)
    K = np.array([[200.0, 0, 40], [0, 210.0, 30], [0, 0, 1]])
    W, H = 80, 60
    x, y = pixel_rays(K, W, H)
    depth = rng.uniform(2, 10, (H, W))
    v, w = np.array([0.5, -0.3, 1.2]), np.array([0.2, -0.4, 0.3])
    flow = motion_field(depth, K, v, w)
    P = np.stack([x * depth, y * depth, depth], axis=-1)
    h = 1e-6
    # the point in the camera frame after dt: P' = R(-w dt) (P - v dt)
    P2 = P - v * h - np.cross(w, P) * h
    u2 = K[0, 0] * P2[..., 0] / P2[..., 2] + K[0, 2]
    u1 = K[0, 0] * x + K[0, 2]
    np.testing.assert_allclose(flow[..., 0], (u2 - u1) / h, rtol=1e-4, atol=1e-2)
    v2 = K[1, 1] * P2[..., 1] / P2[..., 2] + K[1, 2]
    v1 = K[1, 1] * y + K[1, 2]
    np.testing.assert_allclose(flow[..., 1], (v2 - v1) / h, rtol=1e-4, atol=1e-2)


def test_adaptive_sampler_bounds_and_forced() -> None:
    s = AdaptiveSampler(
        "optical_flow",
        0.5,
        min_rate=100,
        max_rate=1000,
        end_ns=50_000_000,
        forced_ns=np.array([3_333_333]),
    )
    assert s.step_ns(0.0) == 10_000_000  # min rate
    assert s.step_ns(1e9) == 1_000_000  # max rate
    assert s.step_ns(250.0) == 2_000_000  # 0.5 px / 250 px/s
    assert s.next_ns(0, 250.0) == 2_000_000
    assert s.next_ns(2_000_000, 250.0) == 3_333_333
    assert s.next_ns(49_500_000, 1.0) == 50_000_000
    assert s.next_ns(50_000_000, 1.0) is None
