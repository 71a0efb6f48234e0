"""The incremental run driver: a run stepped every 20 ms on a growing trajectory writes
the OUTDIR ``simulate`` writes for the same landing, byte for byte (its measured speed
aside), plus its extra files; an aborted run leaves no OUTDIR; without an OUTDIR nothing
is written."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from roslan.config.sim import SimConfig
from roslan.pipeline import RunOptions, open_run, run_simulation
from roslan.trajectory import TauTrajectory
from roslan.trajectory.base import HorizonError, HorizonGuard
from roslan.vehicle import base_link_trajectory

CONFIG = {
    "sensors": [{"type": "imu", "name": "imu", "rate": 400.0}],
    "trajectory": {"k": 0.5, "initial": {"position": [0, 0, 0.3], "descent_rate": 1.0}},
    "output": {"ground_truth_rate": 100.0},
    "seed": 3,
}
STEP_NS = 20_000_000


def _guard(cfg: SimConfig) -> tuple[HorizonGuard, int]:
    traj = TauTrajectory(base_link_trajectory(cfg.trajectory, cfg.vehicle, None))
    return HorizonGuard(traj), traj.duration_ns


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in root.rglob("*") if p.is_file()}


def test_a_stepped_live_run_writes_simulate_s_outdir(tmp_path: Path) -> None:
    cfg = SimConfig.model_validate(CONFIG)
    run_simulation(cfg, tmp_path / "sim", quiet=True)
    guard, end = _guard(cfg)
    run = open_run(cfg, tmp_path / "live", guard, RunOptions(quiet=True))
    h, n_imu = 0, 0
    while h + STEP_NS < end:
        h += STEP_NS
        guard.set_horizon(h)
        step = run.advance(h)
        assert all(m.t_ns <= h for m in step.messages)
        n_imu += sum(tap["t"].size for tap in step.tap("imu"))
    guard.finish()
    last, manifest = run.finish(end, {"episode.json": b'{"policy": "test"}\n'})
    n_imu += sum(tap["t"].size for tap in last.tap("imu"))
    assert manifest is not None
    assert manifest["complete"]
    sim, live = _files(tmp_path / "sim"), _files(tmp_path / "live")
    assert live.pop("episode.json") == b'{"policy": "test"}\n'
    for name in ("timing.json", "PLAYBACK.md"):  # this run's measured speed
        sim.pop(name), live.pop(name)
    # drawn from the trajectory's type: the tau panels of a TauTrajectory, not of its guard
    sim.pop("trajectory.png"), live.pop("trajectory.png")
    assert sorted(live) == sorted(sim)
    # README.md and run.json describe the extra file too, and nothing else differs
    readme = live.pop("README.md").decode().splitlines()
    episode_rows = [ln for ln in readme if ln.startswith("| `episode.json` |")]
    assert len(episode_rows) == 1
    assert [ln for ln in readme if ln not in episode_rows] == sim.pop(
        "README.md"
    ).decode().splitlines()
    live_run, sim_run = json.loads(live.pop("run.json")), json.loads(sim.pop("run.json"))
    assert live_run.pop("files") == sorted([*sim_run.pop("files"), "episode.json"])
    assert live_run == sim_run
    assert [k for k in sim if sim[k] != live[k]] == []
    assert n_imu == len((tmp_path / "sim" / "imu.txt").read_text().splitlines())


def test_an_aborted_or_failed_live_run_leaves_no_outdir(tmp_path: Path) -> None:
    cfg = SimConfig.model_validate(CONFIG)
    guard, _ = _guard(cfg)
    run = open_run(cfg, tmp_path / "out", guard)
    guard.set_horizon(STEP_NS)
    run.advance(STEP_NS)
    run.abort()
    assert list(tmp_path.iterdir()) == []
    # a sensor reading past the horizon: the error comes back, the folder goes
    guard, _ = _guard(cfg)
    run = open_run(cfg, tmp_path / "out", guard)
    with pytest.raises(HorizonError):
        run.advance(STEP_NS)  # the trajectory was not grown to the step's end
    assert list(tmp_path.iterdir()) == []


def test_a_live_run_without_outdir_writes_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """No recorder attached: no bags, no folder, not even a temporary one; the taps are
    the recorded run's readings (imu.txt of the same landing)."""
    import tempfile

    cfg = SimConfig.model_validate(CONFIG)
    run_simulation(cfg, tmp_path / "sim", quiet=True)
    quiet = tmp_path / "quiet"
    (quiet / "tmp").mkdir(parents=True)
    monkeypatch.setenv("TMPDIR", str(quiet / "tmp"))
    monkeypatch.setattr(tempfile, "tempdir", None)  # gettempdir() reads TMPDIR again
    monkeypatch.chdir(quiet)
    guard, end = _guard(cfg)
    run = open_run(cfg, None, guard)
    assert run.rec is None
    h, rows = 0, []
    while h + STEP_NS < end:
        h += STEP_NS
        guard.set_horizon(h)
        step = run.advance(h)
        rows += [
            np.column_stack([tap["t"] * 1e-9, tap["acc"], tap["gyro"]]) for tap in step.tap("imu")
        ]
    guard.finish()
    last, manifest = run.finish(end)
    rows += [np.column_stack([tap["t"] * 1e-9, tap["acc"], tap["gyro"]]) for tap in last.tap("imu")]
    assert manifest is None
    assert list(quiet.rglob("*")) == [quiet / "tmp"]
    written = np.loadtxt(tmp_path / "sim" / "imu.txt")
    # (imu.txt holds 9 significant digits)
    np.testing.assert_allclose(np.concatenate(rows), written, rtol=1e-8, atol=1e-12)
