"""Config loading at the edge: YAML -> models, errors naming file, key, value, allowed."""

from __future__ import annotations

from pathlib import Path

import pytest

from roslan.config.base import load_yaml_model, validate_model
from roslan.config.sim import SimConfig
from roslan.errors import ConfigError
from roslan.trajectory import TrajectoryConfig


def _load(tmp_path: Path, text: str) -> SimConfig:
    p = tmp_path / "sim.yaml"
    p.write_text(text)
    return load_yaml_model(SimConfig, p)


@pytest.mark.parametrize(
    ("yaml_text", "key", "words"),
    [
        ("trajectory: {k: 0}", "trajectory.k", "greater than or equal to 0.001"),
        ("trajectory: {k: -0.3}", "trajectory.k", "greater than or equal to 0.001"),
        ("trajectory: {k: 1.5}", "trajectory.k", "0 < k < 1"),
        ("trajectory: {k: 1}", "trajectory.k", "crash"),
        ("trajectory: {k: .nan}", "trajectory.k", "finite"),
        ("trajectory: {kappa: {y: 0}}", "trajectory.kappa.y", "greater than or equal to 0.001"),
        (
            "trajectory: {kappa: {roll: -1}}",
            "trajectory.kappa.roll",
            "greater than or equal to 0.001",
        ),
        ("trajectory: {kappa: {x: 5}}", "kappa.x", "1/k"),
        (
            "trajectory: {initial: {position: [1, 2, 0], descent_rate: 1}}",
            "trajectory.initial.position",
            "> 0",
        ),
        (
            "trajectory: {initial: {position: [1, 2, 3], descent_rate: -1}}",
            "trajectory.initial.descent_rate",
            "greater than 0",
        ),
        (
            "trajectory: {initial: {position: [1, .nan, 3], descent_rate: 1}}",
            "trajectory.initial.position[1]",
            "finite",
        ),
        ("trajectory: {sample_dt: 0}", "trajectory.sample_dt", "greater than or equal to 0.0001"),
        ("trajectory: {hold: -1}", "trajectory.hold", "greater than or equal to 0"),
        ("trajectory: {speed: 3}", "trajectory.speed", "unknown key"),
        ("trajectory: {kappa: {z: 0.5}}", "trajectory.kappa.z", "unknown key"),
        ("trajectory: {initial: {position: [1, 2, 3]}}", "initial.descent_rate", "missing"),
        (
            "trajectory: {approach: {distance: 5, angle: 0.5, speed: 3},"
            " initial: {position: [1, 2, 3]}}",
            "initial.position",
            "either",
        ),
        ("trajectory: {approach: {distance: 5, angle: 2.0, speed: 3}}", "approach.angle", "1.57"),
        ("trajectory: {flapping: {frequency: 4, heave: 10}}", "flapping.heave", "initial height"),
    ],
)
def test_invalid_trajectory_names_file_and_key(
    tmp_path: Path, yaml_text: str, key: str, words: str
) -> None:
    with pytest.raises(ConfigError) as exc:
        _load(tmp_path, yaml_text)
    msg = str(exc.value)
    assert "sim.yaml" in msg
    assert key in msg
    assert words in msg


def test_malformed_and_missing_files(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"malformed YAML \(line"):
        _load(tmp_path, "trajectory: {k: [0.5\n")
    with pytest.raises(ConfigError, match="file not found"):
        load_yaml_model(SimConfig, tmp_path / "nope.yaml")
    with pytest.raises(ConfigError, match="mapping"):
        _load(tmp_path, "- 1\n- 2\n")


def test_documented_block_loads(tmp_path: Path) -> None:
    cfg = _load(
        tmp_path,
        """
trajectory:
  k: 0.5
  kappa: {x: 0.4, y: 0.6, roll: 0.5, pitch: 0.5, yaw: 0.5}
  initial:
    position: [-8.0, 2.0, 4.6]
    rpy: [0.05, 0.15, 0.3]
    descent_rate: 2.0
  goal: {position: [10.0, 5.0, 0.0], rpy: [0.0, 0.0, 1.57]}
  sample_dt: 0.1
  hold: 0.0
  flapping: {frequency: 0.0, heave: 0.0, pitch: 0.0}
""",
    )
    t = cfg.trajectory
    assert t.k == 0.5
    assert t.kappa.y == 0.6
    assert t.initial.position == (-8.0, 2.0, 4.6)
    assert t.goal.rpy[2] == 1.57
    assert not t.flapping.enabled
    # approach instead of position + descent_rate
    a = _load(tmp_path, "trajectory: {approach: {distance: 10, angle: 0.5236, speed: 4}}")
    assert a.trajectory.approach is not None
    assert a.trajectory.initial_height() == pytest.approx(10 * 0.5, rel=1e-4)


def test_defaults_are_valid_and_frozen() -> None:
    cfg = validate_model(TrajectoryConfig, {})
    assert cfg.k == 0.5
    with pytest.raises(Exception, match="frozen"):
        cfg.k = 0.3  # type: ignore[misc]


@pytest.mark.parametrize(
    "data",
    [
        {},
        {"trajectory": {"approach": {"distance": 10.0, "angle": 0.5236, "speed": 4.0}}},
        {
            "trajectory": {
                "initial": {"rpy": [0.1, 0.0, 0.2]},
                "approach": {"distance": 9.0, "angle": 0.4, "heading": 0.3, "speed": 3.0},
            }
        },
    ],
)
def test_resolved_config_validates_again(data: dict[str, object]) -> None:
    """run.json stores the resolved config; it must load back to the same config."""
    first = validate_model(SimConfig, data)
    dumped = first.model_dump(mode="json")
    again = validate_model(SimConfig, dumped)
    assert again.model_dump(mode="json") == dumped
