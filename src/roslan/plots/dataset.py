"""The dataset's trajectory figure (``trajectories_<scene>.png`` of ``roslan dataset``):
every landing of one scene together, in the goal frame (the paper's Fig. 3)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol

import numpy as np

__all__ = ["Landing", "plot_trajectories"]


class Landing(Protocol):
    """What the figure needs of one landing (e.g. :class:`roslan.batch.paper.DatasetRun`)."""

    @property
    def number(self) -> int: ...
    @property
    def scene(self) -> str: ...
    @property
    def kappa_x(self) -> float: ...
    @property
    def kappa_y(self) -> float: ...
    @property
    def speed(self) -> float: ...
    @property
    def config(self) -> Mapping[str, Any]:
        """The simulation config; its ``trajectory`` block is drawn."""
        ...


def plot_trajectories(runs: Sequence[Landing], path: Path) -> None:
    """All landings of one scene in the goal frame F (paper's Fig. 3): a 3-D view with
    velocity vectors, the top view and height against horizontal distance. Velocity
    vectors are drawn at the instants of each landing's trajectory table (its
    ``sample_dt``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from roslan.trajectory.config import TrajectoryConfig
    from roslan.trajectory.generator import TauTrajectory

    fig = plt.figure(figsize=(14, 4.8), dpi=110)
    ax3 = fig.add_subplot(1, 3, 1, projection="3d")
    axt = fig.add_subplot(1, 3, 2)
    axs = fig.add_subplot(1, 3, 3)
    cmap = plt.get_cmap("tab10")
    colors = [cmap(i) for i in range(10)]
    trajs = [
        TauTrajectory(TrajectoryConfig.model_validate(r.config["trajectory"]), warn=False)
        for r in runs
    ]
    # arrows: velocity scaled so the fastest start spans 15% of the largest start distance
    extent = max((float(np.linalg.norm(tr.initial_gaps[:3])) for tr in trajs), default=1.0)
    vmax = max((float(np.linalg.norm(tr.state([0.0]).rates[0, :3])) for tr in trajs), default=1.0)
    scale = 0.15 * extent / vmax
    for n, (run, traj) in enumerate(zip(runs, trajs, strict=True)):
        st = traj.state(np.linspace(0.0, traj.T, 400))
        p = st.gaps[:, :3]
        # vectors at the table instants (every 0.1 s), at most ~12 per landing
        ta = np.arange(0.0, traj.T, float(run.config["trajectory"]["sample_dt"]))
        ta = ta[:: max(1, len(ta) // 12)]
        sa = traj.state(ta)
        pa, va = sa.gaps[:, :3], sa.rates[:, :3] * scale
        c = colors[n % len(colors)]
        label = (
            f"{run.number}: $\\kappa_x$={run.kappa_x:g}, $\\kappa_y$={run.kappa_y:g}, "
            f"{run.speed:g} m/s"
        )
        # the vectors are tangent to the path: thin paths, bold arrows
        ax3.plot(p[:, 0], p[:, 1], p[:, 2], color=c, lw=0.8, alpha=0.6, label=label)
        ax3.quiver(
            pa[:, 0], pa[:, 1], pa[:, 2], va[:, 0], va[:, 1], va[:, 2],
            color=c, linewidth=1.6, arrow_length_ratio=0.35,
        )  # fmt: skip
        axt.plot(p[:, 0], p[:, 1], color=c, lw=0.8, alpha=0.6)
        axt.quiver(
            pa[:, 0], pa[:, 1], va[:, 0], va[:, 1], color=c, angles="xy", scale_units="xy",
            scale=1.0, width=0.007, headwidth=3.5, headlength=4.0, headaxislength=3.5,
        )  # fmt: skip
        axs.plot(np.hypot(p[:, 0], p[:, 1]), p[:, 2], color=c, lw=1.5)
    for ax in (axt, axs):
        ax.plot([0], [0], "k*", ms=10)
        ax.grid(alpha=0.3)
    ax3.scatter([0], [0], [0], color="k", marker="*", s=60)
    ax3.set(xlabel="x (m)", ylabel="y (m)", zlabel="z (m)", title="landings (goal frame)")
    axt.set(xlabel="x (m)", ylabel="y (m)", title="top view, velocity vectors", aspect="equal")
    axs.set(
        xlabel="horizontal distance to goal (m)", ylabel="height above goal (m)", title="side view"
    )
    scene = runs[0].scene if runs else ""
    k = ", ".join(str(v) for v in sorted({float(r.config["trajectory"]["k"]) for r in runs}))
    fig.suptitle(f"{scene}: k = {k}, approach angle pi/6 (tau-theory landings)")
    fig.legend(loc="lower center", ncol=3, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.1, 1, 0.95))
    tmp = path.with_name(f".{path.stem}.tmp.png")
    fig.savefig(tmp)
    plt.close(fig)
    tmp.replace(path)
