"""Goals come from the scene: a config without ``trajectory.goal`` lands on its scene's
landing marker or perch (one ``note:`` line), a scene without one keeps the world origin
(a warning); the final pose is checked against the marker's and the perch's geometry,
measured from the scene's own triangles."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from roslan.cli import main
from roslan.config.base import Pose
from roslan.errors import Note, SceneError
from roslan.frames import quat_xyzw_to_matrix
from roslan.rundir.readers import load_groundtruth
from roslan.scene import load_scene
from roslan.scene.goal import GoalNote, goal_from_scene, scene_goal
from roslan.trajectory import TrajectoryConfig

README = Path(__file__).resolve().parents[2] / "README.md"
DOCS = Path(__file__).resolve().parents[2] / "docs"

# T = z0 / (k v0) = 1 s, no goal
LANDING: dict[str, Any] = {
    "k": 0.5,
    "initial": {"position": [-1.0, 0.3, 1.0], "rpy": [0.05, 0.1, 0.2], "descent_rate": 2.0},
}
FEET_DROP = 0.08  # the default vehicle: feet centroid and grasp point 8 cm below base_link


def _simulate(
    tmp_path: Path, scene: str, capsys: pytest.CaptureFixture[str]
) -> tuple[np.ndarray, np.ndarray, str]:
    """Simulate LANDING in ``scene``: the contact point (feet centroid / grasp point) and
    base_link's rotation at the end, from groundtruth.txt, and the run's stderr."""
    cfg = tmp_path / "job.yaml"
    job = {"trajectory": LANDING, "scene": scene, "output": {"formats": ["ros1"]}}
    cfg.write_text(yaml.safe_dump(job), encoding="utf-8")
    out = tmp_path / "out"
    rc = main(["simulate", str(cfg), "-o", str(out), "--quiet", "--no-overview"])
    err = capsys.readouterr().err
    assert rc == 0, err
    gt = load_groundtruth(out)
    assert gt is not None
    _t, p, q = gt
    R = quat_xyzw_to_matrix(q[-1])
    return p[-1] + R @ np.array([0.0, 0.0, -FEET_DROP]), R, err


def test_warehouse_without_goal_lands_on_the_marker(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    contact, R, text = _simulate(tmp_path, "warehouse", capsys)
    notes = [ln for ln in text.splitlines() if ln.startswith("note:")]
    assert len(notes) == 1, text
    assert "landing marker" in notes[0]
    assert "warning:" not in text
    # the marker's top face, from its triangles: centre and edge directions
    v = load_scene("warehouse").object("landing_marker").vertices.astype(np.float64)
    top = v[np.isclose(v[:, 2], v[:, 2].max())]
    centre = np.array([*top[:, :2].mean(axis=0), v[:, 2].max()])
    np.testing.assert_allclose(contact, centre, atol=2e-6)
    # the feet stand level, and the body is square to the marker's edges (mod 90 deg)
    assert R[2, 2] == pytest.approx(1.0, abs=1e-9)
    edges = top[:, :2] - top[0, :2]
    length = np.linalg.norm(edges, axis=1)
    edge = edges[np.argmin(np.where(length < 1e-3, np.inf, length))]  # a side, not a diagonal
    edge_yaw = math.atan2(edge[1], edge[0])
    body_yaw = math.atan2(R[1, 0], R[0, 0])
    d = (body_yaw - edge_yaw) % (math.pi / 2)
    assert min(d, math.pi / 2 - d) < 1e-6


def test_refinery_without_goal_perches_on_the_pipe(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    contact, R, text = _simulate(tmp_path, "refinery", capsys)
    notes = [ln for ln in text.splitlines() if ln.startswith("note:")]
    assert len(notes) == 1, text
    assert "perch" in notes[0]
    # the pipe's top line, from its triangles: its highest vertices lie on it
    v = load_scene("refinery").object("perching_pipe").vertices.astype(np.float64)
    top = v[v[:, 2] > v[:, 2].max() - 1e-4]
    centre = top.mean(axis=0)
    np.testing.assert_allclose(contact, centre, atol=2e-6)
    # the grasp point meets the pipe across it: body x is perpendicular to the pipe's axis
    axis = np.linalg.svd(top - centre)[2][0]
    assert abs(float(R[:, 0] @ axis)) < 1e-6
    assert R[2, 2] == pytest.approx(1.0, abs=1e-9)


def test_a_scene_without_marker_keeps_the_origin_with_a_warning(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    contact, _, text = _simulate(tmp_path, "empty", capsys)
    warns = [ln for ln in text.splitlines() if ln.startswith("warning:")]
    assert len(warns) == 1, text
    assert "'empty'" in warns[0]
    assert "world origin" in warns[0]
    assert "note:" not in text
    np.testing.assert_allclose(contact, [0.0, 0.0, 0.0], atol=2e-9)


def test_a_configured_goal_wins_and_files_keep_their_frame() -> None:
    goal = Pose(position=(5.0, 1.0, 0.0), rpy=(0.0, 0.0, 1.0))
    given = TrajectoryConfig.model_validate({**LANDING, "goal": goal.model_dump()})
    assert goal_from_scene(given, "warehouse") is given
    file_traj = TrajectoryConfig.model_validate({"file": "poses.txt"})
    assert goal_from_scene(file_traj, "warehouse") is file_traj
    none = TrajectoryConfig.model_validate(LANDING)
    assert goal_from_scene(none, None) is none


def test_scene_files_give_their_goal_or_perch(tmp_path: Path) -> None:
    """A scene file's ``goal:`` (a perch without ``pose`` sits on it) or a perch placed by
    ``pose``; the loaded scene's goal agrees."""
    ground = [{"name": "floor", "primitive": {"type": "box", "size": [20, 20, 0.1]}}]
    cases: list[tuple[dict[str, Any], str | None, tuple[float, ...] | None]] = [
        ({"goal": {"position": [1, 2, 0.01]}}, "goal", (1.0, 2.0, 0.01)),
        ({"goal": {"position": [1, 2, 1.5]}, "perch": {"type": "bar"}}, "perch", (1, 2, 1.5)),
        ({"perch": {"type": "pipe", "pose": {"position": [3, 0, 1.2]}}}, "perch", (3, 0, 1.2)),
        ({}, None, None),
    ]
    for i, (extra, kind, position) in enumerate(cases):
        path = tmp_path / f"s{i}.yaml"
        path.write_text(yaml.safe_dump({"name": f"s{i}", "objects": ground, **extra}), "utf-8")
        found = scene_goal(path.name, base_dir=tmp_path)
        if kind is None:
            assert found is None
            continue
        assert found is not None
        assert found.kind == kind
        assert found.pose.position == pytest.approx(position)
        assert load_scene(path).goal_position == pytest.approx(position)
    with pytest.raises(SceneError, match=r"nor an existing scene file"):
        scene_goal("missing.yaml", base_dir=tmp_path)


