"""LandingEnv's reset (issue 46 item 1): the scene is built once per scene and scene seed
(``closed_loop.scene_seed: fixed | per_episode``), and the observations of a seed do not
depend on the scenes built before."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import roslan.scene as scene_mod
from env_helpers import tiny_config
from roslan.env import LandingEnv
from roslan.errors import ConfigError


def _count_scene_builds(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    seeds: list[int] = []
    real = scene_mod.load_scene

    def counting(*args: Any, **kwargs: Any) -> Any:
        seeds.append(int(kwargs.get("seed", 0)))
        return real(*args, **kwargs)

    monkeypatch.setattr(scene_mod, "load_scene", counting)
    return seeds


def _imu_only(**over: Any) -> dict[str, Any]:
    """The tiny landing's IMU only, in its (empty) scene: no renderer to make."""
    cfg = tiny_config(**over)
    cfg["sensors"] = [s for s in cfg["sensors"] if s["type"] == "imu"]
    return cfg


def _rollout(env: LandingEnv, seed: int, steps: int = 3) -> list[dict[str, np.ndarray]]:
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for k in range(steps):
        obs, *_ = env.step(np.array([0.2 * k, -0.1, 0.3, 0.0, 0.05, 0.0], np.float32))
        out.append(obs)
    return out


def _same(a: list[dict[str, np.ndarray]], b: list[dict[str, np.ndarray]]) -> bool:
    return len(a) == len(b) and all(
        x.keys() == y.keys() and all(np.array_equal(x[k], y[k]) for k in x)
        for x, y in zip(a, b, strict=True)
    )


def test_a_fixed_scene_is_built_once_and_per_episode_once_per_seed(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    seeds = _count_scene_builds(monkeypatch)
    env = LandingEnv(_imu_only(seed=7))  # scene_seed: fixed (the default)
    for s in (0, 1, 2, 1):
        env.reset(seed=s)
        assert env.episode["scene_seed"] == 7
    assert seeds == [7]
    env.close()
    seeds.clear()
    env = LandingEnv(_imu_only(seed=7, closed_loop={"scene_seed": "per_episode"}))
    for s in (0, 0, 1, 1, 0):
        env.reset(seed=s)
        assert env.episode["scene_seed"] == s
    assert seeds == [0, 1, 0]  # a new seed builds its scene (only the last one is kept)
    env.close()


def test_a_seeds_observations_do_not_depend_on_the_resets_before() -> None:
    # per_episode is the scene of the episode's seed, as before scene_seed existed; a fixed
    # scene at the config's seed is that same scene for that seed
    per = LandingEnv(tiny_config(closed_loop={"scene_seed": "per_episode"}))
    first = _rollout(per, 3)
    _rollout(per, 5)
    again = _rollout(per, 3)
    per.close()
    fixed = LandingEnv(tiny_config(seed=3))
    _rollout(fixed, 4)
    reused = _rollout(fixed, 3)  # the scene built at the first reset, kept
    fixed.close()
    assert _same(first, again)
    assert _same(first, reused)
    # and the scene seed matters: episode 5 in the scene of seed 3 is not episode 5 in its own
    fixed = LandingEnv(tiny_config(seed=3))
    in_fixed = _rollout(fixed, 5)
    fixed.close()
    per = LandingEnv(tiny_config(seed=3, closed_loop={"scene_seed": "per_episode"}))
    in_own = _rollout(per, 5)
    per.close()
    assert not _same(in_fixed, in_own)
    np.testing.assert_array_equal(in_fixed[0]["imu"], in_own[0]["imu"])  # same sensor noise


def test_scene_seed_accepts_only_its_two_values() -> None:
    with pytest.raises(ConfigError, match="scene_seed"):
        LandingEnv(_imu_only(closed_loop={"scene_seed": "random"}))
