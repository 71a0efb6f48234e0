"""The :class:`~roslan.sensors.base.SimContext` the pipeline hands every sensor."""

from __future__ import annotations

import hashlib
import importlib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from roslan.errors import ConfigError
from roslan.rundir.calibration import camera_folder, root_camera, root_imu
from roslan.sensors.base import SensorConfig
from roslan.sensors.clock import Clock

if TYPE_CHECKING:
    from roslan.render.base import BeamCaster, FrameRenderer
    from roslan.scene.model import Scene
    from roslan.trajectory.base import Trajectory

__all__ = ["Context", "stream_key"]


def stream_key(name: str) -> int:
    """Stable 64-bit integer of a component name (SHA-256; never Python's salted ``hash``)."""
    return int.from_bytes(hashlib.sha256(name.encode("utf-8")).digest()[:8], "little")


class Context:
    """Everything a sensor may use during one run.

    Args:
        trajectory: the landing.
        outdir: the (temporary) output folder dataset files go to.
        seed: run seed;
            ``rng(name)`` = ``Generator(PCG64(SeedSequence([seed, stream_key(name)])))``,
            so each component's stream depends only on the seed and its name (adding a sensor
            never changes another sensor's noise).
        start_time_ns: absolute stamp of trajectory time 0.
        sensors: every sensor config of the run.
        scene_spec: the config's ``scene`` (None: no scene) and ``base_dir`` for relative paths.
        sensor_threads: threads of each frame/scan sensor for its per-instant work
            (:class:`~roslan.io.ordered.OrderedPool`; 1: all on the sensor's thread).
        render_helpers: render helper processes per sensor name (event cameras' chains,
            :mod:`roslan.sensors.cameras.event_chains`); absent names get none.
        clock: how far sensors may read the trajectory (default: all of it,
            :meth:`Clock.fixed`; closed loop: the engine's growing clock).
    """

    def __init__(
        self,
        trajectory: Trajectory,
        outdir: Path,
        *,
        seed: int = 0,
        start_time_ns: int = 1,
        sensors: Sequence[SensorConfig] = (),
        scene_spec: str | None = None,
        base_dir: Path | None = None,
        scene: Scene | None = None,
        sensor_threads: int = 1,
        render_helpers: Mapping[str, int] | None = None,
        clock: Clock | None = None,
    ) -> None:
        self.trajectory = trajectory
        self.clock = clock if clock is not None else Clock.fixed(trajectory.duration_ns)
        self.outdir = Path(outdir)
        self.seed = int(seed)
        self.start_time_ns = int(start_time_ns)
        self.sensors: Sequence[SensorConfig] = tuple(sensors)
        self.root_camera = root_camera(self.sensors)
        self.root_imu = root_imu(self.sensors)
        self.scene_spec = scene_spec
        self.base_dir = base_dir
        self._scene = scene
        self.sensor_threads = max(1, int(sensor_threads))
        self._helpers = dict(render_helpers or {})
        self._renderer: FrameRenderer | None = None
        self._raycaster: BeamCaster | None = None

    def stamp(self, t_ns: int) -> int:
        """Absolute header stamp (ns) of trajectory time ``t_ns``."""
        return self.start_time_ns + int(t_ns)

    def rng(self, name: str) -> np.random.Generator:
        """A fresh deterministic generator for component ``name`` (same name -> same stream)."""
        ss = np.random.SeedSequence([self.seed, stream_key(name)])
        return np.random.Generator(np.random.PCG64(ss))

    def path(self, relpath: str) -> Path:
        """``outdir / relpath`` with parent folders created; must stay inside outdir."""
        rel = Path(relpath)
        if rel.is_absolute() or ".." in rel.parts:
            msg = f"dataset path {relpath!r} must be relative and stay inside the output folder"
            raise ValueError(msg)
        p = self.outdir / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        return p

    @property
    def has_scene(self) -> bool:
        return self._scene is not None or self.scene_spec is not None

    @property
    def scene(self) -> Scene:
        """The scene, loaded on first use (ConfigError if the config has none)."""
        if self._scene is None:
            if self.scene_spec is None:
                msg = (
                    "this sensor needs a scene but the config has none; add e.g. "
                    "'scene: warehouse' (built-ins: warehouse, refinery, empty) "
                    "or a scene YAML path"
                )
                raise ConfigError(msg)
            scene_mod = importlib.import_module("roslan.scene")
            self._scene = scene_mod.load_scene(
                self.scene_spec, base_dir=self.base_dir, seed=self.seed
            )
        return self._scene

    def renderer(self) -> FrameRenderer:
        """The process-wide OpenGL renderer of the scene (created on first use)."""
        if self._renderer is None:
            gl = importlib.import_module("roslan.render.gl")
            self._renderer = gl.get_renderer(self.scene)
        return self._renderer

    def render_helpers(self, name: str) -> int:
        """Render helper processes sensor ``name`` may start (0: none)."""
        return max(0, int(self._helpers.get(name, 0)))

    def camera_folder(self, camera: str) -> str:
        """``''`` for the root camera, else ``'<camera>/'``
        (:func:`~roslan.rundir.calibration.camera_folder`)."""
        return camera_folder(self.root_camera, camera)

    def raycaster(self) -> BeamCaster:
        """The process-wide Embree ray caster of the scene (created on first use)."""
        if self._raycaster is None:
            rc = importlib.import_module("roslan.render.raycast")
            self._raycaster = rc.get_raycaster(self.scene)
        return self._raycaster
