"""The one-pass max flow speed of the optical-flow sampling vs the full motion field."""

from __future__ import annotations

import numpy as np
import pytest

from roslan.events.sampling import max_flow_speed, motion_field, pixel_rays


@pytest.mark.parametrize("seed", range(5))
def test_max_flow_speed_equals_max_of_motion_field(seed: int) -> None:
    rng = np.random.default_rng(seed)
    K = np.array([[216.0, 0.0, 172.5], [0.0, 210.0, 129.5], [0.0, 0.0, 1.0]])
    rays = pixel_rays(K, 34, 26)
    for _ in range(20):
        depth = (rng.random((26, 34)) * 10.0 + 0.05).astype(np.float32)
        depth[rng.random(depth.shape) < 0.1] = np.inf  # no hit: rotation only
        depth[rng.random(depth.shape) < 0.05] = np.nan
        if seed == 0:  # behind the camera, at it, and very near (a huge flow)
            depth[0, :3] = (-1.0, 0.0, 1e-30)
        v, w = rng.normal(size=3) * 3.0, rng.normal(size=3) * 2.0
        flow = motion_field(depth, K, v, w, rays)
        expected = float(np.max(np.hypot(flow[..., 0], flow[..., 1])))
        assert max_flow_speed(depth, K, v, w, rays) == expected
        assert max_flow_speed(depth, K, v, w) == expected  # rays computed when not given


def test_max_flow_speed_of_pure_translation_towards_a_wall() -> None:
    # camera moving along +z at 2 m/s towards a fronto-parallel wall at 4 m: the flow is
    # radial, |flow| = f * r * vz / Z with r the normalised radius; largest at a corner
    K = np.array([[100.0, 0.0, 9.5], [0.0, 100.0, 7.5], [0.0, 0.0, 1.0]])
    depth = np.full((16, 20), 4.0, dtype=np.float32)
    speed = max_flow_speed(depth, K, np.array([0.0, 0.0, 2.0]), np.zeros(3))
    r = np.hypot(9.5 / 100.0, 7.5 / 100.0)
    assert speed == pytest.approx(100.0 * r * 2.0 / 4.0, rel=1e-6)


def test_camera_twist_fast_path_equals_the_full_state() -> None:
    """camera_twist through the tau landing's one-instant path and through the generic
    State of any Trajectory (the protocol's own pose_twist_ns) give the same bits; and the
    twist is the finite difference of the pose."""
    from roslan.events.sampling import camera_twist
    from roslan.trajectory import TauTrajectory, TrajectoryConfig
    from roslan.trajectory.base import Trajectory

    tau = TauTrajectory(
        TrajectoryConfig.model_validate(
            {
                "initial": {
                    "position": [-6.0, 3.0, 5.0],
                    "rpy": [0.2, -0.3, 0.8],
                    "descent_rate": 1.5,
                },
                "flapping": {"frequency": 3.0, "heave": 0.05, "pitch": 0.1},
                "goal": {"position": [1.0, 2.0, 0.5], "rpy": [0.0, 0.0, 0.7]},
            }
        ),
        warn=False,
    )

    class Generic:  # the Trajectory protocol's own pose_twist_ns (through state_ns)
        def pose_twist_ns(self, t: int) -> object:
            return Trajectory.pose_twist_ns(tau, t)

    T_bc = np.eye(4)
    T_bc[:3, :3] = [[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]
    T_bc[:3, 3] = (0.12, 0.03, -0.02)
    for t in np.linspace(0, tau.duration_ns, 97).astype(np.int64).tolist():
        fast = camera_twist(tau, t, T_bc)
        slow = camera_twist(Generic(), t, T_bc)  # type: ignore[arg-type]
        for a, b in zip(fast, slow, strict=True):
            assert np.array_equal(a, b)
    t, h = int(1.3e9), 1000
    (T0, _, _), (T1, v, _), (T2, _, _) = (camera_twist(tau, t + d, T_bc) for d in (-h, 0, h))
    v_fd = T1[:3, :3].T @ (T2[:3, 3] - T0[:3, 3]) / (2 * h * 1e-9)
    np.testing.assert_allclose(v, v_fd, rtol=1e-5, atol=1e-6)
