"""The scene's own motion in the motion field and the DSEC flow maps: the one seam
(``SceneAt.point_velocity`` / ``SceneAt.carry``) against finite differences of a moving
object's poses, and the static fast path (the camera's own velocity, the same arrays)."""

from __future__ import annotations

import numpy as np
import pytest

from motion_helpers import Sliding
from roslan.errors import RenderError
from roslan.events.sampling import max_flow_speed, motion_field, pixel_rays
from roslan.scene.model import Material, Scene, SceneObject
from roslan.sensors.cameras.flow_truth import FlowTruth, _Open, displacement_flow
from roslan.sensors.cameras.model import CameraModel
from roslan.sensors.cameras.scene_motion import relative_velocity

W, H, F = 40, 30, 50.0
Z = 4.0  # m: the plane's distance along the camera's optical axis (= world z)
K = np.array([[F, 0.0, (W - 1) / 2], [0.0, F, (H - 1) / 2], [0.0, 0.0, 1.0]])


def _plane(motion: Sliding | None) -> Scene:
    v = np.array([[-9, -9, 0], [9, -9, 0], [9, 9, 0], [-9, 9, 0]], np.float32)
    p0 = np.array([0.3, -0.2, Z])
    pose = np.eye(4)
    pose[:3, 3] = p0
    obj = SceneObject(
        "board",
        v + p0.astype(np.float32),
        np.tile(np.array([0, 0, -1], np.float32), (4, 1)),
        np.zeros((4, 2), np.float32),
        np.array([[0, 1, 2], [0, 2, 3]], np.int32),
        Material(),
        pose=pose,
        local_vertices=v,
        local_normals=np.tile(np.array([0, 0, -1], np.float32), (4, 1)),
        motion=motion,
    )
    return Scene("moving-board" if motion else "board", (obj,))


_START = np.eye(4)
_START[:3, 3] = (0.3, -0.2, Z)
MOTION = Sliding(_START, np.array([0.8, -0.5, 0.3]), 0.7)


def _project(P: np.ndarray) -> np.ndarray:
    return np.stack([F * P[..., 0] / P[..., 2] + K[0, 2], F * P[..., 1] / P[..., 2] + K[1, 2]], -1)


def _seen(t: float) -> tuple[np.ndarray, np.ndarray]:
    """The camera (world = optical frame, at rest) at ``t``: each pixel's point on the
    board (the plane z = Z + v_z t, fronto-parallel since it turns about z) and depth."""
    x, y = pixel_rays(K, W, H)
    z = np.full((H, W), Z + MOTION.v[2] * t)
    return np.stack([x * z, y * z, z], axis=-1), z


def test_static_scene_takes_the_fast_path() -> None:
    """A static scene: the camera's own velocity (the same array) and unmoved points
    (the same array): today's flow, bit for bit."""
    view = _plane(None).at(0.3)
    v = np.array([0.1, 0.2, -1.0])
    P, z = _seen(0.0)
    assert relative_velocity(view, np.eye(4), v, z, pixel_rays(K, W, H), None) is v
    pts = P.reshape(-1, 3)
    assert view.carry(pts, np.zeros(len(pts), np.int64), 0.5) is pts


def test_motion_field_follows_a_moving_object() -> None:
    """A still camera facing a board that translates and turns: the motion field with
    the relative velocity equals the finite difference of the board's poses projected,
    and the sampler's flow bound is its largest value."""
    t, dt = 0.2, 1e-5
    scene = _plane(MOTION)
    P, z = _seen(t)
    ids = np.zeros((H, W), np.int32)
    rays = pixel_rays(K, W, H)
    v_rel = relative_velocity(scene.at(t), np.eye(4), np.zeros(3), z, rays, ids)
    assert v_rel.shape == (H, W, 3)
    flow = motion_field(z, K, v_rel, np.zeros(3), rays)

    def seen_at(tt: float) -> np.ndarray:  # the points at t, carried by the poses to tt
        S = MOTION.at(tt) @ np.linalg.inv(MOTION.at(t))
        return _project(P @ S[:3, :3].T + S[:3, 3])

    want = (seen_at(t + dt) - seen_at(t - dt)) / (2 * dt)
    np.testing.assert_allclose(flow, want, rtol=1e-4, atol=1e-3)
    assert np.abs(want).max() > 5.0  # px/s: the motion is there
    speed = max_flow_speed(z, K, v_rel, np.zeros(3), rays)
    assert speed == pytest.approx(float(np.max(np.hypot(want[..., 0], want[..., 1]))), rel=1e-4)


def test_dsec_flow_carries_points_with_their_object() -> None:
    """A DSEC flow map over 50 ms of the moving board: every pixel's displacement is its
    point carried by the board's poses and projected, not the still world's zero."""
    t0, t1 = 0.2, 0.25
    scene = _plane(MOTION)
    model = CameraModel(W, H, K)
    P, z0 = _seen(t0)
    truth = FlowTruth(
        model,
        pixel_rays(K, W, H),
        lambda t: np.eye(4),
        None,
        50,
        None,
        sky_valid=False,
        scene=scene,
    )  # type: ignore[arg-type]
    m = _Open(
        int(t0 * 1e9), int(t1 * 1e9), z0.astype(np.float32), np.eye(4), np.zeros((H, W), np.int32)
    )
    carry = truth._carry(m)
    assert carry is not None
    far = np.full((H, W), np.inf, np.float32)  # nothing seen at t1: no occlusion test
    disp = displacement_flow(model, pixel_rays(K, W, H), z0, far, np.eye(4), carry=carry)
    step = MOTION.at(t1) @ np.linalg.inv(MOTION.at(t0))
    want = _project(P @ step[:3, :3].T + step[:3, 3]) - _project(P)
    ok = np.isfinite(disp[..., 0])
    assert ok.mean() > 0.8  # the rest leave the image
    np.testing.assert_allclose(disp[ok], want[ok], atol=1e-6)
    assert np.abs(want[ok]).max() > 1.0
    still = displacement_flow(model, pixel_rays(K, W, H), z0, far, np.eye(4))
    np.testing.assert_allclose(still[np.isfinite(still[..., 0])], 0.0, atol=1e-9)


def test_moving_scene_without_ids_is_refused_by_name() -> None:
    """The renderer draws no object ids yet: a moving scene's motion field says so and
    names the scene, instead of a still world's flow."""
    _, z = _seen(0.0)
    with pytest.raises(RenderError, match=r"moving-board.*object ids"):
        relative_velocity(
            _plane(MOTION).at(0.0), np.eye(4), np.zeros(3), z, pixel_rays(K, W, H), None
        )