def _stderr_of(argv: list[str], capsys: pytest.CaptureFixture[str]) -> list[str]:
    rc = main(argv)
    lines = capsys.readouterr().err.splitlines()
    assert rc != 0, lines
    return lines


@pytest.mark.parametrize("command", ["simulate", "trajectory"])
def test_a_scene_that_cannot_load_errs_before_any_goal_warning(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str
) -> None:
    """A misspelt scene name or a scene file whose mesh is missing: the error (naming the
    config, the closest built-in name, the missing file) is the only line; no warning
    about a landing marker the scene was never read for."""
    cfg = tmp_path / "job.yaml"
    misspelt = tmp_path / "misspelt.yaml"
    misspelt.write_text(yaml.safe_dump({"trajectory": LANDING, "scene": "warehous"}), "utf-8")
    scene = tmp_path / "mine.yaml"
    rack = {"name": "rack", "mesh": "models/rack.glb"}
    scene.write_text(yaml.safe_dump({"name": "mine", "objects": [rack]}), "utf-8")
    cfg.write_text(yaml.safe_dump({"trajectory": LANDING, "scene": "mine.yaml"}), "utf-8")
    extra = ["--dry-run"] if command == "simulate" else ["--no-plot"]
    for path, expected in [
        (misspelt, "scene 'warehous': neither a built-in scene"),
        (cfg, "objects[0] (name 'rack').mesh = 'models/rack.glb': file not found"),
    ]:
        lines = _stderr_of([command, str(path), "-o", str(tmp_path / "o"), *extra], capsys)
        assert len(lines) == 1, lines
        assert lines[0].startswith(f"error: {path}: "), lines
        assert expected in lines[0], lines
    lines = _stderr_of(["simulate", str(misspelt), "-o", str(tmp_path / "o")], capsys)
    assert lines[0].endswith("did you mean 'warehouse'?"), lines
    assert not (tmp_path / "o").exists()


