"""Tau-theory generator: independent checks of the closed form (docs/design.md §1)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from roslan.trajectory import (
    TauTrajectory,
    Terminal,
    Trajectory,
    TrajectoryConfig,
    TrajectoryWarning,
)
from roslan.trajectory.tau import S_FLOOR


def make(**kw: object) -> Trajectory:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TrajectoryWarning)
        return TauTrajectory(TrajectoryConfig.model_validate(kw))


BASE = {
    "k": 0.4,
    "kappa": {"x": 0.8, "y": 0.6, "roll": 0.9, "pitch": 0.7, "yaw": 1.1},
    "initial": {"position": [-6.0, 3.0, 5.0], "rpy": [0.2, -0.3, 0.8], "descent_rate": 1.5},
}


@pytest.mark.parametrize("k", [0.2, 0.4, 0.5, 0.7, 0.9])
def test_closed_form_matches_integrated_constant_tau_dot(k: float) -> None:
    """Integrate z' = z / tau with tau' = k (tau = tau0 + k t) and compare with the closed form."""
    z0, v0 = 4.0, 1.7
    tr = make(k=k, initial={"position": [1.0, 1.0, z0], "descent_rate": v0})
    tau0 = -z0 / v0  # tau = z / z' at t = 0
    assert tr.tau0 == pytest.approx(tau0, rel=1e-12)
    assert pytest.approx(-tau0 / k, rel=1e-12) == tr.T

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        tau = tau0 + k * t
        return np.array([y[0] / tau])

    t_eval = np.linspace(0.0, 0.9 * tr.T, 50)
    sol = solve_ivp(rhs, (0.0, t_eval[-1]), [z0], t_eval=t_eval, rtol=1e-11, atol=1e-12)
    assert sol.success
    st_ = tr.state(t_eval)
    np.testing.assert_allclose(st_.gaps[:, 2], sol.y[0], rtol=1e-7, atol=1e-9)
    # tau-dot of the closed form is k
    tau = st_.gaps[:, 2] / st_.rates[:, 2]
    np.testing.assert_allclose(np.gradient(tau, t_eval), k, rtol=1e-6)
    assert st_.rates[0, 2] == pytest.approx(-v0)


def test_coupled_gaps_tau_ratio_and_closure() -> None:
    tr = make(**BASE)
    t = np.linspace(0.0, 0.95 * tr.T, 200)
    s = tr.state(t)
    tau_z = s.gaps[:, 2] / s.rates[:, 2]
    kap = {"x": 0.8, "y": 0.6, "roll": 0.9, "pitch": 0.7, "yaw": 1.1}
    for i, name in enumerate(("x", "y", "z", "roll", "pitch", "yaw")):
        if name == "z":
            continue
        tau_g = s.gaps[:, i] / s.rates[:, i]
        np.testing.assert_allclose(tau_g, kap[name] * tau_z, rtol=1e-10)
    end = tr.state([tr.T])
    assert np.all(end.gaps[0] == 0.0)
    np.testing.assert_allclose(end.rates[0], 0.0, atol=0.0)  # every k*kappa < 1 here


def _central(f: np.ndarray, h: float) -> np.ndarray:
    return (f[2:] - f[:-2]) / (2.0 * h)


@pytest.mark.parametrize(
    "extra",
    [
        {},
        {"goal": {"position": [3.0, -2.0, 1.0], "rpy": [0.1, -0.2, 1.3]}},
        {"flapping": {"frequency": 3.0, "heave": 0.3, "pitch": 0.2, "phase": 0.4}},
    ],
    ids=["F", "world", "flapping"],
)
def test_finite_differences_match_analytic_rates(extra: dict[str, object]) -> None:
    tr = make(**{**BASE, **extra})
    h = 1e-5
    t = np.linspace(0.05, 0.9 * tr.T, 40)
    tt = np.stack([t - h, t, t + h], axis=1).ravel()
    s = tr.state(tt)
    n = t.size

    def fd(arr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        a = arr.reshape(n, 3, -1)
        return (a[:, 2] - a[:, 0]) / (2 * h), (a[:, 2] - 2 * a[:, 1] + a[:, 0]) / (h * h)

    mid = s.gaps.reshape(n, 3, 6)[:, 1]
    d1, d2 = fd(s.gaps)
    rates = s.rates.reshape(n, 3, 6)[:, 1]
    accels = s.accels.reshape(n, 3, 6)[:, 1]
    np.testing.assert_allclose(d1, rates, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(d2, accels, rtol=2e-3, atol=2e-4)
    assert np.abs(mid).max() > 0
    # world frame position -> velocity -> acceleration
    v1, a2 = fd(s.position)
    np.testing.assert_allclose(v1, s.velocity.reshape(n, 3, 3)[:, 1], rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(a2, s.acceleration.reshape(n, 3, 3)[:, 1], rtol=2e-3, atol=2e-4)
    vv, _ = fd(s.velocity)
    np.testing.assert_allclose(vv, s.acceleration.reshape(n, 3, 3)[:, 1], rtol=1e-6, atol=1e-6)


def test_angular_acceleration_matches_finite_differences() -> None:
    tr = make(**BASE, flapping={"frequency": 2.0, "pitch": 0.3})
    h = 1e-5
    t = np.linspace(0.05, 0.9 * tr.T, 30)
    a = tr.state(t - h).omega_body
    b = tr.state(t + h).omega_body
    np.testing.assert_allclose((b - a) / (2 * h), tr.state(t).alpha_body, rtol=1e-6, atol=1e-6)


def test_world_frame_consistent_with_goal_pose() -> None:
    goal = {"position": [10.0, 5.0, 0.5], "rpy": [0.0, 0.0, 1.57]}
    tr = make(**BASE, goal=goal)
    t = np.linspace(0.0, tr.T, 30)
    s = tr.state(t)
    c, sn = math.cos(1.57), math.sin(1.57)
    Rz = np.array([[c, -sn, 0.0], [sn, c, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(s.position, s.gaps[:, :3] @ Rz.T + goal["position"], atol=1e-12)
    np.testing.assert_allclose(s.position[-1], goal["position"], atol=1e-12)
    # at touchdown the body is aligned with the goal frame
    np.testing.assert_allclose(s.R_world_body[-1], Rz, atol=1e-12)


def test_hold_and_clamping() -> None:
    tr = make(**BASE, hold=0.5)
    assert tr.duration == pytest.approx(tr.T + 0.5)
    s = tr.state([-1.0, 0.0, tr.T + 0.25, tr.duration + 3.0])
    np.testing.assert_array_equal(s.gaps[0], s.gaps[1])
    assert np.all(s.rates[0] == 0.0)
    assert np.all(s.gaps[2:] == 0.0)
    assert np.all(s.rates[2:] == 0.0)
    np.testing.assert_allclose(s.position[2], tr.config.goal.position)


def test_table_times_end_exactly_at_T_then_hold() -> None:
    tr = make(**BASE, sample_dt=0.1, hold=0.35)
    t = tr.table_times()
    assert t[0] == 0.0
    assert np.all(np.diff(t) > 0)
    assert tr.T in t
    i = int(np.flatnonzero(t == tr.T)[0])
    np.testing.assert_allclose(t[:i], np.arange(i) * 0.1, atol=1e-12)
    assert t[i] - t[i - 1] <= 0.1 + 1e-12
    assert t[-1] == tr.duration
    assert np.all(np.diff(t[i:]) <= 0.1 + 1e-12)


def test_approach_spec_gives_initial_speed() -> None:
    for heading in (0.0, 0.7, -2.0):
        tr = make(
            k=0.5,
            kappa={"x": 0.7, "y": 0.9},
            approach={"distance": 10.0, "angle": math.pi / 6, "heading": heading, "speed": 4.0},
            goal={"position": [1.0, 2.0, 0.0], "rpy": [0.0, 0.0, 0.4]},
        )
        s = tr.state([0.0])
        assert np.linalg.norm(s.velocity[0]) == pytest.approx(4.0, rel=1e-12)
        g = s.gaps[0]
        assert np.linalg.norm(g[:3]) == pytest.approx(10.0, rel=1e-12)
        assert g[2] == pytest.approx(10.0 * math.sin(math.pi / 6))
        # the robot starts behind the goal along its heading and flies towards it
        horiz_v = s.rates[0, :2]
        assert np.dot(horiz_v, -g[:2]) > 0
        assert math.atan2(-g[1], -g[0]) == pytest.approx(
            math.atan2(math.sin(heading), math.cos(heading))
        )


@pytest.mark.parametrize(
    ("k", "kx", "expected_z", "expected_x"),
    [
        (0.5, 0.5, Terminal.CONSTANT_DECELERATION, Terminal.SOFT),
        (0.4, 1.25, Terminal.SOFT, Terminal.CONSTANT_DECELERATION),
        (0.7, 1.0, Terminal.UNBOUNDED_DECELERATION, Terminal.UNBOUNDED_DECELERATION),
        (0.5, 2.0, Terminal.CONSTANT_DECELERATION, Terminal.NONZERO_RATE),
    ],
)
def test_terminal_classification_and_warnings(
    k: float, kx: float, expected_z: Terminal, expected_x: Terminal
) -> None:
    cfg = TrajectoryConfig.model_validate({**BASE, "k": k, "kappa": {"x": kx}})
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        tr = TauTrajectory(cfg)
    assert tr.terminal["z"] is expected_z
    assert tr.terminal["x"] is expected_x
    texts = [str(w.message) for w in rec if issubclass(w.category, TrajectoryWarning)]
    assert any(t.startswith("z gap") for t in texts) == (
        expected_z is Terminal.UNBOUNDED_DECELERATION
    )
    assert any(t.startswith("x gap") for t in texts) == (
        expected_x in (Terminal.UNBOUNDED_DECELERATION, Terminal.NONZERO_RATE)
    )
    s = tr.state([tr.T])
    assert np.isfinite(s.components()).all()


def test_zero_gap_is_none_and_stays_zero() -> None:
    tr = make(
        **{**BASE, "initial": {"position": [0.0, 2.0, 3.0], "rpy": [0, 0, 0], "descent_rate": 1}}
    )
    assert tr.terminal["x"] is Terminal.NONE
    assert tr.terminal["roll"] is Terminal.NONE
    s = tr.state(np.linspace(0, tr.T, 11))
    assert np.all(s.gaps[:, 0] == 0.0)
    assert np.all(s.omega_body == 0.0)


def test_summary_fields() -> None:
    tr = make(**BASE)
    summ = tr.summary()
    assert summ["T"] == tr.T
    assert summ["tau0"] == pytest.approx(-tr.k * tr.T)
    assert summ["kappa"]["pitch"] == 0.7
    assert set(summ["terminal"]) == {"x", "y", "z", "roll", "pitch", "yaw"}
    t = np.linspace(0, tr.T, 4001)
    sp = np.linalg.norm(tr.state(t).velocity, axis=1)
    assert summ["peak_speed"] == pytest.approx(sp.max(), rel=1e-3)
    assert summ["peak_deceleration"] > 0
    unb = make(**{**BASE, "k": 0.7}).summary()
    assert unb["peak_deceleration"] is None
    assert unb["terminal"]["z"] == "unbounded_deceleration"


# ---------------------------------------------------------------- property tests
@st.composite
def configs(draw: st.DrawFn) -> dict[str, object]:
    k = draw(st.floats(0.02, 0.98))
    kap = {}
    for name in ("x", "y", "roll", "pitch", "yaw"):
        kap[name] = draw(st.floats(0.05, 1.0)) / k  # k*kappa in (0, 1]
    # gaps below a nanometre are zero here: a subnormal gap's g'' underflows to 0 in float64
    xy = [draw(st.floats(-50, 50, allow_subnormal=False)) for _ in range(2)]
    pos = [*(g if abs(g) >= 1e-9 else 0.0 for g in xy), draw(st.floats(0.01, 50))]
    rpy = [draw(st.floats(-1.5, 1.5, allow_subnormal=False)) for _ in range(3)]
    rpy = [a if abs(a) >= 1e-9 else 0.0 for a in rpy]
    return {
        "k": k,
        "kappa": kap,
        "initial": {"position": pos, "rpy": rpy, "descent_rate": draw(st.floats(0.05, 20))},
    }


@settings(max_examples=60, deadline=None)
@given(configs())
def test_property_finite_monotone_terminal(cfg: dict[str, object]) -> None:
    tr = make(**cfg)
    t = np.concatenate([np.linspace(0.0, tr.T, 257), [tr.T, tr.T * (1 - 1e-12)]])
    s = tr.state(t)
    for arr in (
        s.components(),
        s.position,
        s.velocity,
        s.acceleration,
        s.quat_xyzw,
        s.omega_body,
        s.alpha_body,
    ):
        assert np.isfinite(arr).all()
    z = s.gaps[:257, 2]
    assert np.all(np.diff(z) <= 0.0)  # height closes monotonically
    assert np.all(s.rates[:257, 2] <= 0.0)
    end = tr.state([tr.T])
    assert np.all(end.gaps == 0.0)
    # the classification matches the numbers near touchdown
    s_small = 1e-6
    near = tr.state([tr.T * (1 - s_small), tr.T * (1 - s_small / 4)])
    for i, g in enumerate(("x", "y", "z", "roll", "pitch", "yaw")):
        term = tr.terminal[g]
        rate_end, acc_a, acc_b = end.rates[0, i], abs(near.accels[0, i]), abs(near.accels[1, i])
        g0 = tr.initial_gaps[i]
        if term is Terminal.NONE:
            assert g0 == 0.0
        elif term is Terminal.NONZERO_RATE:
            assert abs(rate_end) == pytest.approx(abs(g0) / (tr.k * tr.kappas[i] * tr.T), rel=1e-6)
        else:
            assert rate_end == 0.0
            if term is Terminal.UNBOUNDED_DECELERATION:
                assert acc_b > acc_a  # |g''| grows as s -> 0
            elif term is Terminal.CONSTANT_DECELERATION:
                assert acc_b == pytest.approx(acc_a, rel=1e-9)
            else:
                assert acc_b <= acc_a


def test_floor_is_finite_for_hard_landing_at_T() -> None:
    tr = make(**{**BASE, "k": 0.9})
    s = tr.state([tr.T])
    assert np.isfinite(s.accels).all()
    # the value at T equals the value S_FLOOR * T before it
    before = tr.state([tr.T * (1 - S_FLOOR)])
    assert s.accels[0, 2] == pytest.approx(before.accels[0, 2], rel=1e-6)


def test_state_ns_matches_seconds() -> None:
    tr = make(**BASE)
    t_ns = np.array([0, 123_456_789, tr.touchdown_ns], dtype=np.int64)
    a = tr.state_ns(t_ns)
    b = tr.state(t_ns * 1e-9)
    np.testing.assert_array_equal(a.position, b.position)


def test_default_job_flaps_in_the_imu_pitch_rate() -> None:
    """The packaged default job flaps: the IMU's pitch rate (noise-free readings of its
    mount plus the configured white gyro noise) has a spectral peak at the flapping
    frequency at least 10x the spectrum around it (0.5 f .. 1.5 f, the peak's own +-1 Hz
    excluded); its frame camera exposes for a positive time."""
    from roslan.cli.simulate import load_config
    from roslan.sensors.imu import imu_measurements
    from roslan.vehicle import base_link_trajectory

    cfg, _ = load_config(None)
    flap = cfg.trajectory.flapping
    assert flap.frequency > 0
    assert flap.pitch > 0
    traj = TauTrajectory(base_link_trajectory(cfg.trajectory, cfg.vehicle), warn=False)
    imu = next(s for s in cfg.sensors if s.type == "imu")
    rate = float(imu.rate)
    t_ns = np.arange(0, int(traj.T * 1e9), int(1e9 / rate), dtype=np.int64)
    _, gyro, _ = imu_measurements(traj, t_ns, imu.pose.matrix(), imu.gravity)
    rng = np.random.default_rng(0)
    sigma = imu.gyroscope_noise_density * np.sqrt(rate)  # discrete white-noise std
    q = gyro[:, 1] + rng.normal(0.0, sigma, t_ns.size)  # pitch rate: the IMU's y axis
    spec = np.abs(np.fft.rfft((q - q.mean()) * np.hanning(q.size)))
    f = np.fft.rfftfreq(q.size, 1.0 / rate)
    f0 = flap.frequency
    near = np.abs(f - f0) <= 0.5
    peak_f = f[near][np.argmax(spec[near])]
    assert abs(peak_f - f0) <= 0.25
    hood = (f >= 0.5 * f0) & (f <= 1.5 * f0) & (np.abs(f - f0) > 1.0)
    assert spec[near].max() >= 10.0 * np.median(spec[hood])
    assert spec[near].max() >= 10.0 * spec[hood].max() / 3.0  # no rival line nearby
    cam = next(s for s in cfg.sensors if s.type == "camera")
    assert cam.exposure_time > 0


@pytest.mark.parametrize(
    "extra",
    [
        {},
        {"flapping": {"frequency": 3.0, "heave": 0.3, "pitch": 0.2, "phase": 0.4}},
        {"goal": {"position": [1.0, 2.0, 0.5], "rpy": [0.1, -0.2, 0.7]}},
        {"goal": {"position": [1.0, 2.0, 0.5], "rpy": [0.0, 0.0, 0.7]}, "hold": 0.5},
        {"k": 0.8},
        {"k": 0.5, "kappa": {"x": 1.0, "y": 2.0, "roll": 1.0, "pitch": 1.0, "yaw": 1.0}},
        {"k": 0.25, "kappa": {"x": 2.0, "y": 4.0, "roll": 1.0, "pitch": 1.0, "yaw": 1.0}},
    ],
    ids=["F", "flapping", "tilted-goal", "yawed-goal-hold", "hard", "n1-n2", "n2-n1"],
)
def test_pose_twist_at_one_instant_equals_state_bit_for_bit(extra: dict[str, object]) -> None:
    """The one-instant fast path (the event camera's per-step pose) gives exactly the
    values of the vectorized state, before the start, through touchdown and the hold."""
    tr = make(**{**BASE, **extra})
    assert isinstance(tr, TauTrajectory)
    T_ns, end = tr.touchdown_ns, tr.duration_ns
    rng = np.random.default_rng(3)
    ts = [*rng.integers(-(10**8), end + 10**8, 300).tolist(), 0, T_ns - 1, T_ns, T_ns + 1, end]
    for t in ts:
        st = tr.state_ns(np.array([t], dtype=np.int64))
        p, v, R, w = tr.pose_twist_ns(int(t))
        assert np.array_equal(p, st.position[0]), t
        assert np.array_equal(v, st.velocity[0]), t
        assert np.array_equal(R, st.R_world_body[0]), t
        assert np.array_equal(w, st.omega_body[0]), t
