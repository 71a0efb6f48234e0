"""``roslan.events.fit``: the noise fit recovers the rates of synthetic recordings whose
rates are known (a direct Poisson process per pixel, and roslan's own pixel model), finds
static pixels and hot pixels, and reads roslan's event files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from roslan.errors import RecordingError
from roslan.events.fit import fit_noise, fit_static_counts, static_mask
from roslan.events.model import EventGenerator, EventModelParams
from roslan.events.recording import Recording, read_recording

W, H = 100, 80
LEAK, SHOT, KNEE = 0.8, 4.0, 0.1
T_S = 10.0


def poisson_recording(
    rng: np.random.Generator, level: np.ndarray, hot: np.ndarray | None = None
) -> tuple[np.ndarray, ...]:
    """Events of every pixel as roslan's model fires them: OFF at ``S(I) / 2``, ON at
    ``S(I) / 2`` plus the leak ``S / (exp(S / LEAK) - 1)`` (each event restarts the leak
    clock), ``S(I) = SHOT / (1 + I / KNEE)``; uniform instants over ``T_S``; hot pixels add
    40 Hz."""
    s = SHOT / (1.0 + level.ravel() / KNEE)
    on_rate, off_rate = s / np.expm1(s / LEAK) + s / 2, s / 2
    if hot is not None:
        on_rate = on_rate + 40.0 * hot.ravel()
    n_on = rng.poisson(on_rate * T_S)
    n_off = rng.poisson(off_rate * T_S)
    idx = np.concatenate([np.repeat(np.arange(W * H), n_on), np.repeat(np.arange(W * H), n_off)])
    p = np.concatenate([np.ones(n_on.sum(), np.int8), np.zeros(n_off.sum(), np.int8)])
    t = rng.integers(0, round(T_S * 1e9), idx.size)
    order = np.argsort(t, kind="stable")
    return t[order], idx[order] % W, idx[order] // W, p[order]


def test_fit_recovers_leak_shot_and_knee_with_levels() -> None:
    rng = np.random.default_rng(5)
    level = rng.random(W * H)
    _, x, y, p = poisson_recording(rng, level)
    idx = y * W + x
    on = np.bincount(idx[p == 1], minlength=W * H)
    off = np.bincount(idx[p == 0], minlength=W * H)
    fit = fit_static_counts(on, off, T_S, level)
    assert fit.leak_rate == pytest.approx(LEAK, rel=0.1)
    assert fit.shot_noise_rate == pytest.approx(SHOT, rel=0.1)
    assert fit.shot_noise_knee == pytest.approx(KNEE, rel=0.1)
    assert fit.hot_pixels == 0
    keys = fit.keys()
    assert set(keys) == {"leak_rate", "shot_noise_rate", "shot_noise_knee"}


def test_fit_noise_uses_aps_frames_excludes_motion_and_hot_pixels() -> None:
    """A recording with APS frames: a bright block moves (its pixels fire hundreds of
    events), a few hot pixels fire at 40 Hz; the fit finds the static pixels, flags the hot
    ones and recovers the rates of the rest."""
    rng = np.random.default_rng(6)
    base = np.repeat(np.linspace(0.0, 1.0, W)[None, :], H, 0)
    hot = np.zeros((H, W), bool)
    hot[rng.integers(0, H, 12), rng.integers(0, W, 12)] = True
    t, x, y, p = poisson_recording(rng, base, hot)
    frames = np.repeat(np.rint(base * 255).astype(np.uint8)[None], 20, 0)
    frames += rng.integers(0, 2, frames.shape, dtype=np.uint8) * (frames < 255)  # read noise
    moving = (slice(10, 30), slice(40, 60))
    for k in range(20):  # a block that changes level frame to frame
        frames[k][moving] = 30 + 10 * (k % 5)
    # the moving block fires 500 Hz per pixel
    my, mx = np.mgrid[moving]
    n = rng.poisson(500 * T_S, my.size)
    t_m = rng.integers(0, round(T_S * 1e9), n.sum())
    t = np.concatenate([t, t_m])
    x = np.concatenate([x, np.repeat(mx.ravel(), n)])
    y = np.concatenate([y, np.repeat(my.ravel(), n)])
    p = np.concatenate([p, rng.integers(0, 2, n.sum()).astype(np.int8)])
    order = np.argsort(t, kind="stable")
    rec = Recording(
        Path("synthetic"), W, H, t[order], x[order], y[order], p[order],
        frames, np.linspace(0, T_S * 1e9, 20).astype(np.int64),
    )  # fmt: skip
    mask = static_mask(frames, 2.0, 3)
    assert not mask[7:33, 37:63].any()  # the block and its margin
    assert mask.sum() == W * H - 26 * 26
    fit = fit_noise(rec)
    assert fit.hot_pixels == pytest.approx(int(hot[mask].sum()), abs=1)
    assert fit.leak_rate == pytest.approx(LEAK, rel=0.1)
    assert fit.shot_noise_rate == pytest.approx(SHOT, rel=0.1)
    assert fit.shot_noise_knee == pytest.approx(KNEE, rel=0.1)
    assert "shot_noise_knee:" in fit.report()


def test_fit_recovers_roslan_pixel_model_rates() -> None:
    """A static scene through roslan's own generator (constant shot noise, leak, no
    mismatch): the fit over a quiet span gives its configured rates."""
    params = EventModelParams(
        leak_rate=0.3, shot_noise_rate=0.4, shot_noise_intensity_factor=1.0, leak_jitter=0.0
    )
    gen = EventGenerator(W, H, params, np.random.default_rng(2))
    frame = np.full((H, W), 0.5)
    batches = [gen.update(frame, round(k * 0.05e9)) for k in range(401)]  # 20 s
    t = np.concatenate([b.t for b in batches])
    x = np.concatenate([b.x for b in batches]).astype(np.int64)
    y = np.concatenate([b.y for b in batches]).astype(np.int64)
    p = np.concatenate([b.p for b in batches])
    rec = Recording(Path("generated"), W, H, t - t[0], x, y, p)
    fit = fit_noise(rec, quiet_span=(0.0, 20.0 - t[0] * 1e-9))
    assert fit.shot_noise_rate == pytest.approx(0.4, rel=0.1)
    # the leak events measured are fewer (0.143 Hz: each shot event restarts the pixel's
    # leak clock); the fit returns the configured leak that gives them
    on_minus_off = (2 * int(p.sum()) - p.size) / (W * H) / 20.0
    assert on_minus_off == pytest.approx(0.4 * np.exp(-0.4 / 0.3) / -np.expm1(-0.4 / 0.3), rel=0.1)
    assert fit.leak_rate == pytest.approx(0.3, rel=0.1)
    assert fit.keys()["shot_noise_intensity_factor"] == 1.0


def test_read_recording_errors(tmp_path: Path) -> None:
    bad = tmp_path / "events.csv"
    bad.write_text("x")
    with pytest.raises(RecordingError, match=r"events\.csv: unknown recording type"):
        read_recording(bad)
    with pytest.raises(RecordingError, match="no such file"):
        read_recording(tmp_path / "none.h5")
    txt = tmp_path / "events.txt"
    txt.write_text("0.1 5 6 1\n0.2 7 x 0\n")
    with pytest.raises(RecordingError, match=r"events\.txt: not an events\.txt"):
        read_recording(txt)
    txt.write_text("0.1 5 6 1\n")
    with pytest.raises(RecordingError, match=r"event 0 at pixel \(5, 6\) lies outside the 4x4"):
        read_recording(txt, size=(4, 4))
    h5 = tmp_path / "events.h5"
    h5.write_bytes(b"not hdf5")
    with pytest.raises(RecordingError, match=r"events\.h5: not an events\.h5"):
        read_recording(h5)
    empty = tmp_path / "empty.txt"
    empty.write_text("")
    with pytest.raises(RecordingError, match="holds no events"):
        read_recording(empty)
    rec = read_recording(txt)
    with pytest.raises(RecordingError, match="no APS frames"):
        fit_noise(rec)
    with pytest.raises(RecordingError, match=r"--quiet-span 2.0 1.0"):
        fit_noise(rec, quiet_span=(2.0, 1.0))
