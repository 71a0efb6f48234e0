"""The closed-loop vehicle model: its closed form inside a step against finite differences,
the horizon, and the tau closed form as a solution of it (tau-state, zero and default lag);
an IMU flown on it against the closed-form landing's IMU."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from pipeline_helpers import SHORT_TRAJECTORY
from roslan.config.closed_loop import ClosedLoopConfig, Dynamics
from roslan.config.sim import SimConfig
from roslan.env.dynamics import DynamicsTrajectory
from roslan.env.policies import PolicyContext, TauStatePolicy
from roslan.frames import body_rates_to_euler_rates, euler_rates_to_body_rates
from roslan.trajectory import TauTrajectory, TrajectoryConfig
from roslan.trajectory.base import HorizonError

STEP_NS = 20_000_000  # 50 Hz


def _config(lag: float | None, **traj: Any) -> SimConfig:
    dyn = {} if lag is None else {"acceleration_lag": lag, "body_rate_lag": lag}
    return SimConfig.model_validate(
        {"trajectory": {**SHORT_TRAJECTORY, **traj}, "closed_loop": {"dynamics": dyn}}
    )


def fly_tau_state(cfg: SimConfig) -> tuple[DynamicsTrajectory, int]:
    """Fly tau-state on the bare dynamics until the height gap closes; (traj, touchdown ns)."""
    assert cfg.closed_loop is not None
    traj = DynamicsTrajectory(cfg.trajectory, cfg.closed_loop.dynamics, STEP_NS)
    pol = TauStatePolicy()
    pol.reset(PolicyContext(cfg, STEP_NS * 1e-9, traj.R_world_goal, 20.0, 4.0))
    while traj.steps < 1000:
        ms = traj.mean_state()
        a = pol.act({}, {"state": {"gaps": ms.gaps, "rates": ms.rates, "accels": ms.accels}})
        t0 = traj.horizon_ns
        traj.step(a[:3], a[3:])
        t = np.linspace(t0, traj.horizon_ns, 2001)
        z = traj.gaps_at(t * 1e-9)[1][:, 2]
        below = np.flatnonzero(z <= 1e-12)
        if below.size:
            return traj, round(t[below[0]])
    raise AssertionError("no touchdown")


@pytest.mark.parametrize("flapping", [False, True], ids=["smooth", "flapping"])
def test_zero_lag_tau_state_reproduces_the_closed_form(flapping: bool) -> None:
    flap = {"frequency": 4.5, "heave": 0.008, "pitch": 0.035} if flapping else {}
    cfg = _config(0.0, flapping=flap)
    traj, td_ns = fly_tau_state(cfg)
    ref = TauTrajectory(cfg.trajectory, warn=False)
    assert abs(td_ns * 1e-9 - ref.T) < 0.01
    t = np.linspace(0.0, min(td_ns * 1e-9, ref.T), 400)
    a, b = traj.state(t), ref.state(t)
    assert np.abs(a.position - b.position).max() < 0.01  # 1 cm
    assert np.abs(a.gaps[:, 3:] - b.gaps[:, 3:]).max() < 0.01  # 0.01 rad
    vz = traj.gaps_at([td_ns * 1e-9])[2][0, 2]
    assert abs(vz) <= 0.05


def test_default_lag_touchdown_is_soft() -> None:
    cfg = _config(None)
    assert cfg.closed_loop is not None
    assert cfg.closed_loop.dynamics.acceleration_lag > 0
    traj, td_ns = fly_tau_state(cfg)
    vz = traj.gaps_at([td_ns * 1e-9])[2][0, 2]
    assert abs(vz) <= 0.2


def _random_flight(lag: float, seed: int, steps: int = 12) -> DynamicsTrajectory:
    cfg = _config(lag, flapping={"frequency": 3.0, "heave": 0.01, "pitch": 0.05})
    traj = DynamicsTrajectory(
        cfg.trajectory, Dynamics(acceleration_lag=lag, body_rate_lag=lag), STEP_NS
    )
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        traj.step(rng.uniform(-3, 3, 3), rng.uniform(-1, 1, 3))
    return traj


@pytest.mark.parametrize("lag", [0.0, 0.04])
def test_state_is_its_own_derivative_inside_steps(lag: float) -> None:
    """velocity = d position / dt, acceleration = d velocity / dt, omega from dR/dt."""
    traj = _random_flight(lag, 1)
    h = 1e-6
    # instants strictly inside steps (the zero-lag acceleration jumps at step starts)
    t = (np.arange(11) + 0.37) * STEP_NS * 1e-9
    s0, s1, sm = traj.state(t - h), traj.state(t + h), traj.state(t)
    vel = (s1.position - s0.position) / (2 * h)
    np.testing.assert_allclose(vel, sm.velocity, atol=1e-5)
    acc = (s1.velocity - s0.velocity) / (2 * h)
    np.testing.assert_allclose(acc, sm.acceleration, atol=1e-4)
    dR = (s1.R_world_body - s0.R_world_body) / (2 * h)
    W = np.einsum("nji,njk->nik", sm.R_world_body, dR)  # R^T dR = [omega]x
    omega = np.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], axis=1)
    np.testing.assert_allclose(omega, sm.omega_body, atol=1e-5)


@pytest.mark.parametrize("lag", [0.0, 0.04])
def test_state_is_continuous_across_step_boundaries(lag: float) -> None:
    traj = _random_flight(lag, 2)
    tb = np.arange(1, 12) * STEP_NS * 1e-9
    eps = 1e-9
    a, b = traj.state(tb - eps), traj.state(tb + eps)
    np.testing.assert_allclose(a.position, b.position, atol=1e-8)
    if lag > 0:  # lagged actuators: velocity and body rates are continuous too
        np.testing.assert_allclose(a.velocity, b.velocity, atol=1e-7)
        np.testing.assert_allclose(a.omega_body, b.omega_body, atol=1e-6)


def test_commanded_body_rates_are_reached_with_zero_lag() -> None:
    """With no lag, a held body-rate command is the body rate at the step's start."""
    cfg = _config(0.0)
    traj = DynamicsTrajectory(
        cfg.trajectory, Dynamics(acceleration_lag=0, body_rate_lag=0), STEP_NS
    )
    cmd = np.array([0.3, -0.2, 0.5])
    traj.step(np.zeros(3), cmd)
    st = traj.state([1e-9])
    np.testing.assert_allclose(st.omega_body[0], cmd, atol=1e-6)
    np.testing.assert_allclose(st.acceleration[0], 0.0, atol=1e-12)


