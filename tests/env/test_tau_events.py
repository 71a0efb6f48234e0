"""The ``tau-events`` policy (roslan.env.tau_events): closed loop on a short warehouse
landing, its tau of the height gap from events + IMU against the true one, and its errors."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from env_helpers import marker_landing
from roslan.env import LandingEnv, PolicyContext, make_policy
from roslan.env.tau_events import TauEventsPolicy
from roslan.errors import ConfigError

pytest.importorskip("roslan.render.gl")


def short_landing(**over: Any) -> dict[str, Any]:
    """The marker landing of tests/helpers (1.5 m up, 128x96 camera), keys replaced."""
    cfg = marker_landing()
    cfg.update(over)
    return cfg


def _fly(cfg: dict[str, Any], seed: int) -> tuple[dict[str, Any], np.ndarray, TauEventsPolicy]:
    policy = make_policy("tau-events")
    assert isinstance(policy, TauEventsPolicy)
    env = LandingEnv(cfg, policy_name="tau-events")
    rows = []
    try:
        obs, info = env.reset(seed=seed)
        policy.reset(env.policy_context())
        while True:
            action = policy.act(obs, info)
            assert np.all(np.isfinite(action))
            z, vz = float(info["state"]["gaps"][2]), float(info["state"]["rates"][2])
            est = policy.estimate
            assert est is not None
            rows.append((info["t"], z / vz if vz < -1e-3 else math.nan, est.tau))
            obs, _, term, trunc, info = env.step(action)
            if term or trunc:
                return dict(info["episode"]), np.array(rows), policy
    finally:
        env.close()


@pytest.fixture(scope="module")
def episode() -> tuple[dict[str, Any], np.ndarray, TauEventsPolicy]:
    return _fly(short_landing(), seed=3)


@pytest.mark.xfail(
    strict=True,
    reason="regression of the 2026-12-02 marker detector on this 128x96 camera from 1.5 m: "
    "0.61 m off the marker (limit 0.5); the DAVIS346 default landing succeeds (10/10 seeds)",
)
def test_lands_softly_on_tau_from_events(episode: tuple[dict[str, Any], np.ndarray, Any]) -> None:
    ep, _, _ = episode
    assert ep["reason"] == "touchdown", ep
    assert ep["touchdown_vertical_speed"] <= 0.5, ep
    # closed_loop.success's bounds: slow sideways too (the coupling's tau is held at 1 s
    # near contact) and near the marker
    assert ep["touchdown_horizontal_speed"] <= 1.0, ep
    assert ep["position_error"] <= 0.5, ep
    assert ep["success"], ep


@pytest.mark.parametrize("seed", [0, 1])
def test_a_landing_from_far_off_ends_slow_sideways(seed: int) -> None:
    """From 2.9 m off the marker: the horizontal gaps close with the height gap, and near
    contact (|tau| < COUPLING_TAU_MIN) the residual gap is centred gently instead of at a
    speed growing as 1 / tau (it reached 0.6-1.1 m/s sideways on these seeds). Told the
    true start (``start_estimate`` zero): this tests the coupling, not the estimators."""
    cfg = short_landing(
        closed_loop={
            "start_estimate": {"position_sigma": 0, "velocity_sigma": 0, "attitude_sigma": 0}
        }
    )
    cfg["trajectory"]["initial"] = {
        "position": [-2.6, 1.2, 2.3],
        "rpy": [0.05, 0.1, 0.3],
        "descent_rate": 2.0,
    }
    ep, _, _ = _fly(cfg, seed)
    assert ep["reason"] == "touchdown", ep
    assert ep["touchdown_vertical_speed"] <= 0.5, ep
    assert ep["touchdown_horizontal_speed"] <= 0.5, ep
    assert ep["position_error"] <= 0.25, ep


def test_tau_estimate_tracks_the_true_tau_of_the_height_gap(
    episode: tuple[dict[str, Any], np.ndarray, Any],
) -> None:
    ep, rows, policy = episode
    t_td = ep["touchdown_time"]
    last = (rows[:, 0] >= 0.3 * t_td) & (rows[:, 0] < t_td) & np.isfinite(rows[:, 1])
    assert np.count_nonzero(last) >= 20
    est = rows[last, 2]
    assert np.all(np.isfinite(est))
    err = np.abs(est / rows[last, 1] - 1.0)
    assert np.median(err) <= 0.2, np.median(err)
    # the camera's own estimates were used, not only dead reckoning
    assert sum(1 for h in policy.history if h[3]) >= 20


def test_a_distorted_event_camera_is_undistorted_per_event() -> None:
    """Barrel distortion (k1 = -0.25): each event is moved to its pixel's ideal position
    (the lens model's exact inverse) before the divergence fit; read as a pinhole's, the
    same events gave an 83 % tau error and a 0.83 m/s touchdown."""
    cfg = short_landing()
    cfg["sensors"][1].update(
        {"distortion_model": "plumb_bob", "distortion_coeffs": [-0.25, 0.05, 0.0, 0.0, 0.0]}
    )
    ep, rows, _ = _fly(cfg, seed=3)
    assert ep["reason"] == "touchdown", ep
    assert ep["touchdown_vertical_speed"] <= 0.5, ep
    t_td = ep["touchdown_time"]
    last = (rows[:, 0] >= 0.3 * t_td) & (rows[:, 0] < t_td) & np.isfinite(rows[:, 1])
    err = np.abs(rows[last, 2] / rows[last, 1] - 1.0)
    assert np.median(err) <= 0.2, np.median(err)


def test_needs_an_event_camera_and_an_imu() -> None:
    cfg = short_landing()
    cfg["sensors"] = [s for s in cfg["sensors"] if s["type"] == "imu"]
    env = LandingEnv(cfg)
    try:
        env.reset(seed=0)
        assert env._traj is not None
        ctx = PolicyContext(env.config, env.dt, env._traj.R_world_goal, 20.0, 4.0)
        with pytest.raises(ConfigError, match="needs an event camera and an IMU"):
            make_policy("tau-events").reset(ctx)
    finally:
        env.close()
