"""Small scenes, analytic trajectories and a minimal SimContext for the beam-sensor tests.

Scenes are built directly with NumPy (a plane, a box, a closed box room), so the
expected ranges follow from elementary geometry written in the tests.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from roslan.io.files import DatasetFolder
from roslan.render.raycast import get_raycaster
from roslan.scene.model import Material, Scene, SceneObject
from roslan.sensors.clock import Clock
from roslan.trajectory.base import State

START_NS = 1_700_000_000_000_000_000


def _obj(name: str, verts: np.ndarray, faces: np.ndarray, refl: float = 0.5) -> SceneObject:
    v = np.asarray(verts, np.float32)
    return SceneObject(
        name=name,
        vertices=v,
        normals=np.zeros_like(v),
        uvs=np.zeros((v.shape[0], 2), np.float32),
        faces=np.asarray(faces, np.int32),
        material=Material(reflectivity=refl),
    )


def plane(
    z: float = 0.0, half: float = 1000.0, refl: float = 0.5, name: str = "ground"
) -> SceneObject:
    """Horizontal square at height z, normal +z."""
    v = [[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]]
    return _obj(name, np.array(v), np.array([[0, 1, 2], [0, 2, 3]]), refl)


def vertical_wall_x(x: float, half: float = 1000.0, refl: float = 0.5) -> SceneObject:
    """Plane x = const, spanning y and z in [-half, half]."""
    v = [[x, -half, -half], [x, half, -half], [x, half, half], [x, -half, half]]
    return _obj("wall", np.array(v), np.array([[0, 1, 2], [0, 2, 3]]), refl)


def box(
    lo: tuple[float, float, float],
    hi: tuple[float, float, float],
    name: str = "box",
    refl: float = 0.5,
    inward: bool = False,
) -> SceneObject:
    """Axis-aligned box with 12 triangles (winding outward, or inward for a room)."""
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    v = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
                  [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]])  # fmt: skip
    f = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                  [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])  # fmt: skip
    if inward:
        f = f[:, ::-1]
    return _obj(name, v, f, refl)


def scene(*objects: SceneObject, name: str = "test") -> Scene:
    return Scene(name=name, objects=tuple(objects))


def _rot_z(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class LinearTrajectory:
    """Constant velocity, constant yaw rate about z: an analytic stand-in for Trajectory."""

    def __init__(
        self,
        p0: tuple[float, float, float],
        v: tuple[float, float, float] = (0, 0, 0),
        yaw0: float = 0.0,
        yaw_rate: float = 0.0,
        duration: float = 0.35,
    ) -> None:
        self.p0 = np.asarray(p0, float)
        self.v = np.asarray(v, float)
        self.yaw0 = yaw0
        self.yaw_rate = yaw_rate
        self.duration = duration

    @property
    def duration_ns(self) -> int:
        return round(self.duration * 1e9)

    def state(self, t: Any) -> State:
        t = np.atleast_1d(np.asarray(t, float))
        n = t.shape[0]
        yaw = self.yaw0 + self.yaw_rate * t
        R = np.stack([_rot_z(y) for y in yaw]) if n < 64 else _rot_z_many(yaw)
        z3 = np.zeros((n, 3))
        z6 = np.zeros((n, 6))
        omega = np.zeros((n, 3))
        omega[:, 2] = self.yaw_rate
        half = yaw / 2
        quat = np.stack([np.zeros(n), np.zeros(n), np.sin(half), np.cos(half)], axis=1)
        return State(t=t, gaps=z6, rates=z6, accels=z6, position=self.p0 + t[:, None] * self.v,
                     velocity=np.broadcast_to(self.v, (n, 3)).copy(), acceleration=z3,
                     R_world_body=R, quat_xyzw=quat, omega_body=omega, alpha_body=z3)  # fmt: skip


def _rot_z_many(yaw: np.ndarray) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.zeros((yaw.shape[0], 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    return R


class FakeContext:
    """The parts of SimContext the beam sensors use."""

    def __init__(self, scene_: Scene, trajectory: Any, outdir: Path, seed: int = 0) -> None:
        self._scene = scene_
        self.trajectory = trajectory
        self.start_time_ns = START_NS
        self.seed = seed
        self.sensors: list[Any] = []
        self.root_camera: str | None = None
        self.root_imu: str | None = None
        self.sensor_threads = 1
        self.labels = False  # output.labels
        self.outdir = outdir
        self.files = DatasetFolder(outdir)
        self._clock: Clock | None = None

    def stamp(self, t_ns: int) -> int:
        return self.start_time_ns + int(t_ns)

    def rng(self, name: str) -> np.random.Generator:
        key = [self.seed, *name.encode()]
        return np.random.default_rng(np.random.SeedSequence(key))

    def path(self, relpath: str) -> Path:
        return self.files.path(relpath)

    @property
    def scene(self) -> Scene:
        return self._scene

    @property
    def clock(self) -> Clock:
        """The whole trajectory known in advance (as ``simulate``), made on first use."""
        if self._clock is None:
            self._clock = Clock.fixed(self.trajectory.duration_ns)
        return self._clock

    def renderer(self) -> Any:  # pragma: no cover - beams never rasterize
        raise NotImplementedError

    def raycaster(self) -> Any:
        return get_raycaster(self._scene)


def run_sensor(sensor: Any, ctx: FakeContext) -> list[Any]:
    """Iterate the sensor's stream fully and close it; returns the Message list."""
    msgs = list(sensor.messages(ctx))
    sensor.close(ctx)
    return msgs
