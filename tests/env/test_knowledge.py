"""The information boundary (roslan.env.knowledge): what a policy may know, and the
estimators of ``tau-events`` (attitude filter, vertical scale) on synthetic data."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from env_helpers import marker_landing
from roslan.config.closed_loop import StartEstimateConfig
from roslan.env import PERCHING_CONFIG, LandingEnv, make_policy
from roslan.env.attitude import AttitudeFilter, expm_so3
from roslan.env.dynamics import DynamicsTrajectory
from roslan.env.knowledge import draw_start_estimate
from roslan.env.navigation import VerticalEstimator
from roslan.errors import ConfigError
from roslan.frames import rpy_to_matrix

pytest.importorskip("roslan.render.gl")


def small_landing(**closed_loop: Any) -> dict[str, Any]:
    """The marker landing (tests/helpers) with a 0.05 m/s^2 accelerometer bias."""
    return marker_landing(closed_loop, accelerometer_bias_sigma=0.05)


SPREAD = {"position": [0.2, 0.2, 0.1], "rpy": [0.03, 0.03, 0.05], "descent_rate": 0.2}


def _numbers(obj: Any) -> list[float]:
    """Every number in a nested structure (pydantic models dumped, arrays flattened)."""
    if hasattr(obj, "model_dump"):
        return _numbers(obj.model_dump())
    if isinstance(obj, dict):
        return [x for v in obj.values() for x in _numbers(v)]
    if isinstance(obj, (list, tuple)):
        return [x for v in obj for x in _numbers(v)]
    if isinstance(obj, np.ndarray):
        return [float(x) for x in obj.ravel()]
    if isinstance(obj, (int, float)) and not isinstance(obj, bool):
        return [float(obj)]
    if hasattr(obj, "__dataclass_fields__"):
        return [x for k in obj.__dataclass_fields__ for x in _numbers(getattr(obj, k))]
    return []


def test_no_number_in_the_policy_context_is_the_drawn_start() -> None:
    env = LandingEnv(small_landing(start_spread=SPREAD))
    try:
        env.reset(seed=5)
        ctx = env.policy_context()
        drawn = env.config.trajectory.initial
        assert drawn is not None
        assert env._traj is not None
        truth = env._traj.state([0.0])
        secret = [*drawn.position, *drawn.rpy, drawn.descent_rate]
        secret += [float(x) for x in truth.gaps[0]] + [float(x) for x in truth.rates[0]]
        secret += [float(x) for x in truth.position[0]] + [float(x) for x in truth.velocity[0]]
        secret += [float(x) for x in truth.R_world_body[0].ravel()]
        secret = [x for x in secret if abs(x) > 1e-12]  # the goal frame's zeros are public
        known = set(_numbers(ctx))
        assert known, "the context holds numbers"
        leaked = [x for x in secret if x in known]
        assert leaked == [], leaked
        # the context's config is the nominal one (as written), the episode's is the draw
        assert ctx.config.trajectory.initial == env.base_config.trajectory.initial
        assert ctx.config.trajectory.initial != drawn
    finally:
        env.close()


def test_tau_events_reads_only_the_observation_and_the_raw_events() -> None:
    """Two tau-events policies in lockstep, one given the full info, one only the raw
    events: the same actions, step after step."""
    env = LandingEnv(small_landing(start_spread=SPREAD))
    full, bare = make_policy("tau-events"), make_policy("tau-events")
    try:
        obs, info = env.reset(seed=2)
        full.reset(env.policy_context())
        bare.reset(env.policy_context())
        for _ in range(40):
            a = full.act(obs, info)
            b = bare.act(obs, {"events": info["events"]})
            np.testing.assert_array_equal(a, b)
            obs, _, term, trunc, info = env.step(a)
            if term or trunc:
                break
    finally:
        env.close()


def test_the_observation_carries_the_start_estimate_and_the_goal() -> None:
    env = LandingEnv(small_landing())
    try:
        obs, _ = env.reset(seed=1)
        ctx = env.policy_context()
        assert ctx.start_estimate is not None
        first = (obs["start_estimate"].copy(), obs["goal"].copy())
        np.testing.assert_array_equal(first[0], ctx.start_estimate.as_observation())
        np.testing.assert_allclose(first[1], [2.0, -1.0, 0.01, 0.0, 0.0, 0.3], atol=1e-6)
        assert obs in env.observation_space
        for _ in range(3):
            obs, *_ = env.step(np.zeros(6))
            np.testing.assert_array_equal(obs["start_estimate"], first[0])
            np.testing.assert_array_equal(obs["goal"], first[1])
        # the default error is not zero: the estimate is not the true start
        assert env._traj is not None
        true_gaps = env._traj.state([0.0]).gaps[0]
        assert not np.allclose(first[0][:3], true_gaps[:3], atol=1e-3)
    finally:
        env.close()


def _reference_traj() -> DynamicsTrajectory:
    from roslan.config.closed_loop import Dynamics
    from roslan.trajectory import TrajectoryConfig

    cfg = TrajectoryConfig.model_validate(small_landing()["trajectory"])
    return DynamicsTrajectory(cfg, Dynamics(), 20_000_000)


def test_start_estimate_errors_have_the_configured_spread_and_zero_is_the_truth() -> None:
    traj = _reference_traj()
    truth = traj.state([0.0])
    exact = draw_start_estimate(
        traj, StartEstimateConfig(position_sigma=0, velocity_sigma=0, attitude_sigma=0), 3
    )
    np.testing.assert_allclose(exact.position, truth.position[0], atol=1e-12)
    np.testing.assert_allclose(exact.velocity, truth.velocity[0], atol=1e-12)
    np.testing.assert_allclose(exact.R_world_body, truth.R_world_body[0], atol=1e-12)
    np.testing.assert_allclose(exact.gaps, truth.gaps[0], atol=1e-9)
    cfg = StartEstimateConfig(position_sigma=0.3, velocity_sigma=0.1, attitude_sigma=0.02)
    draws = [draw_start_estimate(traj, cfg, s) for s in range(600)]
    dp = np.array([d.position - truth.position[0] for d in draws])
    dv = np.array([d.velocity - truth.velocity[0] for d in draws])
    R0 = truth.R_world_body[0]
    ang = np.array(
        [math.acos(np.clip((np.trace(R0.T @ d.R_world_body) - 1) / 2, -1, 1)) for d in draws]
    )
    assert np.allclose(dp.std(axis=0), 0.3, rtol=0.12)
    assert np.allclose(dv.std(axis=0), 0.1, rtol=0.12)
    # the angle of three independent N(0, s^2) body-axis rotations: rms s sqrt(3)
    assert math.sqrt(np.mean(ang**2)) == pytest.approx(0.02 * math.sqrt(3), rel=0.12)
    # its own generator: the same seed, the same draw
    again = draw_start_estimate(traj, cfg, 7)
    np.testing.assert_array_equal(again.position, draws[7].position)


def test_a_negative_sigma_is_a_config_error_naming_the_key() -> None:
    with pytest.raises(ConfigError, match="start_estimate"):
        LandingEnv(small_landing(start_estimate={"position_sigma": -1.0}))


def test_tau_events_refuses_a_perch_with_a_clear_message() -> None:
    env = LandingEnv(PERCHING_CONFIG)
    try:
        env.reset(seed=0)
        with pytest.raises(ConfigError, match=r"not on the ground plane.*perch"):
            make_policy("tau-events").reset(env.policy_context())
    finally:
        env.close()


def test_attitude_filter_corrects_a_wrong_start_and_estimates_the_gyro_bias() -> None:
    """At rest, a filter started 0.1 rad off in roll and pitch, with a gyro biased by
    0.01 rad/s: the accelerometer brings roll and pitch back; the bias is learnt."""
    R_true = rpy_to_matrix(np.array([0.02, -0.03, 0.5]))
    f = R_true.T @ np.array([0.0, 0.0, 9.81])
    bias = np.array([0.01, -0.01, 0.0])
    filt = AttitudeFilter(R_true @ expm_so3(np.array([0.1, -0.1, 0.0])), kp=2.0, ki=0.5)
    rng = np.random.default_rng(0)
    for _ in range(20_000):  # 20 s at 1 kHz
        gyro = bias + 1e-3 * rng.standard_normal(3)
        filt.update(gyro, f + 0.01 * rng.standard_normal(3), 1e-3, np.zeros(3))
    g_est = filt.R.T @ np.array([0.0, 0.0, 1.0])
    g_true = R_true.T @ np.array([0.0, 0.0, 1.0])
    assert math.acos(min(1.0, float(g_est @ g_true))) < 2e-3
    np.testing.assert_allclose(filt.bias[:2], bias[:2], atol=2e-3)
    # a gated sample (the specific force far from the expected one) corrects nothing
    before = filt.corrected
    filt.update(np.zeros(3), 3.0 * f, 1e-3, np.zeros(3))
    assert filt.corrected == before


def test_vertical_estimator_recovers_the_start_errors_and_the_bias_from_divergence() -> None:
    """A braking descent; the dead reckoning starts 0.4 m and 0.15 m/s wrong with an
    accelerometer bias of 0.06 m/s^2; exact divergences bring all three most of the way
    back (the priors, weak but not nothing, hold them a little)."""
    z0, v0, b_true = 3.0, -1.5, 0.06
    c0_err, dv_err = 0.4, 0.15
    est = VerticalEstimator(z0 + c0_err, 0.5, 0.2, 0.1)
    t = np.linspace(0.0, 2.5, 120)
    a = 0.5  # braking, m/s^2
    h = z0 + v0 * t + 0.5 * a * t * t
    v = v0 + a * t
    # the dead reckoning: started at the estimate, integrating the biased accelerometer
    v_dr = (v0 + dv_err) + (a + b_true) * t
    p_dr = (v0 + dv_err) * t + 0.5 * (a + b_true) * t * t
    o = 0.05
    for i in range(t.size):
        est.add(-v[i] / (h[i] + o), float(t[i]), float(p_dr[i]), float(v_dr[i]), o)
    c0, dv, b = est.theta
    assert abs(c0 + z0) < 0.08  # from 0.4
    assert abs(dv - dv_err) < 0.05  # from 0.15
    assert abs(b - b_true) < 0.03  # from 0.06
    assert est.accepted == t.size
    assert est.rejected == 0
    # at the end (the dead reckoning alone is 0.96 m off in height)
    t1, p1, v1 = float(t[-1]), float(p_dr[-1]), float(v_dr[-1])
    assert est.height(t1, p1) == pytest.approx(h[-1], abs=0.1)
    assert est.velocity(t1, v1) == pytest.approx(v[-1], abs=0.05)


def test_vertical_estimator_takes_the_markers_heights_over_a_biased_divergence() -> None:
    """The same descent with divergences whose scale is 25 % short (the early sideways
    flight's): the marker's heights (2 % noise) over the last second bring the height
    and the vertical speed back; without them both stay wrong."""
    z0, v0, b_true = 3.0, -1.5, 0.06
    t = np.linspace(0.0, 2.5, 120)
    a = 0.5
    h = z0 + v0 * t + 0.5 * a * t * t
    v = v0 + a * t
    v_dr = (v0 + 0.15) + (a + b_true) * t
    p_dr = (v0 + 0.15) * t + 0.5 * (a + b_true) * t * t
    rng = np.random.default_rng(2)
    ests = [VerticalEstimator(z0 + 0.4, 0.5, 0.2, 0.1) for _ in range(2)]
    for i in range(t.size):
        for est in ests:
            est.add(-v[i] / (0.75 * h[i]), float(t[i]), float(p_dr[i]), float(v_dr[i]), 0.0)
        if t[i] >= 1.5:
            meas = h[i] * (1.0 + 0.02 * rng.standard_normal())
            assert ests[1].add_height(float(meas), float(t[i]), float(p_dr[i]), 0.02 * h[i])
    t1, p1, v1 = float(t[-1]), float(p_dr[-1]), float(v_dr[-1])
    assert ests[1].heights == int(np.count_nonzero(t >= 1.5))
    assert ests[1].height(t1, p1) == pytest.approx(h[-1], rel=0.05)
    assert ests[1].velocity(t1, v1) == pytest.approx(v[-1], abs=0.08)
    assert abs(ests[0].height(t1, p1) / h[-1] - 1.0) > 0.1  # divergence alone: scale short


def test_the_constant_entries_keep_their_space_and_refuse_another_shape() -> None:
    from roslan.config.closed_loop import ClosedLoopConfig
    from roslan.env.knowledge import CONSTANT_SHAPES
    from roslan.env.observe import ObservationBuilder

    ob = ObservationBuilder([], ClosedLoopConfig())
    for key, shape in CONSTANT_SHAPES.items():
        ob.constant(key, np.zeros(shape))
    space = ob.space
    ob.constant("goal", np.arange(6.0))  # a new episode's value: the same space
    assert ob.space is space
    obs = ob.build({}, (0, 20_000_000))
    np.testing.assert_array_equal(obs["goal"], np.arange(6.0, dtype=np.float32))
    obs["goal"][0] = 99.0  # each step's array is the caller's
    assert ob.build({}, (0, 20_000_000))["goal"][0] == 0.0
    with pytest.raises(ValueError, match="'goal': shape"):
        ob.constant("goal", np.zeros(5))
