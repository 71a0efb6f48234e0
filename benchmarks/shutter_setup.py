"""What the shutter benchmarks share (bench_shutter.py, bench_shutter_accuracy.py): a
context holding the renderer and the trajectory, and the body poses at instants."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["BenchCtx", "body_poses"]


class BenchCtx:
    """The part of a run's context a camera renders with: ``renderer()`` and ``trajectory``."""

    def __init__(self, renderer: Any, trajectory: Any) -> None:
        self._r = renderer
        self.trajectory = trajectory

    def renderer(self) -> Any:
        return self._r


def body_poses(traj: Any, t_ns: np.ndarray) -> np.ndarray:
    """(N, 4, 4) ``T_world_body`` of ``traj`` at (N,) trajectory instants (ns)."""
    st = traj.state(t_ns.astype(np.float64) * 1e-9)
    T = np.zeros((len(t_ns), 4, 4))
    T[:, :3, :3] = st.R_world_body
    T[:, :3, 3] = st.position
    T[:, 3, 3] = 1.0
    return T