def test_reading_past_the_horizon_raises_until_finished() -> None:
    traj = _random_flight(0.03, 3, steps=3)
    traj.state([3 * STEP_NS * 1e-9])  # the horizon itself is readable
    with pytest.raises(HorizonError, match="past its horizon"):
        traj.state([3 * STEP_NS * 1e-9 + 1e-6])
    end = 2 * STEP_NS + 12345
    traj.finish(end)
    assert traj.finished
    assert traj.duration_ns == end + round(traj.hold * 1e9)
    rest = traj.state(np.linspace(end * 1e-9 + 1e-6, traj.duration, 5))
    at_end = traj.state([end * 1e-9])
    np.testing.assert_allclose(rest.position, np.repeat(at_end.position, 5, axis=0), atol=1e-12)
    assert np.all(rest.velocity == 0.0)
    with pytest.raises(HorizonError):
        traj.step(np.zeros(3), np.zeros(3))


@given(
    rpy=st.tuples(st.floats(-3.0, 3.0), st.floats(-1.3, 1.3), st.floats(-3.0, 3.0)),
    w=st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(-5, 5)),
)
def test_body_and_euler_rates_round_trip(rpy: tuple[float, ...], w: tuple[float, ...]) -> None:
    e = body_rates_to_euler_rates(np.array(rpy), np.array(w))
    back = euler_rates_to_body_rates(np.array(rpy), e)
    np.testing.assert_allclose(back, w, atol=1e-9 * (1 + max(map(abs, w))) / math.cos(rpy[1]) ** 2)


def test_imu_on_the_flown_landing_matches_the_closed_form_imu(tmp_path: Path) -> None:
    """An IMU sampling the zero-lag tau-state flight reads what it reads on the closed form
    (same seed, same noise): within the piecewise-constant command's error."""
    from roslan.pipeline.context import Context
    from roslan.sensors.imu import Imu, ImuConfig

    cfg = _config(0.0)
    traj, td_ns = fly_tau_state(cfg)
    traj.finish(td_ns)
    ref = TauTrajectory(TrajectoryConfig.model_validate({**SHORT_TRAJECTORY}), warn=False)
    imu_cfg = ImuConfig.model_validate({"type": "imu", "name": "imu", "rate": 200.0})
    out = {}
    for name, tr in (("flown", traj), ("closed", ref)):
        folder = tmp_path / name
        ctx = Context(tr, folder, seed=4, start_time_ns=10**18, sensors=[imu_cfg])
        imu = Imu(imu_cfg)
        for _ in imu.messages(ctx):
            pass
        imu.close(ctx)
        out[name] = np.loadtxt(folder / "imu.txt")
    a, b = out["flown"], out["closed"]
    n = min(len(a), len(b)) - 2  # the touchdown instants differ by < 1 sample
    assert n > 150
    np.testing.assert_allclose(a[:n, 0], b[:n, 0])
    # gyro: the Euler rates are held over each step
    np.testing.assert_allclose(a[:n, 4:7], b[:n, 4:7], atol=0.05)  # rad/s
    # specific force: each step holds the closed form's mean acceleration over the step,
    # so the step means agree (4 samples of 200 Hz per 50 Hz step)
    m = n // 4 * 4
    fa = a[:m, 1:4].reshape(-1, 4, 3).mean(axis=1)
    fb = b[:m, 1:4].reshape(-1, 4, 3).mean(axis=1)
    np.testing.assert_allclose(fa, fb, rtol=0.02, atol=0.05)  # m/s^2 (peak 20 m/s^2)


def test_closed_loop_block_is_left_out_of_simulate_dumps() -> None:
    assert "closed_loop" not in SimConfig().model_dump(mode="json")
    cfg = SimConfig.model_validate({"closed_loop": {"control_rate": 25}})
    assert cfg.model_dump(mode="json")["closed_loop"]["control_rate"] == 25.0
    assert ClosedLoopConfig().control_rate == 50.0


def test_long_flights_keep_every_step() -> None:
    """Past the buffers' first growth, every step's start state is still what the
    vehicle was at that step (read back at the step boundaries)."""
    cfg = _config(0.03)
    assert cfg.closed_loop is not None
    traj = DynamicsTrajectory(cfg.trajectory, cfg.closed_loop.dynamics, STEP_NS)
    rng = np.random.default_rng(7)
    seen = [traj.mean_state().gaps]
    for _ in range(150):
        traj.step(rng.uniform(-1, 1, 3), rng.uniform(-0.3, 0.3, 3))
        seen.append(traj.mean_state().gaps)
    t = np.arange(151) * STEP_NS * 1e-9
    np.testing.assert_allclose(traj.gaps_at(t)[1], np.asarray(seen), atol=1e-12)
