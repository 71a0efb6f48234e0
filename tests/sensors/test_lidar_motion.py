"""Motion distortion: every beam leaves from the pose at its own firing instant."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from range_helpers import FakeContext, LinearTrajectory, run_sensor, scene, vertical_wall_x
from roslan.config.base import Pose, validate_model
from roslan.sensors.beams import Lidar, LidarConfig, rays_in_world
from roslan.trajectory import TauTrajectory, TrajectoryConfig

WALL_X = 12.0


@pytest.mark.parametrize("firing_poses", ["interpolated", "exact"])
def test_lidar_moving_toward_wall_measures_each_column_at_its_instant(
    tmp_path: Path, firing_poses: str
) -> None:
    v = 15.0  # m/s toward the wall: 1.5 m closer by the end of a 10 Hz turn
    traj = LinearTrajectory((0.0, 0.0, 0.0), v=(v, 0.0, 0.0), duration=0.3)
    cfg = validate_model(
        LidarConfig,
        {"type": "lidar", "name": "velodyne", "noise_sigma": 0.0, "firing_poses": firing_poses},
    )
    lid = Lidar(cfg)
    ctx = FakeContext(scene(vertical_wall_x(WALL_X)), traj, tmp_path)
    msgs = run_sensor(lid, ctx)
    assert len(msgs) == 3
    caster = ctx.raycaster()
    for t0_ns in (0, 100_000_000):
        pts = lid.scan(traj, caster, t0_ns, ctx.rng("x"))
        t_fire = t0_ns * 1e-9 + pts["time"].astype(np.float64)
        # the sensor frame is only translated: a point's x is the wall's distance at its instant
        expected_x = WALL_X - v * t_fire
        assert pts.shape[0] > 10_000
        np.testing.assert_allclose(pts["x"], expected_x, atol=2e-4)
        # the effect is real: within one turn the wall comes 1.5 m closer
        assert np.ptp(expected_x) > 1.0
        # range along each beam: d / (cos(el) cos(az)) with the distance of its own instant
        r = np.sqrt(pts["x"] ** 2 + pts["y"] ** 2 + pts["z"] ** 2)
        cos_el_az = pts["x"] / r
        np.testing.assert_allclose(r * cos_el_az, expected_x, atol=2e-4)


def test_rotating_lidar_points_land_on_the_wall(tmp_path: Path) -> None:
    """Yawing at 4 rad/s (0.4 rad per turn): each point, put back in the world with the pose
    of its firing instant, lies on the wall."""
    yaw_rate = 4.0
    p0 = np.array([1.0, -0.5, 0.3])
    traj = LinearTrajectory(tuple(p0), v=(2.0, 1.0, 0.0), yaw0=0.2, yaw_rate=yaw_rate)
    pose = Pose(position=(0.2, 0.1, 0.15), rpy=(0.0, 0.0, 0.3))
    cfg = validate_model(
        LidarConfig, {"type": "lidar", "name": "v", "noise_sigma": 0.0, "pose": pose.model_dump()}
    )
    lid = Lidar(cfg)
    ctx = FakeContext(scene(vertical_wall_x(WALL_X)), traj, tmp_path)
    pts = lid.scan(traj, ctx.raycaster(), 50_000_000, ctx.rng("x"))
    t = 0.05 + pts["time"].astype(np.float64)
    yaw = 0.2 + yaw_rate * t + 0.3
    body = p0 + t[:, None] * np.array([2.0, 1.0, 0.0])
    c, s = np.cos(0.2 + yaw_rate * t), np.sin(0.2 + yaw_rate * t)
    origin_x = body[:, 0] + c * 0.2 - s * 0.1
    world_x = origin_x + np.cos(yaw) * pts["x"] - np.sin(yaw) * pts["y"]
    assert pts.shape[0] > 5000
    np.testing.assert_allclose(world_x, WALL_X, atol=5e-4)
    # with the turn-start pose instead, the points would miss the wall by decimetres
    yaw_start = 0.2 + yaw_rate * 0.05 + 0.3
    wrong = (
        p0[0] + 0.05 * 2.0 + math.cos(0.4) * 0.2 - math.sin(0.4) * 0.1
        + math.cos(yaw_start) * pts["x"] - math.sin(yaw_start) * pts["y"]
    )  # fmt: skip
    assert np.abs(wrong - WALL_X).max() > 0.1


def test_interpolated_poses_match_exact_state_on_a_flapping_landing() -> None:
    cfg = TrajectoryConfig(
        flapping={"frequency": 12.0, "heave": 0.05, "pitch": 0.2}, kappa={"yaw": 0.3}
    )
    traj = TauTrajectory(cfg, warn=False)
    T_bs = Pose(position=(0.1, 0.05, 0.2), rpy=(0.1, -0.3, 0.5)).matrix()
    lid = Lidar(validate_model(LidarConfig, {"type": "lidar", "name": "v"}))
    s = lid.spec
    for t0 in (0.0, 0.7, traj.T - 0.05):
        tk = t0 + np.arange(s.azimuth_steps) * s.column_period
        o, d = rays_in_world(traj, T_bs, tk, lid.frac, lid.directions)
        # independent: state at every firing instant
        t = (tk[:, None] + lid.frac[None, :] * s.column_period).reshape(-1)
        st = traj.state(t)
        R_ws = st.R_world_body @ T_bs[:3, :3]
        o_ref = st.position + st.R_world_body @ T_bs[:3, 3]
        d_ref = np.einsum("nij,nj->ni", R_ws, lid.directions.reshape(-1, 3))
        np.testing.assert_allclose(o.reshape(-1, 3), o_ref, atol=1.5e-6)  # float32, as Embree
        np.testing.assert_allclose(d.reshape(-1, 3), d_ref, atol=5e-7)  # float32 directions


def test_points_from_a_landing_lie_on_the_empty_scene_ground(tmp_path: Path) -> None:
    """Real tau-theory landing (rolling, pitching, yawing, flapping) over the built-in
    `empty` scene (ground plane z = 0): every point, mapped to the world with the exact
    pose of its own firing instant, lies on the ground."""
    from roslan.scene import load_scene

    cfg = TrajectoryConfig(
        initial={"position": [-3.0, 1.0, 2.5], "rpy": [0.2, 0.3, 0.5], "descent_rate": 2.0},
        flapping={"frequency": 8.0, "heave": 0.05, "pitch": 0.2},
    )
    traj = TauTrajectory(cfg, warn=False)
    pose = Pose(position=(0.1, 0.0, -0.05), rpy=(0.0, 0.4, 0.0))
    data = {"type": "lidar", "name": "v", "noise_sigma": 0.0, "pose": pose.model_dump()}
    lid = Lidar(validate_model(LidarConfig, data))
    ctx = FakeContext(load_scene("empty"), traj, tmp_path)
    t0_ns = 400_000_000
    pts = lid.scan(traj, ctx.raycaster(), t0_ns, ctx.rng("v"))
    assert pts.shape[0] > 20_000
    t = t0_ns * 1e-9 + pts["time"].astype(np.float64)
    st = traj.state(t)
    T = pose.matrix()
    R_ws = st.R_world_body @ T[:3, :3]
    p_ws = st.position + st.R_world_body @ T[:3, 3]
    xyz = np.column_stack([pts["x"], pts["y"], pts["z"]]).astype(np.float64)
    world = p_ws + np.einsum("nij,nj->ni", R_ws, xyz)
    np.testing.assert_allclose(world[:, 2], 0.0, atol=2e-4)
    # with one pose for the whole turn (the Gazebo plugin's shortcut) they would not
    st0 = traj.state([t0_ns * 1e-9])
    R0 = st0.R_world_body[0] @ T[:3, :3]
    world0 = st0.position[0] + st0.R_world_body[0] @ T[:3, 3] + xyz @ R0.T
    assert np.abs(world0[:, 2]).max() > 0.05


_small = st.floats(min_value=-1.0, max_value=1.0, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(
    rv=st.tuples(_small, _small, _small),
    v=st.tuples(_small, _small, _small),
    scale=st.sampled_from([1e-6, 1e-4, 1e-3, 0.1, 1.0, 2.5]),
)
@example(rv=(0.0, 1.0, 1.0), v=(0.0, 0.0, 0.0), scale=2.5)  # angle 3.54 rad > pi
def test_rotation_helpers_match_scipy(
    rv: tuple[float, float, float], v: tuple[float, float, float], scale: float
) -> None:
    from scipy.spatial.transform import Rotation

    from roslan.frames import rotation_log as rotvec_log
    from roslan.sensors.beams.rays import _rotate

    r = np.array([rv]) * scale
    vec = np.array([v])
    expected = Rotation.from_rotvec(r[0]).apply(vec[0])
    # documented accuracy: float32 resolution (series below 3.5e-4 rad)
    np.testing.assert_allclose(_rotate(r, vec)[0], expected, atol=1e-7)
    R = Rotation.from_rotvec(r[0]).as_matrix()
    log = rotvec_log(R[None])[0]
    # the log is the rotation vector of angle in [0, pi]: r itself below pi, and in any
    # case a rotation vector of the same rotation (scale 2.5 reaches 4.3 rad)
    assert np.linalg.norm(log) <= np.pi + 1e-9
    np.testing.assert_allclose(Rotation.from_rotvec(log).as_matrix(), R, atol=1e-7)
    if np.linalg.norm(r[0]) < np.pi - 1e-3:
        np.testing.assert_allclose(log, r[0], atol=1e-7)
