"""roslan.env.wrappers: smaller action sets flown through LandingEnv."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from env_helpers import tiny_config
from roslan.env import LandingEnv, ReducedAction, TauStatePolicy, VerticalAction
from roslan.errors import ActionError, ConfigError

pytest.importorskip("roslan.render.gl")


def test_vertical_action_passes_the_env_checker() -> None:
    from gymnasium.utils.env_checker import check_env

    env = VerticalAction(LandingEnv(tiny_config()))
    assert env.action_space.shape == (1,)
    assert env.action_space.high[0] == env.unwrapped.action_space.high[2]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "not the unwrapped environment"
        check_env(env, skip_render_check=True)
    env.close()


def test_zero_rest_flies_only_the_kept_components() -> None:
    env = ReducedAction(LandingEnv(tiny_config()), ["r", "az"])  # order of ACTION_NAMES
    assert env.keep == [2, 5]
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([-1.5, 0.25], np.float32))
    np.testing.assert_array_equal(info["action"], [0, 0, -1.5, 0, 0, 0.25])
    # what the wrapped env flew: its commanded yaw rate reaches the vehicle (lagged)
    rates = [info["state"]["rates"][5]]
    for _ in range(5):
        _, _, _, _, info = env.step(np.array([0.0, 0.25], np.float32))
        rates.append(info["state"]["rates"][5])
    assert rates[-1] > rates[0] + 0.05
    env.close()


def test_tau_state_rest_with_tau_state_vertical_is_tau_state() -> None:
    """The vertical channel fed from a tau-state controller of its own, the rest from the
    wrapper's: the same episode as tau-state flying all six, step for step."""
    seed = 3
    full_env = LandingEnv(tiny_config())
    obs, info = full_env.reset(seed=seed)
    pol = TauStatePolicy()
    ctx = full_env.policy_context()
    pol.reset(ctx)
    env = VerticalAction(LandingEnv(tiny_config()), rest="tau-state")
    obs_w, info_w = env.reset(seed=seed)
    agent = TauStatePolicy()
    agent.reset(ctx)
    for _ in range(400):
        a = pol.act(obs, info)
        obs, _, term, trunc, info = full_env.step(a)
        az = agent.act(obs_w, info_w)[2]
        obs_w, _, term_w, trunc_w, info_w = env.step(np.array([az]))
        np.testing.assert_array_equal(info_w["state"]["gaps"], info["state"]["gaps"])
        assert (term, trunc) == (term_w, trunc_w)
        if term or trunc:
            break
    assert term
    assert info_w["episode"]["success"]
    full_env.close()
    env.close()


def test_bad_keep_and_bad_actions_are_clear() -> None:
    with pytest.raises(ConfigError, match=r"keep = \['vz'\].*ax, ay, az, p, q, r"):
        ReducedAction(LandingEnv(tiny_config()), ["vz"])
    env = VerticalAction(LandingEnv(tiny_config()))
    env.reset(seed=0)
    with pytest.raises(ActionError, match=r"shape \(2,\); expected \(1,\): \[az\]"):
        env.step(np.zeros(2))
    with pytest.raises(ActionError, match=r"action\[0\] \(az\) = nan"):
        env.step(np.array([np.nan]))
    env.close()
