"""``--dry-run`` refuses what the run refuses, with the run's own message, and writes
nothing: ``simulate``, ``batch`` (and ``dataset``, through the same per-task check)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from roslan.batch import dry_check, load_sweep, sweep_tasks
from roslan.cli import main
from roslan.config.sim import SimConfig
from roslan.errors import RoslanError
from roslan.pipeline import run_simulation


def _job(**altimeter: Any) -> dict[str, Any]:
    """A short landing on the empty scene's ground with one altimeter."""
    alt = {"type": "altimeter", "name": "altimeter", "rate": 20.0, **altimeter}
    return {
        "trajectory": {
            "k": 0.5,
            "initial": {"position": [-1.0, 0.3, 1.0], "descent_rate": 1.0},
            "hold": 0.2,
        },
        "scene": "empty",
        "sensors": [alt],
    }


BELOW = {"pose": {"position": [0.0, 0.0, -0.2]}}
"""20 cm below base_link: under the feet (z = -0.08), so it enters the ground at touchdown."""


def _files(root: Path) -> list[Path]:
    return sorted(p for p in root.rglob("*") if p.name != "job.yaml")


def _run_error(config: dict[str, Any], outdir: Path, **kw: Any) -> str:
    with pytest.raises(RoslanError) as err:
        run_simulation(SimConfig.model_validate(config), outdir, quiet=True, **kw)
    return str(err.value)


@pytest.mark.parametrize("case", ["altimeter-below-base-link", "outdir-exists", "no-scene"])
def test_simulate_dry_run_refuses_what_the_run_refuses(
    case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    job, outdir, flag = _job(), tmp_path / "out", "--overwrite"
    if case == "altimeter-below-base-link":
        job, flag = _job(**BELOW), "--allow-collision"
    elif case == "outdir-exists":
        outdir.mkdir()
        # an old roslan output (--overwrite may replace it: it holds only its files)
        (outdir / "run.json").write_text('{"complete": true, "files": ["run.json"]}')
    else:  # a sensor that needs a scene (sonar ray casts it), without one
        job = {**_job(), "scene": None}
        job["sensors"] = [{"type": "sonar", "name": "sonar", "rate": 20.0}]
        flag = ""
    path = tmp_path / "job.yaml"
    path.write_text(yaml.safe_dump(job), encoding="utf-8")
    before = _files(tmp_path)
    real = _run_error(job, outdir)
    assert _files(tmp_path) == before  # the run refused before writing
    capsys.readouterr()
    rc = main(["simulate", str(path), "-o", str(outdir), "--dry-run"])
    err = capsys.readouterr().err
    assert rc == 2
    assert real in err, (real, err)  # the run's own message
    if case != "outdir-exists":  # config problems name the file
        assert f"error: {path}:" in err
    assert _files(tmp_path) == before  # the dry run wrote nothing
    if case == "altimeter-below-base-link":
        assert "sensor 'altimeter' (origin) enters object 'ground'" in real
    if flag:  # what lifts the run's refusal lifts the dry run's
        assert main(["simulate", str(path), "-o", str(outdir), "--dry-run", flag]) == 0
        assert "1 valid, 0 invalid" in capsys.readouterr().out
        assert _files(tmp_path) == before


def test_batch_dry_run_refuses_what_the_batch_refuses(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Per task: the clearance check, a foreign complete run in the task's folder and a
    non-roslan folder are refused by name, as the batch itself reports them."""
    sweep = {
        "base": _job(),
        "axes": [{"grid": {"sensors.0.pose.position": [[0.0, 0.0, 0.0], [0.0, 0.0, -0.2]]}}],
    }
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump(sweep), encoding="utf-8")
    out = tmp_path / "b"
    rc = main(["batch", str(path), "-o", str(out), "--dry-run", "--workers", "1"])
    assert rc == 1
    assert "1 valid, 1 invalid" in capsys.readouterr().out
    assert not out.exists()
    # the table's message (wrapped in its cell) is the batch's own, task by task
    verdicts = [dry_check(t, out) for t in sweep_tasks(load_sweep(path))]
    assert verdicts[0] is None
    assert verdicts[1] is not None
    assert "sensor 'altimeter' (origin) enters object 'ground'" in verdicts[1]
    # a folder that is not a roslan output, for the valid task: the run would refuse it
    sweep["axes"] = [{"grid": {"seed": [0, 1]}}]
    path.write_text(yaml.safe_dump(sweep), encoding="utf-8")
    (out / "0000").mkdir(parents=True)
    (out / "0000" / "notes.txt").write_text("mine")
    before = _files(tmp_path)
    rc = main(["batch", str(path), "-o", str(out), "--dry-run", "--workers", "1"])
    assert rc == 1
    assert "1 valid, 1 invalid" in capsys.readouterr().out
    verdicts = [dry_check(t, out) for t in sweep_tasks(load_sweep(path))]
    assert verdicts[0] is not None
    assert "not a roslan output" in verdicts[0]
    assert verdicts[1] is None
    assert _files(tmp_path) == before


def test_batch_dry_run_reports_a_foreign_complete_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    sweep = {"base": _job(), "axes": [{"grid": {"seed": [0]}}]}
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump(sweep), encoding="utf-8")
    out = tmp_path / "b"
    (out / "0000").mkdir(parents=True)
    (out / "0000" / "run.json").write_text(
        '{"complete": true, "config": {"seed": 99}, "files": ["run.json"]}', encoding="utf-8"
    )
    rc = main(["batch", str(path), "-o", str(out), "--dry-run", "--workers", "1"])
    assert rc == 1
    assert "0 valid, 1 invalid" in capsys.readouterr().out
    (task,) = sweep_tasks(load_sweep(path))
    assert "holds a complete run of a different config" in str(dry_check(task, out))
    assert main(["batch", str(path), "-o", str(out), "--dry-run", "--overwrite"]) == 0
