"""The tau panel of ``roslan plot trajectory`` stays readable with flapping (the default
job's): tau is drawn for the tau-theory gaps, the paper's Fig. 3 check (tau_z on its
theory line tau0 + k t) holds on what is drawn, and no spike of the flown gaps' tau (a
rate crossing zero) stretches the axes."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

import roslan.plots.trajectory as traj_plot
from roslan.config.sim import SimConfig
from roslan.pipeline import run_simulation
from roslan.plots.trajectory import load_samples, tau_limits, tau_of

# the default job's landing and flapping, shortened: T = 1.0 / (0.5 * 2.0) = 1 s
JOB: dict[str, Any] = {
    "trajectory": {
        "k": 0.5,
        "initial": {"position": [-1.6, 0.4, 1.0], "rpy": [0.05, 0.15, 0.3], "descent_rate": 2.0},
        "flapping": {"frequency": 4.5, "heave": 0.008, "pitch": 0.035},
        "hold": 0.2,
    },
    "output": {"formats": ["ros1"], "ground_truth_rate": 50.0},
}


@pytest.fixture(scope="module")
def flapping_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("tau") / "run"
    run_simulation(SimConfig.model_validate(JOB), out, quiet=True, overview=False)
    return out


def _land(s: Any) -> np.ndarray:
    return np.asarray(s.dense.t < s.touchdown - 1e-9)


def test_fig3_check_on_the_tau_theory_gaps(flapping_run: Path) -> None:
    s = load_samples(flapping_run)
    assert s.unperturbed is not None
    assert s.k == 0.5
    assert s.tau0 is not None
    land = _land(s)
    t = s.unperturbed.t[land]
    tau_z = tau_of(s.unperturbed.gaps[land, 2], s.unperturbed.rates[land, 2])
    np.testing.assert_allclose(tau_z, s.tau0 + s.k * t, atol=1e-9)
    # the flown pitch gap's rate crosses zero with the flapping: tau runs off
    flown = tau_of(s.dense.gaps[land, 4], s.dense.rates[land, 4])
    assert np.nanmax(np.abs(flown)) > 5.0 * abs(s.tau0)
    # where the flapping has faded, the flown height gap's tau meets the theory too
    np.testing.assert_allclose(s.unperturbed.gaps[~land, 2], s.dense.gaps[~land, 2], atol=1e-12)


def test_tau_limits_ignore_spikes(flapping_run: Path) -> None:
    s = load_samples(flapping_run)
    assert s.tau0 is not None
    assert s.k is not None
    land = _land(s)
    d = s.dense
    flown = [tau_of(d.gaps[land, i], d.rates[land, i]) for i in range(6)]
    theory = s.tau0 + s.k * np.array([0.0, s.touchdown])
    lo, hi = tau_limits(flown, theory)
    assert lo <= s.tau0 < 0.0 < hi  # the theory line and tau = 0 inside
    # a spike of tau_pitch (tens of |tau0|) does not stretch them
    assert lo > 2.0 * s.tau0
    assert hi < 0.6 * abs(s.tau0)


def test_the_drawn_tau_panel_shows_the_theory_line(
    flapping_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    drawn: list[Any] = []
    save = traj_plot.save_figure

    def keep(fig: Any, out: Path) -> Path:
        drawn.append(fig)
        return save(fig, out)

    monkeypatch.setattr(traj_plot, "save_figure", keep)
    assert traj_plot.plot_trajectory(flapping_run, tmp_path / "t.png").is_file()
    (fig,) = drawn
    (ax,) = [a for a in fig.axes if a.get_ylabel().startswith("τ")]
    s = load_samples(flapping_run)
    assert s.tau0 is not None
    lo, hi = ax.get_ylim()
    assert lo <= s.tau0 < hi
    assert hi - lo < 2.0 * abs(s.tau0)  # the theory line spans most of the panel
    labels = [line.get_label() for line in ax.get_lines()]
    assert "τ_z" in labels
    assert any(label.startswith("τ_z theory") for label in labels)
    # every tau curve drawn stays inside the panel (no clipped spike)
    for line in [ln for ln in ax.get_lines() if str(ln.get_label()).startswith("τ")]:
        y = np.asarray(line.get_ydata(), dtype=float)
        y = y[np.isfinite(y)]
        assert y.size == 0 or (y.min() >= lo and y.max() <= hi), line.get_label()


def test_coincident_groups_join_curves_one_line_apart() -> None:
    """Curves within half a percent of the panel's height share a group; the NaN a gap's
    tau takes at the goal (0 / 0), a few samples apart, does not split a group."""
    t = np.linspace(0.0, 1.0, 200)
    line = -1.0 + t
    late = line.copy()
    late[-3:] = np.nan
    curves = {
        "x": -2.0 + 2.0 * t,
        "roll": line,
        "pitch": late,
        "yaw": line + 0.004,  # 0.4 % of a span of 1: on the line
        "y": line + 0.02,  # 2 %: a line of its own
    }
    assert traj_plot.coincident_groups(curves, span=1.0) == [
        ["x"],
        ["roll", "pitch", "yaw"],
        ["y"],
    ]
    mostly_nan = line.copy()
    mostly_nan[:50] = np.nan  # finite at 3/4 of the samples only: not the same curve
    assert traj_plot.coincident_groups({"a": line, "b": mostly_nan}, 1.0) == [["a"], ["b"]]


def test_coinciding_tau_curves_take_turns_and_the_legend_says_so(
    flapping_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Equal kappa: tau_roll, tau_pitch and tau_yaw are one line. Each is drawn in dashes
    that take turns with the others' (every position of the line belongs to exactly one
    of them, so all three colours show), and the legend names the equality."""
    drawn: list[Any] = []
    save = traj_plot.save_figure

    def keep(fig: Any, out: Path) -> Path:
        drawn.append(fig)
        return save(fig, out)

    monkeypatch.setattr(traj_plot, "save_figure", keep)
    traj_plot.plot_trajectory(flapping_run, tmp_path / "t.png")
    (fig,) = drawn
    (ax,) = [a for a in fig.axes if a.get_ylabel().startswith("τ")]
    curves = [ln for ln in ax.get_lines() if len(ln.get_ydata()) > 2]
    ref = np.asarray(curves[3].get_ydata(), dtype=float)  # x, y, z, then roll
    shared = [
        ln
        for ln in curves
        if np.allclose(np.asarray(ln.get_ydata(), dtype=float), ref, equal_nan=True, atol=1e-9)
    ]
    assert [ln.get_color() for ln in shared] == [
        traj_plot.GAP_COLORS[g] for g in ("roll", "pitch", "yaw")
    ]
    patterns = [ln._unscaled_dash_pattern for ln in shared]
    period = sum(patterns[0][1])
    s = np.linspace(0.0, 3.0 * period, 997, endpoint=False)
    on = []
    for offset, (dash, gap) in patterns:
        phase = (s + offset) % (dash + gap)
        on.append(phase < dash)
    assert np.array_equal(np.sum(on, axis=0), np.ones(s.size))  # exactly one colour at a time
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert {"τ_roll", "τ_pitch = τ_roll", "τ_yaw = τ_roll", "τ_x", "τ_z"} <= set(legend)
