"""``--overwrite`` replaces only a roslan run's own files: run.json lists what the run
wrote, and an OUTDIR holding another run (a nested run.json) or any other file is refused
with a clear message, nothing deleted - for ``simulate`` and per run folder of a batch."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
import yaml

from roslan.batch import parse_sweep, run_tasks, sweep_tasks
from roslan.cli import main
from roslan.errors import OutputError
from roslan.rundir.folder import finalize, make_temp

# a 0.2 s IMU-only landing (T = z0 / (k v0) = 0.3 / 1.5)
JOB: dict[str, Any] = {
    "trajectory": {"k": 0.5, "initial": {"position": [-0.4, 0.2, 0.3], "descent_rate": 3.0}},
    "sensors": [{"type": "imu", "name": "imu", "rate": 400.0}],
    "output": {"formats": ["ros1"], "ground_truth_rate": 50.0},
}


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {
        p.relative_to(folder).as_posix(): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _simulate(tmp_path: Path, out: Path, *extra: str) -> int:
    cfg = tmp_path / "job.yaml"
    cfg.write_text(yaml.safe_dump(JOB), encoding="utf-8")
    return main(["simulate", str(cfg), "-o", str(out), "--quiet", "--no-overview", *extra])


def test_run_json_lists_every_file_the_run_wrote(tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert _simulate(tmp_path, out) == 0
    files = json.loads((out / "run.json").read_text())["files"]
    assert files == sorted(_snapshot(out))
    assert {"run.json", "landing.bag", "imu.txt", "calib/imu.yaml"} <= set(files)
    # and --overwrite replaces such a folder
    assert _simulate(tmp_path, out, "--overwrite") == 0


def test_overwrite_refuses_a_folder_holding_another_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    assert _simulate(tmp_path, out) == 0
    assert _simulate(tmp_path, out / "deep" / "ranges") == 0  # the README's out/ranges
    before = _snapshot(tmp_path)
    capsys.readouterr()
    assert _simulate(tmp_path, out, "--overwrite") != 0
    err = capsys.readouterr().err
    assert err.startswith(f"error: output folder {out} holds another roslan run in ")
    assert str(out / "deep" / "ranges") in err
    assert "refusing to replace it even with --overwrite" in err
    assert "Traceback" not in err
    assert _snapshot(tmp_path) == before  # nothing deleted, nothing written
    assert sorted(p.name for p in tmp_path.iterdir()) == ["job.yaml", "out"]


def test_overwrite_refuses_a_file_the_run_did_not_write(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    assert _simulate(tmp_path, out) == 0
    (out / "plots").mkdir()
    (out / "plots" / "notes.txt").write_text("mine", encoding="utf-8")
    before = _snapshot(tmp_path)
    capsys.readouterr()
    assert _simulate(tmp_path, out, "--overwrite") != 0
    err = capsys.readouterr().err
    assert "holds files its roslan run did not write: plots/notes.txt;" in err
    assert _snapshot(tmp_path) == before
    # the dry run gives the same verdict
    assert _simulate(tmp_path, out, "--overwrite", "--dry-run") != 0
    assert "plots/notes.txt" in capsys.readouterr().err
    # a run.json that does not list its files (an older roslan) cannot vouch for them
    (out / "plots" / "notes.txt").unlink()
    manifest = json.loads((out / "run.json").read_text())
    del manifest["files"]
    (out / "run.json").write_text(json.dumps(manifest), encoding="utf-8")
    assert _simulate(tmp_path, out, "--overwrite") != 0
    assert "without the list of the files" in capsys.readouterr().err


def test_figures_roslan_writes_into_a_run_are_the_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``roslan plot imu OUT`` writes OUT/plots/imu.png and lists it in OUT/derived.txt, so
    the next ``--overwrite`` (``make demo`` after the README's plots) replaces it; a file
    of the user's beside it still stops the replacement."""
    out = tmp_path / "out"
    assert _simulate(tmp_path, out) == 0
    assert main(["plot", "imu", str(out)]) == 0
    assert main(["plot", "imu", str(out), "-o", str(tmp_path / "beside.png")]) == 0
    assert (out / "plots" / "imu.png").is_file()
    assert (out / "derived.txt").read_text() == "plots/imu.png\n"  # not the one beside
    (out / "plots" / "mine.txt").write_text("mine", encoding="utf-8")
    capsys.readouterr()
    assert _simulate(tmp_path, out, "--overwrite") != 0
    err = capsys.readouterr().err
    assert "holds files its roslan run did not write: plots/mine.txt;" in err
    (out / "plots" / "mine.txt").unlink()
    assert _simulate(tmp_path, out, "--overwrite") == 0
    assert not (out / "plots").exists()
    assert not (out / "derived.txt").exists()


def test_a_file_arriving_during_the_run_stops_the_replacement(tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert _simulate(tmp_path, out) == 0
    (out / "late.txt").write_text("x", encoding="utf-8")
    before = _snapshot(out)
    tmp = make_temp(out)
    (tmp / "run.json").write_text("{}", encoding="utf-8")
    with pytest.raises(OutputError, match=r"did not write: late\.txt"):
        finalize(tmp, out, overwrite=True)
    assert _snapshot(out) == before


def test_batch_overwrite_keeps_a_task_folder_with_foreign_files(tmp_path: Path) -> None:
    out = tmp_path / "sweep"
    sweep = parse_sweep({"base": JOB, "axes": [{"zip": {"seed": [1, 2]}}]}, base_dir=tmp_path)
    report = run_tasks(sweep_tasks(sweep), out, workers=0, progress=False)
    assert [r.status for r in report.results] == ["complete"] * 2
    (out / "0001" / "analysis.csv").write_text("1,2\n", encoding="utf-8")
    before = _snapshot(out / "0001")
    report = run_tasks(sweep_tasks(sweep), out, workers=0, progress=False, overwrite=True)
    first, second = report.results
    assert first.status == "complete"
    assert second.status == "failed"
    assert second.error is not None
    assert "did not write: analysis.csv" in second.error
    assert _snapshot(out / "0001") == before
