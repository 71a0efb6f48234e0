"""benchmarks/train_landing.py: its learning path never reads the true state, and its
residual vertical action is flown as documented (needs the ``rl`` extra: skipped without)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

import roslan.env  # noqa: F401  (registers the ids)
from roslan.env.tau_events import TauEventsPolicy

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "train_landing.py"


def _load() -> Any:
    spec = importlib.util.spec_from_file_location("train_landing", SCRIPT)
    assert spec is not None
    assert spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["train_landing"] = mod
    spec.loader.exec_module(mod)
    return mod


tl = _load()


class _Guard(gym.Wrapper[Any, Any, Any, Any]):
    """Makes the base env's own info raise on ``"state"`` (any read by the layers above,
    other than NoTruthInfo's copy, which skips the key)."""

    def _wrap(self, info: dict[str, Any]) -> dict[str, Any]:
        class Raising(dict[str, Any]):
            def __getitem__(self, key: str) -> Any:
                if key == "state":
                    raise AssertionError("info['state'] read")
                return super().__getitem__(key)

            def get(self, key: str, default: Any = None) -> Any:
                if key == "state":
                    raise AssertionError("info['state'] read")
                return super().get(key, default)

        return Raising(info)

    def reset(self, **kw: Any) -> Any:
        obs, info = self.env.reset(**kw)
        return obs, self._wrap(info)

    def step(self, action: Any) -> Any:
        obs, r, te, tr, info = self.env.step(action)
        return obs, r, te, tr, self._wrap(info)


def test_no_truth_info_raises_and_drops_state() -> None:
    info = tl.NoTruthInfo({"state": {"gaps": [1.0]}, "t": 0.1})
    assert "state" not in dict.keys(info)
    assert info["t"] == 0.1
    with pytest.raises(tl.TruthAccess):
        _ = info["state"]
    with pytest.raises(tl.TruthAccess):
        info.get("state")


def test_pooled_events_sums_blocks() -> None:
    rng = np.random.default_rng(3)
    count = rng.integers(0, 5, (2, 48, 64)).astype(np.float32)
    p = tl.pooled_events(count)
    assert p.shape == (2, 12, 16)
    # block (1, 2, 3): rows 8..11, cols 12..15 of polarity 1
    assert p[1, 2, 3] == pytest.approx(np.log1p(count[1, 8:12, 12:16].sum()))


def test_wrapper_steps_without_truth_and_maps_the_residual() -> None:
    base = _Guard(gym.make("roslan/LandingLite-v0"))
    env = tl.EventsVertical(base)
    twin = gym.make("roslan/LandingLite-v0")  # the same episode, flown by hand
    try:
        obs, info = env.reset(seed=7)
        tobs, tinfo = twin.reset(seed=7)
        ref = TauEventsPolicy()
        ref.reset(twin.unwrapped.policy_context())
        assert obs.shape == env.observation_space.shape
        np.testing.assert_array_equal(obs, tl.features(tobs, 0.0))
        bound = float(twin.action_space.high[2])
        for a in (0.5, -1.0, 2.0, 0.0, -0.25):
            expect = np.asarray(ref.act(tobs, tinfo), dtype=np.float64).copy()
            expect[2] = np.clip(expect[2] + tl.RESIDUAL_SCALE * np.clip(a, -1, 1), -bound, bound)
            ref._a_cmd = expect[:3].copy()
            obs, _, te, tr, info = env.step(np.array([a], dtype=np.float32))
            tobs, _, tte, ttr, tinfo = twin.step(expect)
            np.testing.assert_allclose(dict.__getitem__(info, "action"), expect, rtol=0, atol=0)
            np.testing.assert_array_equal(obs, tl.features(tobs, float(np.clip(a, -1, 1))))
            assert (te, tr) == (tte, ttr)
            with pytest.raises(tl.TruthAccess):
                _ = info["state"]
    finally:
        env.close()
        twin.close()
