"""Running sweeps: Dask LocalCluster vs serial, worker death, resume, per-task failures."""

from __future__ import annotations

import json
import os
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import cloudpickle
import pytest

from roslan.batch import make_tasks, parse_sweep, run_tasks, sweep_tasks, validate_config
from roslan.pipeline import run_simulation

# Workers unpickle the fault-injecting runners below by value (this module is not
# importable from a worker process).
cloudpickle.register_pickle_by_value(sys.modules[__name__])

# Tiny IMU-only landings: 0.3 m up at 3 m/s descent -> T = 0.2 s, ~300 messages.
BASE: dict[str, Any] = {
    "trajectory": {"k": 0.5, "initial": {"position": [-0.4, 0.2, 0.3], "descent_rate": 3.0}},
    "sensors": [{"type": "imu", "name": "imu", "rate": 400.0, "topic": "/imu"}],
    "output": {"formats": ["ros1"], "ground_truth_rate": 50.0},
}
# Files that report this run's wall-clock speed (documented by the pipeline).
TIMED = {"timing.json", "PLAYBACK.md"}


def _sweep(**axes: list[Any]) -> Any:
    return parse_sweep({"base": BASE, "axes": [{"zip": axes}]}, base_dir=Path.cwd())


def _files(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name not in TIMED
    }


def _batch_json(out: Path) -> dict[str, Any]:
    data: dict[str, Any] = json.loads((out / "batch.json").read_text())
    return data


def _kill_first_time(
    config: Any, outdir: Path, overwrite: bool, config_path: Path | None
) -> Mapping[str, Any]:
    """Runner that kills its own worker process the first time it runs task 0001."""
    marker = outdir.parent / "killed.marker"
    if outdir.name == "0001" and not marker.exists():
        marker.write_text(str(os.getpid()))
        (outdir.parent / ".0001.partial-killed").mkdir()  # what a killed simulation leaves
        os._exit(1)  # the worker dies mid-task, no cleanup, like an OOM kill
    return run_simulation(config, outdir, overwrite=overwrite, quiet=True)


def test_two_worker_cluster_survives_a_killed_worker_and_equals_serial_runs(
    tmp_path: Path,
) -> None:
    # One LocalCluster run (cluster start-up dominates the cost) checks both: a worker
    # killed mid-task does not stop the batch, and results equal serial runs byte for byte.
    out = tmp_path / "dask"
    sweep = _sweep(seed=[1, 2, 3], **{"trajectory.kappa.x": [0.4, 0.6, 0.8]})
    tasks = sweep_tasks(sweep)
    report = run_tasks(tasks, out, workers=2, progress=False, runner=_kill_first_time)
    assert report.workers == 2
    assert (out / "killed.marker").exists()  # the worker really died once
    assert [r.status for r in report.results] == ["complete"] * 3, report.results
    # the real number of attempts is recorded, and the killed attempt's partial folder is gone
    assert [r.attempts for r in report.results] == [1, 2, 1]
    assert not list(out.glob(".*partial*"))
    assert not list(out.glob(".*.attempts"))
    # the same configs, simulated one after the other in this process
    for task in tasks:
        cfg = validate_config(task.config, task.base_dir, "test")
        run_simulation(cfg, tmp_path / "serial" / task.name, quiet=True)
        got = _files(out / task.name)
        want = _files(tmp_path / "serial" / task.name)
        assert got.keys() == want.keys()
        assert "landing.bag" in got
        assert "imu.txt" in got
        for name in want:
            assert got[name] == want[name], name
    # the three tasks really differ (seed and kappa reach the simulation)
    assert len({(out / t.name / "imu.txt").read_bytes() for t in tasks}) == 3
    data = _batch_json(out)
    assert data["finished"] is True
    assert data["counts"] == {"complete": 3}
    assert [t["attempts"] for t in data["tasks"]] == [1, 2, 1]
    assert [t["overrides"]["seed"] for t in data["tasks"]] == [1, 2, 3]
    # rerun: everything is skipped, nothing is rewritten
    stamp = {t.name: (out / t.name / "run.json").stat().st_mtime_ns for t in tasks}
    again = run_tasks(sweep_tasks(sweep), out, workers=2, progress=False)
    assert [r.status for r in again.results] == ["skipped"] * 3
    assert {t.name: (out / t.name / "run.json").stat().st_mtime_ns for t in tasks} == stamp
    assert again.results[0].messages is not None
    assert again.results[0].messages > 0
    assert _batch_json(out)["counts"] == {"skipped": 3}


