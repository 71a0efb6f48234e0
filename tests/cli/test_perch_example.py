"""The perching example (README, "Perching"): valid as written, passes the run's own
checks over its full landing, and - shortened to about a second like every README
example under test - runs and ends with the grasp point on the refinery's pipe.

The YAML is read from the README itself (:data:`PERCH_YAML`), never copied here.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from roslan.cli import main
from roslan.config.sim import SimConfig
from roslan.frames import quat_xyzw_to_matrix
from roslan.pipeline import check_run
from roslan.rundir.readers import load_groundtruth
from roslan.scene import load_scene
from roslan.scene.goal import GoalNote
from roslan.trajectory.config import Initial

README = Path(__file__).resolve().parents[2] / "README.md"


def _readme_perch_yaml() -> str:
    """The README's ``# perch.yaml`` block, exactly as shown there."""
    blocks = re.findall(
        r"^```yaml\n(# perch\.yaml\n.*?)^```", README.read_text("utf-8"), re.M | re.S
    )
    assert len(blocks) == 1, "README.md shows one perch.yaml"
    return str(blocks[0])


PERCH_YAML = _readme_perch_yaml()

GRASP = np.array([0.0, 0.0, -0.08])  # the default vehicle's grasp point in base_link


def test_perch_example_passes_the_runs_checks(tmp_path: Path) -> None:
    path = tmp_path / "perch.yaml"
    path.write_text(PERCH_YAML, encoding="utf-8")
    config = SimConfig.model_validate(yaml.safe_load(PERCH_YAML))
    assert "goal" not in config.trajectory.model_fields_set
    with pytest.warns(GoalNote, match="perch of scene 'refinery'"):
        plan = check_run(config, tmp_path / "perch_out", config_path=path)
    assert plan.config.trajectory.goal.position == (0.0, 0.0, 2.5)
    assert not (tmp_path / "perch_out").exists()


def test_perch_example_runs_and_grips_the_pipe(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = yaml.safe_load(PERCH_YAML)
    # shortened (as the README's examples are under test): a 1.25 s landing, no hold
    data["trajectory"].pop("approach")
    short = Initial(position=(-1.0, 0.3, 0.5), rpy=(0.05, 0.1, 0.2), descent_rate=1.0)
    data["trajectory"]["initial"] = short.model_dump()
    data["trajectory"]["hold"] = 0.0
    path = tmp_path / "perch.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    out = tmp_path / "perch_out"
    argv = ["simulate", str(path), "-o", str(out), "--quiet", "--no-overview", "--workers", "0"]
    rc = main([*argv, "--format", "ros1"])
    err = capsys.readouterr().err
    assert rc == 0, err
    assert [ln for ln in err.splitlines() if ln.startswith("note:")], err
    for name in ("landing.bag", "imu.txt", "range_sonar.txt"):  # the README's sensors
        assert (out / name).exists(), name
    gt = load_groundtruth(out)
    assert gt is not None
    _, p, q = gt
    grasp = p[-1] + quat_xyzw_to_matrix(q[-1]) @ GRASP
    v = load_scene("refinery").object("perching_pipe").vertices.astype(np.float64)
    top = v[v[:, 2] > v[:, 2].max() - 1e-4]  # the pipe's top line
    np.testing.assert_allclose(grasp, top.mean(axis=0), atol=2e-6)
