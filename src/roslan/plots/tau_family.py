"""``roslan plot tau-family``: gap closure for several tau-dot values k (paper, Fig. 1)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from roslan.errors import ConfigError
from roslan.io.files import atomic_write
from roslan.trajectory.tau import classify, gap

__all__ = ["DEFAULT_KS", "plot_tau_family"]

DEFAULT_KS = (0.2, 0.4, 0.5, 0.7, 1.0)


def plot_tau_family(
    ks: Sequence[float], path: Path, *, gap0: float = 1.0, rate0: float = 1.0
) -> None:
    """Gap, closure rate and acceleration against time for each ``k``, all starting from
    the same gap ``gap0`` (m) closing at ``rate0`` (m/s), so T = gap0 / (k rate0) differs.

    ``k = 1`` is allowed here to show the constant-speed collision. Writes a PNG at
    ``path`` atomically (matplotlib Agg, deterministic).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    for k in ks:
        if not (math.isfinite(k) and 0.0 < k <= 1.0):
            msg = f"--k {k}: every k must satisfy 0 < k <= 1"
            raise ConfigError(msg)
    fig = Figure(figsize=(12.0, 4.0), dpi=100)
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 3)
    t_end = max(gap0 / (k * rate0) for k in ks)
    acc_cap = 0.0
    for k in sorted(ks):
        T = gap0 / (k * rate0)
        t = np.linspace(0.0, T, 400)
        s = np.clip(1.0 - t / T, 0.0, 1.0)
        g, dg, ddg = gap(gap0, 1.0 / k, T, s)
        label = f"k = {k:g} ({classify(k).value.replace('_', ' ')})"
        axes[0].plot(t, g, lw=1.5, label=label)
        axes[1].plot(t, -dg, lw=1.5)
        axes[2].plot(t[:-1], ddg[:-1], lw=1.5)  # the last point may be unbounded (k > 0.5)
        acc_cap = max(acc_cap, float(ddg[0]))
    axes[0].set_title("gap χ [m] (closes at T = χ0 / (k |χ'0|))")
    axes[1].set_title("closure rate -χ' [m/s]")
    axes[2].set_title("acceleration χ'' [m/s²] (braking > 0)")
    for ax, unit in zip(axes, ("χ [m]", "-χ' [m/s]", "χ'' [m/s²]"), strict=True):
        ax.set_ylabel(unit)
    axes[2].set_ylim(-0.05 * max(acc_cap, 1e-9) * 4, 4.0 * max(acc_cap, 1e-9))
    for ax in axes:
        ax.set_xlabel("t [s]")
        ax.set_xlim(0.0, t_end * 1.02)
        ax.grid(True, lw=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"tau-constant gap closure, χ0 = {gap0:g} m, χ'0 = -{rate0:g} m/s")
    fig.tight_layout()
    with atomic_write(path, "wb") as fh:
        fig.savefig(fh, format="png", metadata={"Software": None})
