"""Rotation helpers and the Euler-rate kinematics (docs/design.md §2)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from roslan.frames import (
    R_LINK_OPTICAL,
    T_LINK_OPTICAL,
    euler_rates_to_body_acceleration,
    euler_rates_to_body_rates,
    euler_zyx_kinematics,
    matrix_to_quat_xyzw,
    matrix_to_rpy,
    quat_multiply,
    quat_xyzw_to_matrix,
    rotation_log,
    rpy_to_matrix,
    rpy_to_quat_xyzw,
)
from roslan.trajectory import TauTrajectory, Trajectory, TrajectoryConfig, TrajectoryWarning


def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _exp(v: np.ndarray) -> np.ndarray:
    """Rodrigues' formula, written independently of the library."""
    th = float(np.linalg.norm(v))
    if th < 1e-15:
        return np.eye(3)
    k = v / th
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(th) * K + (1 - math.cos(th)) * K @ K


angles = st.tuples(st.floats(-math.pi, math.pi), st.floats(-1.5, 1.5), st.floats(-math.pi, math.pi))


@settings(max_examples=80, deadline=None)
@given(angles)
def test_rpy_matrix_is_zyx_product_and_round_trips(rpy: tuple[float, float, float]) -> None:
    r, p, y = rpy
    R = rpy_to_matrix(np.array(rpy))
    np.testing.assert_allclose(R, _rz(y) @ _ry(p) @ _rx(r), atol=1e-14)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-14)
    back = matrix_to_rpy(R)
    np.testing.assert_allclose(rpy_to_matrix(back), R, atol=1e-12)
    np.testing.assert_allclose(back, rpy, atol=1e-8)


@settings(max_examples=80, deadline=None)
@given(arrays(np.float64, 4, elements=st.floats(-1, 1)).filter(lambda q: np.linalg.norm(q) > 0.1))
def test_quaternion_matrix_round_trip(q: np.ndarray) -> None:
    q = q / np.linalg.norm(q)
    R = quat_xyzw_to_matrix(q)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-13)
    assert np.linalg.det(R) > 0
    q2 = matrix_to_quat_xyzw(R)
    assert q2[3] >= 0
    assert abs(float(np.dot(q2, q))) == pytest.approx(1.0, abs=1e-12)  # same up to sign
    if q[3] > 1e-6:
        np.testing.assert_allclose(q2, q, atol=1e-12)
    # rotating a vector by the matrix equals q v q*
    v = np.array([0.3, -1.2, 2.0])
    qv = quat_multiply(quat_multiply(q, np.array([*v, 0.0])), q * np.array([-1, -1, -1, 1]))
    np.testing.assert_allclose(qv[:3], R @ v, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(angles)
def test_rpy_quaternion_agrees_with_matrix(rpy: tuple[float, float, float]) -> None:
    q = rpy_to_quat_xyzw(np.array(rpy))
    assert q[3] >= 0
    np.testing.assert_allclose(quat_xyzw_to_matrix(q), rpy_to_matrix(np.array(rpy)), atol=1e-13)


@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, 3, elements=st.floats(-3.1, 3.1)))
def test_rotation_log_inverts_exp(v: np.ndarray) -> None:
    if np.linalg.norm(v) >= math.pi:
        v = v / np.linalg.norm(v) * 3.1
    np.testing.assert_allclose(rotation_log(_exp(v)), v, atol=1e-9)


def test_rotation_log_near_pi_and_identity() -> None:
    v = np.array([0.0, 0.0, math.pi - 1e-9])
    np.testing.assert_allclose(np.abs(rotation_log(_exp(v))), np.abs(v), atol=1e-6)
    np.testing.assert_allclose(rotation_log(np.eye(3)), 0.0, atol=0)


def _traj(**kw: object) -> Trajectory:
    base = {
        "k": 0.45,
        "kappa": {"roll": 0.6, "pitch": 0.8, "yaw": 1.2},
        "initial": {"position": [-3.0, 1.0, 3.0], "rpy": [0.6, -0.5, 2.0], "descent_rate": 1.0},
        "goal": {"position": [1.0, 2.0, 3.0], "rpy": [0.3, -0.2, 0.9]},
    }
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TrajectoryWarning)
        return TauTrajectory(TrajectoryConfig.model_validate({**base, **kw}))