def test_changed_config_in_a_completed_folder_is_not_skipped(tmp_path: Path) -> None:
    out = tmp_path / "out"
    run_tasks(sweep_tasks(_sweep(seed=[1])), out, workers=0, progress=False)
    report = run_tasks(sweep_tasks(_sweep(seed=[9])), out, workers=0, progress=False)
    (res,) = report.results
    assert res.status == "failed"
    assert res.error is not None
    assert "different config" in res.error
    assert "--overwrite" in res.error
    report = run_tasks(
        sweep_tasks(_sweep(seed=[9])), out, workers=0, progress=False, overwrite=True
    )
    assert report.results[0].status == "complete"
    assert json.loads((out / "0000" / "run.json").read_text())["seed"] == 9


def test_invalid_and_failing_tasks_are_reported_without_stopping_others(tmp_path: Path) -> None:
    out = tmp_path / "out"
    # task 1: k * kappa.x > 1 (invalid config); task 2: the scene file does not exist
    # (valid config, fails when simulated); tasks 0 and 3 are fine
    tasks = sweep_tasks(
        _sweep(
            **{
                "trajectory.kappa.x": [0.5, 3.0, 0.5, 0.6],
                "scene": [None, None, str(tmp_path / "missing.yaml"), None],
            }
        )
    )
    assert tasks[1].error is not None
    # debris of a simulation killed earlier (SIGKILL leaves the hidden partial folder)
    (out / ".0000.partial-x1y2").mkdir(parents=True)
    (out / ".0000.partial-x1y2" / "imu.txt").write_text("0 1 2\n")
    report = run_tasks(tasks, out, workers=0, retries=3, progress=False)
    assert not list(out.glob(".*partial*"))
    status = [r.status for r in report.results]
    assert status == ["complete", "invalid", "failed", "complete"]
    assert "kappa.x = 3.0" in (report.results[1].error or "")
    assert "missing.yaml" in (report.results[2].error or "")
    assert report.results[2].attempts == 1  # roslan errors are deterministic: no retry
    assert not report.ok
    data = _batch_json(out)
    assert data["counts"] == {"complete": 2, "invalid": 1, "failed": 1}
    assert "kappa.x = 3.0" in data["tasks"][1]["error"]
    assert not (out / "0001").exists()
    assert not (out / "0002").exists()


def _flaky(
    config: Any, outdir: Path, overwrite: bool, config_path: Path | None
) -> Mapping[str, Any]:
    """Raises OSError on the first attempt of each task, then simulates."""
    marker = outdir.parent / f"{outdir.name}.tried"
    if not marker.exists():
        marker.write_text("1")
        raise OSError("transient failure")
    return run_simulation(config, outdir, overwrite=overwrite, quiet=True)


def _always_crash(
    config: Any, outdir: Path, overwrite: bool, config_path: Path | None
) -> Mapping[str, Any]:
    if outdir.name == "0000":
        raise RuntimeError("simulator crashed")
    return run_simulation(config, outdir, overwrite=overwrite, quiet=True)


def test_transient_failures_are_retried_then_reported(tmp_path: Path) -> None:
    report = run_tasks(
        sweep_tasks(_sweep(seed=[1, 2])),
        tmp_path / "a",
        workers=0,
        retries=1,
        runner=_flaky,
        progress=False,
    )
    assert [(r.status, r.attempts) for r in report.results] == [("complete", 2)] * 2
    report = run_tasks(
        sweep_tasks(_sweep(seed=[1, 2])),
        tmp_path / "b",
        workers=0,
        retries=2,
        runner=_always_crash,
        progress=False,
    )
    assert [r.status for r in report.results] == ["failed", "complete"]
    assert report.results[0].attempts == 3
    assert "RuntimeError: simulator crashed" in (report.results[0].error or "")


def test_make_tasks_rejects_duplicate_names(tmp_path: Path) -> None:
    from roslan.errors import ConfigError

    with pytest.raises(ConfigError, match="not unique"):
        make_tasks([BASE, BASE], tmp_path, names=["a", "a"])


def test_batch_cli_end_to_end(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import yaml

    from roslan.cli import main

    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(
        yaml.safe_dump(
            {
                "base": BASE,
                "axes": [{"grid": {"seed": [4, 5]}}, {"zip": {"trajectory.k": [0.5, 1.5]}}],
            }
        )
    )
    rc = main(["batch", str(sweep), "-o", str(tmp_path / "out"), "--workers", "0", "--quiet"])
    assert rc == 1  # k = 1.5 is invalid for two tasks
    err = capsys.readouterr().out
    assert "error: 0001" in err
    assert "trajectory.k = 1.5" in err
    data = _batch_json(tmp_path / "out")
    assert data["counts"] == {"complete": 2, "invalid": 2}
    rc = main(["batch", str(tmp_path / "nope.yaml"), "-o", str(tmp_path / "x")])
    assert rc == 2
    assert "nope.yaml: file not found" in capsys.readouterr().err
