"""``roslan plot trajectory``: the landing in 3-D with velocity vectors and orientation
triads, the gaps and their tau against time (the paper's Figs. 1 and 3).

Everything is drawn in the goal frame F (origin at the goal, z up), where the gaps
live. Curves come from the closed-form trajectory of the run's resolved config
(``run.json``) sampled densely; without run.json, from ``trajectory.csv`` alone. The
exported ``trajectory.csv`` rows are drawn as dots over the curves either way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from roslan.plots.style import (
    AXIS_COLORS,
    GAP_COLORS,
    figure,
    save_figure,
    style,
    velocity_arrows,
)
from roslan.rundir.readers import (
    TrajectoryTable,
    load_run,
    load_summary,
    load_trajectory_table,
    resolved_config,
)

__all__ = [
    "TrajectorySamples",
    "coincident_groups",
    "load_samples",
    "plot_trajectory",
    "tau_limits",
]

F64 = NDArray[np.float64]
COMMAND = "roslan plot trajectory"
GAP_NAMES = ("x", "y", "z", "roll", "pitch", "yaw")


@dataclass(frozen=True, slots=True)
class TrajectorySamples:
    """What the trajectory plots draw.

    Attributes:
        dense: the gaps sampled finely (closed form) or the table itself.
        table: the ``trajectory.csv`` rows.
        touchdown: touchdown time T, s.
        k: constant tau-dot of the height gap, or None if unknown.
        tau0: tau of the height gap at t = 0, s, or None.
        closed_form: True when ``dense`` comes from the closed-form trajectory.
        unperturbed: with flapping, the same landing's gaps without it (closed form,
            sampled at ``dense.t``): the tau-theory gaps whose tau the paper's Fig. 3
            shows; None without flapping (or without the closed form).
    """

    dense: TrajectoryTable
    table: TrajectoryTable
    touchdown: float
    k: float | None
    tau0: float | None
    closed_form: bool
    unperturbed: TrajectoryTable | None = None


def _closed_form(
    outdir: Path, n: int
) -> tuple[TrajectoryTable, float, float, float, TrajectoryTable | None] | None:
    """Dense samples of the run's trajectory from run.json, and of the same landing
    without its flapping (None without flapping); None if unavailable."""
    cfg = resolved_config(load_run(outdir))
    if cfg is None or not isinstance(cfg.get("trajectory"), dict):
        return None
    if cfg["trajectory"].get("file") is not None:
        return None  # the spline needs the pose file; the caller uses the exported table
    from pydantic import ValidationError

    from roslan.errors import RoslanError
    from roslan.trajectory import TauTrajectory, TrajectoryConfig
    from roslan.trajectory.config import Flapping

    try:
        config = TrajectoryConfig.model_validate(cfg["trajectory"])
        traj = TauTrajectory(config, warn=False)
        calm = None
        if config.flapping.enabled:
            calm = TauTrajectory(config.model_copy(update={"flapping": Flapping()}), warn=False)
    except (ValidationError, RoslanError, ValueError):
        return None
    t = np.linspace(0.0, traj.duration, n)
    # include the touchdown instant exactly
    t = np.unique(np.concatenate([t, [traj.T]]))
    tt, gaps, rates, accels = traj.gaps_at(t)
    dense = TrajectoryTable(t=tt, gaps=gaps, rates=rates, accels=accels)
    unperturbed = None
    if calm is not None:
        tt, gaps, rates, accels = calm.gaps_at(t)
        unperturbed = TrajectoryTable(t=tt, gaps=gaps, rates=rates, accels=accels)
    return dense, traj.T, traj.k, traj.tau0, unperturbed


def load_samples(outdir: Path, command: str = COMMAND, n: int = 1500) -> TrajectorySamples:
    """The trajectory of the run in ``outdir`` (needs ``trajectory.csv``)."""
    table = load_trajectory_table(outdir, command)
    summary = load_summary(outdir) or {}
    cf = _closed_form(outdir, n)
    if cf is not None:
        dense, touchdown, k, tau0, unperturbed = cf
        return TrajectorySamples(dense, table, touchdown, k, tau0, True, unperturbed)
    t_sum = summary.get("touchdown_time")
    if isinstance(t_sum, int | float):
        t_down = float(t_sum)
    else:
        # first row where the height gap has closed
        closed = np.flatnonzero(np.abs(table.gaps[:, 2]) <= 1e-9)
        t_down = float(table.t[closed[0]] if closed.size else table.t[-1])
    k_sum = summary.get("k")
    tau_sum = summary.get("tau0")
    return TrajectorySamples(
        table,
        table,
        t_down,
        float(k_sum) if isinstance(k_sum, int | float) else None,
        float(tau_sum) if isinstance(tau_sum, int | float) else None,
        False,
    )


def rpy_matrices(rpy: F64) -> F64:
    """(N, 3) roll/pitch/yaw -> (N, 3, 3) R = Rz Ry Rx (frame F from body)."""
    from roslan.frames import rpy_to_matrix

    return np.asarray(rpy_to_matrix(rpy), dtype=np.float64)


def tau_of(gap: F64, rate: F64) -> F64:
    """tau = gap / rate (s); NaN where the rate vanishes (not drawn)."""
    out = np.full_like(gap, np.nan)
    ok = np.abs(rate) > 1e-9 * max(1.0, float(np.max(np.abs(rate), initial=0.0)))
    out[ok] = gap[ok] / rate[ok]
    return out


def _draw_3d(ax: Any, s: TrajectorySamples, n_vel: int = 12, n_triads: int = 7) -> None:
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    d = s.dense
    land = d.t <= s.touchdown + 1e-12
    p = d.gaps[land, :3]
    t = d.t[land]
    span = float(np.max(np.ptp(p, axis=0))) if p.shape[0] > 1 else 1.0
    span = max(span, 1e-3)
    # path coloured by time
    seg = np.stack([p[:-1], p[1:]], axis=1)
    lc = Line3DCollection(seg, cmap="viridis", linewidths=2.2)
    lc.set_array(0.5 * (t[:-1] + t[1:]))
    ax.add_collection3d(lc)
    cbar = ax.figure.colorbar(lc, ax=ax, shrink=0.45, pad=0.0, location="left", aspect=25)
    cbar.set_label("trajectory time t [s]")
    # velocity vectors: arrow = displacement in a round number of seconds
    velocity_arrows(ax, p, d.rates[land][:, :3], n_vel)
    # orientation triads of base_link (x red, y green, z blue)
    it = np.unique(np.linspace(0, p.shape[0] - 1, n_triads).round().astype(int))
    R = rpy_matrices(d.gaps[land][it, 3:])
    L = 0.07 * span
    for axis in range(3):
        u = R[:, :, axis] * L
        ax.quiver(
            p[it, 0],
            p[it, 1],
            p[it, 2],
            u[:, 0],
            u[:, 1],
            u[:, 2],
            color=AXIS_COLORS[axis],
            linewidth=1.6,
            arrow_length_ratio=0.0,
            label=f"body {'xyz'[axis]} axis",
        )
    ax.scatter(*p[0], s=40, color="k", marker="o", depthshade=False, label="start")
    ax.scatter(
        0.0,
        0.0,
        0.0,
        s=110,
        color="gold",
        edgecolors="k",
        marker="*",
        depthshade=False,
        label="goal (origin of F)",
        zorder=5,
    )
    # the table rows as dots
    tab = s.table.gaps[s.table.t <= s.touchdown + 1e-12, :3]
    if s.closed_form:
        ax.scatter(
            tab[:, 0],
            tab[:, 1],
            tab[:, 2],
            s=5,
            color="0.35",
            depthshade=False,
            label="trajectory.csv rows",
        )
    lo = np.minimum(p.min(axis=0), 0.0)
    hi = np.maximum(p.max(axis=0), 0.0)
    mid, half = (lo + hi) / 2.0, max(float(np.max(hi - lo)) / 2.0 * 1.08, 1e-3)
    ax.set_xlim(mid[0] - half, mid[0] + half)
    ax.set_ylim(mid[1] - half, mid[1] + half)
    ax.set_zlim(max(mid[2] - half, min(lo[2], 0.0) - 0.02 * half), mid[2] + half)
    ax.set_box_aspect((1.0, 1.0, (ax.get_zlim()[1] - ax.get_zlim()[0]) / (2 * half)))
    ax.set_xlabel("x_F [m]")
    ax.set_ylabel("y_F [m]")
    ax.set_zlabel("z_F (height) [m]")
    ax.view_init(elev=22, azim=-60)
    ax.legend(loc="upper left", fontsize=7, framealpha=0.85)
    ax.set_title("Landing path in the goal frame F")


def tau_limits(curves: list[F64], theory: F64 | None = None) -> tuple[float, float]:
    """y limits of the tau panel that no spike can stretch: the 2nd to 98th percentile
    of every finite tau (where a rate crosses zero, tau = gap / rate runs off to
    +-infinity), widened by 10%, always holding the theory line and tau = 0."""
    values = np.concatenate([c[np.isfinite(c)] for c in curves] + [np.zeros(1)])
    lo, hi = np.percentile(values, [2.0, 98.0]) if values.size > 1 else (0.0, 0.0)
    if theory is not None:
        lo, hi = min(lo, float(theory.min())), max(hi, float(theory.max()))
    pad = 0.1 * max(hi - lo, 1e-3)
    return float(lo - pad), float(hi + pad)


COINCIDENT = 0.005
"""Curves closer than this fraction of the tau panel's height everywhere share one line on
the page: :func:`coincident_groups` finds them, and they are drawn in interleaved dashes."""


def coincident_groups(
    curves: dict[str, F64], span: float, tol: float = COINCIDENT
) -> list[list[str]]:
    """The curves (same samples) that would hide one another: each group (in ``curves``'
    order) holds curves within ``tol * span`` of its first one wherever both are finite,
    both being finite at nine in ten samples where either is (tau = 0 / 0 is NaN at the
    goal, a few samples sooner or later for each gap)."""
    groups: list[list[str]] = []
    for name, c in curves.items():
        for group in groups:
            ref = curves[group[0]]
            both, either = np.isfinite(ref) & np.isfinite(c), np.isfinite(ref) | np.isfinite(c)
            gap = float(np.max(np.abs(ref[both] - c[both]))) if both.any() else np.inf
            if gap <= tol * span and np.count_nonzero(both) >= 0.9 * np.count_nonzero(either):
                group.append(name)
                break
        else:
            groups.append([name])
    return groups


def _draw_tau(ax_tau: Any, s: TrajectorySamples) -> None:
    """tau of each non-zero gap up to touchdown, with the paper's Fig. 3 theory line for
    tau_z; with flapping, of the tau-theory gaps (the flapping is in the gap panels).
    Curves on one line (equal kappa and tau(0)) are drawn in interleaved dashes of their
    colours, and the legend says which equal which."""
    d = s.unperturbed if s.unperturbed is not None else s.dense
    land = d.t < s.touchdown - 1e-9
    taus = {
        g: tau_of(d.gaps[land, i], d.rates[land, i])
        for i, g in enumerate(GAP_NAMES)
        if np.max(np.abs(d.gaps[:, i]), initial=0.0) >= 1e-9
    }
    curves = list(taus.values())
    tt = np.array([0.0, s.touchdown])
    theory = s.tau0 + s.k * tt if s.k is not None and s.tau0 is not None else None
    lo, hi = tau_limits(curves, theory)
    for group in coincident_groups(taus, hi - lo):
        n, dash = len(group), 5.0
        for j, g in enumerate(group):
            solid = GAP_NAMES.index(g) < 3
            style: str | tuple[float, tuple[float, float]]
            if n == 1:
                style, label = ("-" if solid else "--"), f"τ_{g}"
            else:  # dashes of length `dash` taking turns: every colour shows along the line
                style = (j * dash, (dash, (n - 1) * dash))
                label = f"τ_{g}" + ("" if j == 0 else f" = τ_{group[0]}")
            color = GAP_COLORS[g]
            ax_tau.plot(d.t[land], taus[g], color=color, label=label if n == 1 else None,
                        linestyle=style)  # fmt: skip
            if n > 1:  # the legend's short line shows the colour: a dash that starts at once
                ax_tau.plot([], [], color=color, label=label, linestyle=(0, (2.0, 1.0)))
    if theory is not None:
        assert s.k is not None
        ax_tau.plot(
            tt,
            theory,
            ":",
            color="k",
            linewidth=1.6,
            label=f"τ_z theory, τ̇ = k = {s.k:g}",
            zorder=5,
        )
    ax_tau.set_ylim(lo, hi)
    ax_tau.set_ylabel("τ = gap / rate [s]")
    ax_tau.set_xlabel("trajectory time t [s]")
    if s.unperturbed is not None:
        ax_tau.text(
            0.99,
            0.04,
            "τ of the tau-theory gaps, flapping removed (flown gaps above)",
            transform=ax_tau.transAxes,
            ha="right",
            va="bottom",
            fontsize=7,
            color="0.3",
        )


def _draw_gaps(ax_pos: Any, ax_ang: Any, ax_tau: Any, s: TrajectorySamples) -> None:
    d, tab = s.dense, s.table
    for i, g in enumerate(GAP_NAMES):
        ax = ax_pos if i < 3 else ax_ang
        scale = 1.0 if i < 3 else 180.0 / math.pi
        ax.plot(
            d.t,
            d.gaps[:, i] * scale,
            color=GAP_COLORS[g],
            label=g,
            linestyle="-" if i < 3 else "--",
        )
        if s.closed_form:
            ax.plot(tab.t, tab.gaps[:, i] * scale, ".", color=GAP_COLORS[g], ms=3)
    if s.unperturbed is not None:  # the flapping: flown gaps against the tau-theory ones
        u = s.unperturbed
        for ax, i, scale in ((ax_pos, 2, 1.0), (ax_ang, 4, 180.0 / math.pi)):
            ax.plot(u.t, u.gaps[:, i] * scale, color="k", linewidth=0.8, linestyle=":",
                    label=f"{GAP_NAMES[i]} without flapping")  # fmt: skip
    ax_pos.set_ylabel("position gap [m]")
    ax_ang.set_ylabel("attitude gap [deg]")
    _draw_tau(ax_tau, s)
    for ax in (ax_pos, ax_ang, ax_tau):
        ax.axvline(s.touchdown, color="0.4", linewidth=0.9, linestyle="-.")
        ax.set_xlim(d.t[0], d.t[-1])
        ax.legend(loc="upper left" if ax is ax_tau else "best", ncol=2, fontsize=7)
    ax_pos.set_title(f"Gaps and τ against time (touchdown T = {s.touchdown:.3f} s, dash-dot)")
    for ax in (ax_pos, ax_ang):
        ax.tick_params(labelbottom=False)


def plot_trajectory(outdir: Path, out: Path | None = None) -> Path:
    """Draw the trajectory figure of the run in ``outdir``; returns the PNG path
    (default ``OUTDIR/plots/trajectory.png``)."""
    outdir = Path(outdir)
    s = load_samples(outdir)
    out = Path(out) if out is not None else outdir / "plots" / "trajectory.png"
    with style():
        fig = figure(12.5, 6.2)
        left, right = fig.subfigures(1, 2, width_ratios=(1.1, 1.0), wspace=0.04)
        ax3 = left.add_subplot(projection="3d")
        ax_pos, ax_ang, ax_tau = right.subplots(3, 1, sharex=True)
        _draw_3d(ax3, s)
        _draw_gaps(ax_pos, ax_ang, ax_tau, s)
        return save_figure(fig, out)