def test_a_scene_file_without_goal_still_warns_once_it_loads(tmp_path: Path) -> None:
    """The origin warning is kept for a scene file that loads and defines no goal."""
    ground = [{"name": "floor", "primitive": {"type": "box", "size": [20, 20, 0.1]}}]
    (tmp_path / "bare.yaml").write_text(yaml.safe_dump({"name": "b", "objects": ground}))
    traj = TrajectoryConfig.model_validate(LANDING)
    with pytest.warns(UserWarning, match=r"scene 'bare.yaml' defines no landing marker"):
        same = goal_from_scene(traj, "bare.yaml", base_dir=tmp_path)
    assert same is traj


def test_goal_note_is_a_note() -> None:
    traj = TrajectoryConfig.model_validate(LANDING)
    with pytest.warns(GoalNote, match=r"perch of scene .refinery."):
        moved = goal_from_scene(traj, "refinery")
    assert issubclass(GoalNote, Note)
    assert moved.goal == Pose(position=(0.0, 0.0, 2.5), rpy=(0.0, 0.0, 0.25))


def _named_examples() -> dict[str, dict[str, Any]]:
    """The named YAML blocks (``# job.yaml`` first line) of README.md and docs/."""
    out: dict[str, dict[str, Any]] = {}
    for page in [README, *sorted(DOCS.rglob("*.md"))]:
        text = page.read_text(encoding="utf-8")
        for m in re.finditer(r"^```yaml\n# ([\w.]+\.yaml)\b.*?\n(.*?)^```", text, re.M | re.S):
            out.setdefault(m.group(1), yaml.safe_load(m.group(2)))
    return out


@pytest.mark.parametrize("name", ["job.yaml", "cameras.yaml", "events.yaml"])
def test_readme_examples_land_on_the_marker(name: str) -> None:
    """The README's warehouse examples give no goal: they land on the landing marker."""
    from roslan.config.sim import SimConfig
    from roslan.pipeline.plan import with_scene_goal

    data = _named_examples()[name]
    config = SimConfig.model_validate(data)
    with pytest.warns(GoalNote):
        flown = with_scene_goal(config, None)
    marker = scene_goal(str(config.scene))
    assert marker is not None
    assert marker.kind in ("landing marker", "perch")
    assert flown.trajectory.goal == marker.pose


def test_trajectory_command_flies_the_scene_goal(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``roslan trajectory CONFIG`` writes the landing ``roslan simulate`` flies."""
    import json

    cfg = tmp_path / "job.yaml"
    cfg.write_text(yaml.safe_dump({"trajectory": LANDING, "scene": "refinery"}), "utf-8")
    assert main(["trajectory", str(cfg), "-o", str(tmp_path / "t"), "--no-plot"]) == 0
    assert "note: trajectory.goal not set" in capsys.readouterr().err
    goal = json.loads((tmp_path / "t" / "summary.json").read_text())["goal"]
    # base_link's goal: the pipe's top, raised by the grasp point's 8 cm
    assert goal["position"] == pytest.approx([0.0, 0.0, 2.5 + FEET_DROP])
    assert goal["rpy"] == pytest.approx([0.0, 0.0, 0.25])
