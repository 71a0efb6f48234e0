"""``roslan fit-noise``: a synthetic events.h5 / events.txt of known rates round-trips
through roslan's own writers and the command's YAML; bad files give one clear line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from roslan.cli import main
from roslan.events.files import EventH5Writer, format_events_txt
from roslan.events.model import EventBatch

W, H, T_S = 60, 50, 20.0
ON_HZ, OFF_HZ = 0.9, 0.3  # per pixel: shot noise 0.6 Hz (both polarities) and a leak


def synthetic(rng: np.random.Generator) -> EventBatch:
    n_on = rng.poisson(ON_HZ * T_S, W * H)
    n_off = rng.poisson(OFF_HZ * T_S, W * H)
    idx = np.concatenate([np.repeat(np.arange(W * H), n_on), np.repeat(np.arange(W * H), n_off)])
    p = np.concatenate([np.ones(n_on.sum(), np.int8), np.zeros(n_off.sum(), np.int8)])
    t = rng.integers(0, round(T_S * 1e9), idx.size)
    o = np.argsort(t, kind="stable")
    return EventBatch(t[o], (idx[o] % W).astype(np.uint16), (idx[o] // W).astype(np.uint16), p[o])


def expected_leak(shot: float, excess: float) -> float:
    """The leak rate r with ``shot / (exp(shot / r) - 1) = excess`` (bisection)."""
    lo, hi = 1e-6, 100.0
    for _ in range(200):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if shot / np.expm1(shot / mid) < excess else (lo, mid)
    return lo


@pytest.mark.parametrize("suffix", [".h5", ".txt"])
def test_fit_noise_recovers_rates_of_synthetic_file(
    tmp_path: Path, suffix: str, capsys: pytest.CaptureFixture[str]
) -> None:
    ev = synthetic(np.random.default_rng(1))
    path = tmp_path / f"events{suffix}"
    if suffix == ".h5":
        w = EventH5Writer(path, W, H)
        w.write(ev)
        w.close()
        size: list[str] = []
    else:
        path.write_bytes(format_events_txt(ev.t, ev.x, ev.y, ev.p))
        size = ["--size", str(W), str(H)]
    assert main(["fit-noise", str(path), "--quiet-span", "0", str(T_S), *size]) == 0
    out = capsys.readouterr().out
    keys = yaml.safe_load(out)
    assert keys["shot_noise_rate"] == pytest.approx(2 * OFF_HZ, rel=0.1)
    assert keys["shot_noise_intensity_factor"] == 1.0
    assert keys["leak_rate"] == pytest.approx(expected_leak(2 * OFF_HZ, ON_HZ - OFF_HZ), rel=0.1)
    assert f"of {W * H} (quiet span 0-20 s)" in out


def test_fit_noise_bad_inputs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "rec.aedat4"
    bad.write_bytes(b"garbage")
    assert main(["fit-noise", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {bad}: ")
    assert "Traceback" not in err
    txt = tmp_path / "events.txt"
    txt.write_text("0.1 1 1 1\n0.5 2 2 0\n")
    assert main(["fit-noise", str(txt)]) == 2
    assert "no APS frames to find static pixels in; name a quiet span" in capsys.readouterr().err
    assert main(["fit-noise", str(txt), "--quiet-span", "3", "1"]) == 2
    assert "need 0 <= T0 < T1" in capsys.readouterr().err