def test_body_rates_match_log_map_of_finite_rotation() -> None:
    """omega_body = log(R(t)^T R(t+h)) / h, both for F-relative and world orientation."""
    for tr in (_traj(), _traj(flapping={"frequency": 4.0, "pitch": 0.3})):
        h = 1e-6
        t = np.linspace(0.01, 0.95 * tr.T, 25)
        a, b = tr.state(t - h), tr.state(t + h)
        rel = np.einsum("nji,njk->nik", a.R_world_body, b.R_world_body)
        np.testing.assert_allclose(rotation_log(rel) / (2 * h), tr.state(t).omega_body, atol=1e-6)


def test_fused_kinematics_equals_reference_helpers() -> None:
    rng = np.random.default_rng(3)
    rpy = rng.uniform(-3, 3, (500, 3))
    rpy[:, 1] = rng.uniform(-1.5, 1.5, 500)
    d1, d2 = rng.normal(size=(500, 3)), rng.normal(size=(500, 3))
    for q_ref_rpy in (None, [0.0, 0.0, 2.5], [0.4, -0.3, 1.0]):
        q_ref = None if q_ref_rpy is None else rpy_to_quat_xyzw(np.array(q_ref_rpy))
        quat, R, w, al = euler_zyx_kinematics(rpy, d1, d2, q_ref)
        R_ref = rpy_to_matrix(rpy)
        if q_ref_rpy is not None:
            R_ref = rpy_to_matrix(np.array(q_ref_rpy)) @ R_ref
        np.testing.assert_allclose(R, R_ref, atol=1e-13)
        np.testing.assert_allclose(quat_xyzw_to_matrix(quat), R_ref, atol=1e-13)
        assert np.all(quat[:, 3] >= 0)
        np.testing.assert_allclose(w, euler_rates_to_body_rates(rpy, d1), atol=1e-13)
        np.testing.assert_allclose(al, euler_rates_to_body_acceleration(rpy, d1, d2), atol=1e-12)


def test_body_rates_formula_against_matrix_derivative() -> None:
    """Independent check: [w]x = R^T dR/dt with dR/dt by central differences."""
    rng = np.random.default_rng(0)
    rpy = rng.uniform(-1.2, 1.2, (20, 3))
    d = rng.normal(size=(20, 3))
    h = 1e-6
    dR = (rpy_to_matrix(rpy + h * d) - rpy_to_matrix(rpy - h * d)) / (2 * h)
    W = np.einsum("nji,njk->nik", rpy_to_matrix(rpy), dR)
    w_fd = np.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], axis=1)
    np.testing.assert_allclose(euler_rates_to_body_rates(rpy, d), w_fd, atol=1e-8)


def test_goal_frame_world_round_trip() -> None:
    tr = _traj()
    t = np.linspace(0, tr.T, 50)
    s = tr.state(t)
    R_wg = rpy_to_matrix(np.array(tr.config.goal.rpy))
    p_wg = np.array(tr.config.goal.position)
    # world -> F recovers the gaps; orientation in F recovers roll/pitch/yaw
    np.testing.assert_allclose((s.position - p_wg) @ R_wg, s.gaps[:, :3], atol=1e-12)
    R_gb = np.einsum("ji,njk->nik", R_wg, s.R_world_body)
    np.testing.assert_allclose(matrix_to_rpy(R_gb), s.gaps[:, 3:], atol=1e-10)
    np.testing.assert_allclose(s.velocity @ R_wg, s.rates[:, :3], atol=1e-12)


def test_optical_frame_axes() -> None:
    # body x (forward) is optical z, body y (left) is optical -x, body z (up) is optical -y
    R_optical_link = R_LINK_OPTICAL.T
    np.testing.assert_array_equal(R_optical_link @ [1, 0, 0], [0, 0, 1])
    np.testing.assert_array_equal(R_optical_link @ [0, 1, 0], [-1, 0, 0])
    np.testing.assert_array_equal(R_optical_link @ [0, 0, 1], [0, -1, 0])
    # the pose of the optical frame in the link frame: the same rotation, no offset
    np.testing.assert_array_equal(T_LINK_OPTICAL[:3, :3], R_LINK_OPTICAL)
    np.testing.assert_array_equal(T_LINK_OPTICAL[:3, 3], 0.0)
    np.testing.assert_array_equal(T_LINK_OPTICAL[3], [0, 0, 0, 1])
