"""The :class:`~roslan.sensors.base.SimContext` the pipeline hands every sensor."""

from __future__ import annotations

import hashlib
import importlib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from roslan.errors import ConfigError
from roslan.io.files import DatasetFolder
from roslan.render.backends import SceneBackends
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
        outdir: the (temporary) output folder dataset files go to (:attr:`files`), or
            None: the run records no files (its sensors write none).
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
        backends: the scene's renderer and ray caster, owned by the run
            (:class:`~roslan.render.backends.SceneBackends`; default: made here on first
            use, owned by this context).
        labels: the run's ``output.labels`` (sensors write their label outputs).
    """

    def __init__(
        self,
        trajectory: Trajectory,
        outdir: Path | None,
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
        backends: SceneBackends | None = None,
    ) -> None:
        self.trajectory = trajectory
        self.clock = clock if clock is not None else Clock.fixed(trajectory.duration_ns)
        self.files = DatasetFolder(Path(outdir)) if outdir is not None else None
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
        self._backends = backends

    def stamp(self, t_ns: int) -> int:
        """Absolute header stamp (ns) of trajectory time ``t_ns``."""
        return self.start_time_ns + int(t_ns)

    def rng(self, name: str) -> np.random.Generator:
        """A fresh deterministic generator for component ``name`` (same name -> same stream)."""
        ss = np.random.SeedSequence([self.seed, stream_key(name)])
        return np.random.Generator(np.random.PCG64(ss))

    def path(self, relpath: str) -> Path:
        """``outdir / relpath`` with parent folders created; must stay inside outdir
        (RuntimeError in a run that records no files: check :attr:`files` first)."""
        if self.files is None:
            msg = f"dataset file {relpath!r}: this run records no files (ctx.files is None)"
            raise RuntimeError(msg)
        return self.files.path(relpath)

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

    @property
    def backends(self) -> SceneBackends:
        """The scene's renderer and ray caster (made here on first use unless the run
        handed its own)."""
        if self._backends is None:
            self._backends = SceneBackends(self.scene)
        return self._backends

    def renderer(self) -> FrameRenderer:
        """The OpenGL renderer of the scene (created on first use)."""
        return self.backends.renderer()

    def render_helpers(self, name: str) -> int:
        """Render helper processes sensor ``name`` may start (0: none)."""
        return max(0, int(self._helpers.get(name, 0)))

    def camera_folder(self, camera: str) -> str:
        """``''`` for the root camera, else ``'<camera>/'``
        (:func:`~roslan.rundir.calibration.camera_folder`)."""
        return camera_folder(self.root_camera, camera)

    def raycaster(self) -> BeamCaster:
        """The Embree ray caster of the scene (created on first use), the one the run's
        clearance and contact checks cast through."""
        return self.backends.caster()
