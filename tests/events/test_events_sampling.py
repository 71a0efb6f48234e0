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
