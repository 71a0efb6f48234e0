"""The depth camera's rolling-shutter readout against analytic depths: every row at its
own instant (:mod:`roslan.sensors.cameras.depth_readout`), under a pure rotation and a
pure translation over a floor, and with a silhouette that must not smear."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

import roslan.render.gl as gl
from roslan.scene.model import Lights, Material, Scene, SceneObject
from roslan.sensors.cameras import DepthCamera, DepthCameraConfig
from roslan.sensors.cameras.model import T_LINK_OPTICAL
from roslan.sensors.cameras.row_exposure import output_rays

W, H = 48, 36
FX = 40.0
HEIGHT = 3.0  # m above the floor


def _quad(name: str, half: float, z: float) -> SceneObject:
    v = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]])
    return SceneObject(
        name,
        v.astype(np.float32),
        np.tile(np.array([0, 0, 1], np.float32), (4, 1)),
        np.zeros((4, 2), np.float32),
        np.array([[0, 1, 2], [0, 2, 3]], np.int32),
        Material(),
    )


def _floor(*extra: SceneObject) -> Scene:
    return Scene("floor", (_quad("floor", 40.0, 0.0), *extra), Lights())


def _R_look_down(pitch: float) -> np.ndarray:
    """``R_world_optical`` of a camera looking straight down (optical z = world -z,
    optical x = world +x), pitched by ``pitch`` about its optical x axis."""
    down = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
    c, s = np.cos(pitch), np.sin(pitch)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    return down @ rx


class _Motion:
    """A trajectory stand-in: the camera above the floor, pitching at ``omega`` (rad/s)
    about its optical x axis and descending at ``v`` (m/s) from t = 0."""

    def __init__(self, omega: float, v: float) -> None:
        self.omega, self.v = omega, v

    def optical(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t = np.atleast_1d(np.asarray(t, np.float64))
        R = np.stack([_R_look_down(self.omega * a) for a in t])
        p = np.zeros((t.size, 3))
        p[:, 2] = HEIGHT - self.v * t
        return R, p

    def state(self, t: np.ndarray) -> Any:
        R, p = self.optical(t)
        R_link = T_LINK_OPTICAL[:3, :3]
        return SimpleNamespace(R_world_body=R @ R_link.T, position=p)


class _Ctx:
    def __init__(self, scene: Scene, trajectory: _Motion) -> None:
        self._r = gl.get_renderer(scene)
        self.trajectory = trajectory

    def renderer(self) -> Any:
        return self._r


def _camera(readout: float, samples: int = 2, **keys: Any) -> DepthCamera:
    cfg = {"type": "depth_camera", "name": "d", "rate": 10.0, "topic": "/d"}
    cfg |= {"resolution": [W, H], "fx": FX, "readout_time": readout}
    cfg |= {"readout_samples": samples} | keys
    return DepthCamera(DepthCameraConfig.model_validate(cfg))


def _frame(cam: DepthCamera, ctx: _Ctx, stamp: int) -> np.ndarray:
    cam._plans(ctx)  # type: ignore[arg-type]
    e = cam._eyes[0]
    z = cam.rolling_depth(ctx, ctx.renderer(), e, stamp)  # type: ignore[arg-type]
    return np.asarray(z, np.float64)


def _analytic(cam: DepthCamera, traj: _Motion, stamp: int, readout: float) -> np.ndarray:
    """Each output pixel's z-depth at its own row's instant: the floor z = 0 met by the
    pixel's ray (through the lens) from the pose at ``t_r``."""
    e = cam._eyes[0]
    assert e.plan is not None
    x, y = (a.astype(np.float64) for a in output_rays(e.plan, W, H))
    t_r = stamp * 1e-9 - 0.5 * readout * (H - 1) / H + np.arange(H) * readout / H
    R, p = traj.optical(t_r)
    d = np.stack([x, y, np.ones_like(x)], axis=-1)  # (H, W, 3), z-depth = its scale
    dz = np.einsum("rj,rwj->rw", R[:, 2, :], d)  # world z of each ray, per row's pose
    return -p[:, 2][:, None] / dz


@pytest.mark.parametrize("distortion", [False, True])
def test_rows_under_pure_rotation_see_their_own_instant(distortion: bool) -> None:
    """A floor under a pitching camera: each row's depth equals the analytic depth at
    that row's instant (top, middle and bottom rows), within 1e-4; the rows' instants
    matter by far more than that (2 renders over a 40 ms readout)."""
    omega, readout, stamp = 2.0, 0.04, 500_000_000  # pitched 1 rad at the stamp
    lens = {"distortion_model": "plumb_bob", "distortion_coeffs": [-0.2, 0.05, 0, 0, 0]}
    cam = _camera(readout, **(lens if distortion else {}))
    traj = _Motion(omega, 0.0)
    z = _frame(cam, _Ctx(_floor(), traj), stamp)
    want = _analytic(cam, traj, stamp, readout)
    for r in (0, H // 2, H - 1):
        np.testing.assert_allclose(z[r], want[r], rtol=1e-4)
    at_stamp = _analytic(cam, traj, stamp, 0.0)  # every row at the stamp's pose
    assert np.max(np.abs(want - at_stamp)[[0, -1]] / want[[0, -1]]) > 100 * 1e-4


def test_rows_under_descent_see_their_own_instant() -> None:
    """A descending camera over a floor (pure translation): row r reads
    ``HEIGHT - v t_r`` exactly, with 3 renders over the readout (rows far from a render's
    instant too)."""
    v, readout, stamp = 2.0, 0.04, 100_000_000
    cam = _camera(readout, samples=3)
    traj = _Motion(0.0, v)
    z = _frame(cam, _Ctx(_floor(), traj), stamp)
    t_r = stamp * 1e-9 - 0.5 * readout * (H - 1) / H + np.arange(H) * readout / H
    centre = z[:, W // 2 - 1 : W // 2 + 1].mean(axis=1)  # the optical axis' columns
    np.testing.assert_allclose(centre, HEIGHT - v * t_r, rtol=2e-4)
    np.testing.assert_allclose(z, _analytic(cam, traj, stamp, readout), rtol=2e-4)


def test_a_moving_silhouette_does_not_smear() -> None:
    """A raised board's outline over the floor, under pitch and descent: every output
    depth is the board's or the floor's at that pixel's instant (within 1 %), never a
    blend between them."""
    board = _quad("board", 0.6, 1.0)
    readout, stamp = 0.04, 150_000_000
    cam = _camera(readout)
    traj = _Motion(2.0, 2.0)
    z = _frame(cam, _Ctx(_floor(board), traj), stamp)
    floor = _analytic(cam, traj, stamp, readout)
    # the board's depth: the same rays to the plane z = 1 (its height above the floor)
    e = cam._eyes[0]
    assert e.plan is not None
    x, y = (a.astype(np.float64) for a in output_rays(e.plan, W, H))
    t_r = stamp * 1e-9 - 0.5 * readout * (H - 1) / H + np.arange(H) * readout / H
    R, p = traj.optical(t_r)
    dz = np.einsum("rj,rwj->rw", R[:, 2, :], np.stack([x, y, np.ones_like(x)], -1))
    top = (1.0 - p[:, 2][:, None]) / dz
    near_board = np.abs(z - top) < 0.01 * top
    near_floor = np.abs(z - floor) < 0.01 * floor
    assert near_board.sum() > 50
    assert near_floor.sum() > 500
    assert np.all(near_board | near_floor)
