"""The ``output.labels`` switch and the per-sensor ``labels`` opt-out (issue 47)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from roslan.config.base import load_yaml_model, validate_model
from roslan.config.sim import SimConfig
from roslan.errors import ConfigError
from roslan.pipeline.plan import check_run, make_plan

LABELLED_TYPES = [
    {"type": "camera", "name": "cam", "rate": 10.0},
    {"type": "stereo_camera", "name": "stereo", "rate": 10.0},
    {"type": "depth_camera", "name": "depth", "rate": 10.0},
    {"type": "event_camera", "name": "dvs", "rate": 10.0},
    {"type": "lidar", "name": "lidar"},
    {"type": "solid_state_lidar", "name": "livox"},
    {"type": "laser", "name": "laser"},
    {"type": "sonar", "name": "sonar"},
    {"type": "altimeter", "name": "alt"},
]


def test_defaults_leave_the_dump_unchanged() -> None:
    """At their defaults the new keys are not in the dump (run.json stays byte-identical)."""
    cfg = SimConfig.model_validate({"scene": "warehouse", "sensors": LABELLED_TYPES})
    data = cfg.model_dump(mode="json")
    assert "labels" not in data["output"]
    assert all("labels" not in s for s in data["sensors"])
    assert cfg.output.labels is False
    assert all(s.labels is True for s in cfg.sensors)  # type: ignore[attr-defined]


def test_set_keys_are_dumped_and_read_back() -> None:
    sensors = [{**s, "labels": False} for s in LABELLED_TYPES]
    cfg = SimConfig.model_validate(
        {"scene": "warehouse", "output": {"labels": True}, "sensors": sensors}
    )
    data = cfg.model_dump(mode="json")
    assert data["output"]["labels"] is True
    assert [s["labels"] for s in data["sensors"]] == [False] * len(sensors)
    assert SimConfig.model_validate(data) == cfg


@pytest.mark.parametrize(
    ("data", "needle"),
    [
        ({"output": {"labels": "yes"}}, "output.labels = 'yes'"),
        ({"output": {"labels": 1}}, "output.labels = 1"),
        (
            {"sensors": [{"type": "camera", "name": "c", "rate": 5.0, "labels": "no"}]},
            "sensors[0].labels = 'no'",
        ),
        ({"sensors": [{"type": "imu", "name": "imu", "labels": False}]}, "sensors[0].labels"),
    ],
)
def test_bad_values_are_named(tmp_path: Path, data: dict[str, object], needle: str) -> None:
    path = tmp_path / "job.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError) as err:
        load_yaml_model(SimConfig, path)
    assert str(path) in str(err.value)
    assert needle in str(err.value)


def test_labels_without_a_scene_refused(tmp_path: Path) -> None:
    cfg = validate_model(SimConfig, {"output": {"labels": True}})
    with pytest.raises(ConfigError, match=r"output\.labels = true: .*has\s+none"):
        make_plan(cfg, tmp_path / "out")


def test_labels_on_a_scene_without_classes_refused(tmp_path: Path) -> None:
    scene = tmp_path / "bare.yaml"
    scene.write_text(
        yaml.safe_dump(
            {
                "name": "bare",
                "objects": [{"name": "floor", "primitive": {"type": "box", "size": [9, 9, 0.1]}}],
            }
        )
    )
    job = {
        "scene": str(scene),
        "trajectory": {"goal": {"position": [0, 0, 0.05], "rpy": [0, 0, 0]}},
        "output": {"labels": True},
    }
    cfg = validate_model(SimConfig, job)
    with pytest.raises(ConfigError) as err:
        check_run(cfg, tmp_path / "out")
    msg = str(err.value)
    assert "output.labels = true" in msg
    assert str(scene) in msg
    assert "no classes" in msg
    # the same scene with a class passes the check
    data = yaml.safe_load(scene.read_text())
    data["objects"][0]["class"] = "ground"
    scene.write_text(yaml.safe_dump(data))
    check_run(validate_model(SimConfig, job), tmp_path / "out")


def test_dataset_writes_labels_unless_told_not_to() -> None:
    from roslan.batch.paper import dataset_plan

    on = dataset_plan(["empty"], check_clearance=False, sensors=[])
    off = dataset_plan(["empty"], check_clearance=False, sensors=[], labels=False)
    assert all(SimConfig.model_validate(r.config).output.labels for r in on)
    assert not any(SimConfig.model_validate(r.config).output.labels for r in off)


def test_labels_guide_lists_the_class_table() -> None:
    import re

    from roslan.scene.classes import BUILTIN_CLASSES

    text = (Path(__file__).parents[2] / "docs" / "guide" / "labels.md").read_text()
    rows = re.findall(r"^\| (\d+) \| `([a-z_]+)` \| (.+?) \|$", text, flags=re.M)
    assert [(int(i), n, d) for i, n, d in rows] == list(BUILTIN_CLASSES)
