"""The sensors of one episode, run causally on the growing trajectory.

Without ``record`` the sensors run on :class:`~roslan.pipeline.engine.SensorEngine` with no
bag writers (their dataset files go to a temporary folder, removed at the episode's end);
with ``record=OUTDIR`` the incremental run driver (:func:`roslan.pipeline.run.open_run`)
streams the same engine's messages into the bags and writes the OUTDIR ``simulate``
writes, plus ``episode.json``, atomically at the end.
"""

from __future__ import annotations

import contextlib
import shutil
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from roslan.config.sim import SimConfig
    from roslan.env.dynamics import DynamicsTrajectory
    from roslan.pipeline.engine import StepOutput
    from roslan.scene.model import Scene

__all__ = ["SensorSession"]


class SensorSession:
    """One episode's sensors (module docstring).

    Args:
        config: the episode's config (its ``seed`` is the episode's).
        traj: the vehicle's growing trajectory.
        scene: the loaded scene (None: none).
        record: OUTDIR to write, or None.
        overwrite: replace an existing OUTDIR (only once the new one is complete).
        config_path: the YAML file the config came from (relative paths, run.json).
    """

    def __init__(
        self,
        config: SimConfig,
        traj: DynamicsTrajectory,
        scene: Scene | None,
        *,
        record: Path | None = None,
        overwrite: bool = False,
        config_path: Path | None = None,
    ) -> None:
        self.config = config
        self.traj = traj
        self._tmp: Path | None = None
        self._run: Any = None
        self._engine: Any = None
        if record is not None:
            from roslan.pipeline.run import RunOptions, open_run

            self._run = open_run(
                config,
                Path(record),
                traj,
                RunOptions(overwrite=overwrite, quiet=True),
                scene=scene,
                config_path=config_path,
            )
            self._run.enable_taps()
            return
        from roslan.pipeline.context import Context
        from roslan.pipeline.engine import SensorEngine
        from roslan.sensors.clock import Clock
        from roslan.sensors.registry import sensor_class

        self._tmp = Path(tempfile.mkdtemp(prefix="roslan-episode-"))
        ctx = Context(
            traj,
            self._tmp,
            seed=config.seed,
            start_time_ns=config.output.start_time,
            sensors=config.sensors,
            scene_spec=config.scene,
            scene=scene,
            clock=Clock(0, align=True),
        )
        sensors = [sensor_class(sc.type)(sc) for sc in config.sensors]
        self._engine = SensorEngine(ctx, sensors, None)
        self._engine.enable_taps()

    def advance(self, horizon_ns: int) -> StepOutput:
        """Run every sensor up to ``horizon_ns`` (inclusive)."""
        driver = self._run if self._run is not None else self._engine
        out: StepOutput = driver.advance(horizon_ns)
        return out

    def finish(self, end_ns: int, extra_files: dict[str, bytes] | None = None) -> StepOutput:
        """End the run at ``end_ns``: the last messages; with ``record``, OUTDIR complete."""
        try:
            if self._run is not None:
                out: StepOutput = self._run.finish(end_ns, extra_files=extra_files or {})
            else:
                out = self._engine.finish(end_ns)
        finally:
            self._cleanup()
        return out

    def abort(self) -> None:
        """Stop without writing anything (no half-written OUTDIR)."""
        with contextlib.suppress(Exception):
            if self._run is not None:
                self._run.abort()
            elif self._engine is not None:
                self._engine.abort()
        self._cleanup()

    def _cleanup(self) -> None:
        if self._tmp is not None:
            shutil.rmtree(self._tmp, ignore_errors=True)
            self._tmp = None
