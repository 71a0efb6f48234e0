"""The sensors of one episode, run causally on the growing trajectory.

A thin layer over the incremental run driver (:func:`roslan.pipeline.live.open_run`):
without ``record`` no OUTDIR sink is attached (no bag writers, no folder, no dataset
file at all: the sensors get ``ctx.files = None``); with ``record=OUTDIR`` the same
engine's messages stream into the bags and the episode ends with the OUTDIR
``simulate`` writes, plus ``episode.json``, moved into place atomically.
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from roslan.config.sim import SimConfig
    from roslan.env.dynamics import DynamicsTrajectory
    from roslan.pipeline.engine import StepOutput
    from roslan.render.backends import SceneBackends
    from roslan.scene.model import Scene

__all__ = ["SensorSession"]


class SensorSession:
    """One episode's sensors (module docstring).

    Args:
        config: the episode's config (its ``seed`` is the episode's).
        traj: the vehicle's growing trajectory.
        scene: the loaded scene (None: none).
        backends: its renderer and ray caster (the environment's, shared with contact).
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
        backends: SceneBackends | None = None,
        record: Path | None = None,
        overwrite: bool = False,
        config_path: Path | None = None,
    ) -> None:
        from roslan.pipeline.live import open_run
        from roslan.pipeline.run import RunOptions

        self._run = open_run(
            config,
            record,
            traj,
            RunOptions(overwrite=overwrite, quiet=True),
            scene=scene,
            backends=backends,
            config_path=config_path,
        )

    def advance(self, horizon_ns: int) -> StepOutput:
        """Run every sensor up to ``horizon_ns`` (inclusive)."""
        return self._run.advance(horizon_ns)

    def finish(self, end_ns: int, extra_files: dict[str, bytes] | None = None) -> StepOutput:
        """End the run at ``end_ns``: the last messages; with ``record``, OUTDIR complete."""
        out, _ = self._run.finish(end_ns, extra_files=extra_files or {})
        return out

    def abort(self) -> None:
        """Stop without writing anything (no half-written OUTDIR)."""
        with contextlib.suppress(Exception):
            self._run.abort()
