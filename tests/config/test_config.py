"""Config loading at the edge: YAML -> models, errors naming file, key, value, allowed."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from roslan.config.base import load_yaml_model, validate_model
from roslan.config.sim import SimConfig
from roslan.errors import ConfigError
from roslan.limits import MAX_COORD_M, MAX_DURATION_S, MAX_RATE_HZ
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


@pytest.mark.parametrize(
    ("rate", "exposure", "ok"),
    [(30.0, 5.0, False), (30.0, 0.034, False), (30.0, 1 / 30, True), (30.0, 0.005, True)],
)
def test_exposure_longer_than_the_frame_period_refused_by_name(
    tmp_path: Path, rate: float, exposure: float, ok: bool
) -> None:
    """``exposure_time: 5`` (meant 5 ms) on a 30 Hz camera is impossible: refused with
    the file, the key, the value and what is allowed (up to 1 / rate)."""
    sensor = {"type": "camera", "name": "cam", "rate": rate, "exposure_time": exposure}
    path = tmp_path / "job.yaml"
    path.write_text(yaml.safe_dump({"scene": "empty", "sensors": [sensor]}), encoding="utf-8")
    if ok:
        assert load_yaml_model(SimConfig, path).sensors[0].exposure_time == exposure  # type: ignore[attr-defined]
        return
    with pytest.raises(ConfigError) as err:
        load_yaml_model(SimConfig, path)
    text = str(err.value)
    assert text.startswith(f"{path}: sensors[0].exposure_time = {exposure:g}")
    assert f"allowed: 0 to {1 / rate:.6g} s" in text
    stereo = {**sensor, "type": "stereo_camera"}  # the same rule for both frame cameras
    with pytest.raises(ConfigError, match=r"sensors\[0\]\.exposure_time"):
        validate_model(SimConfig, {"scene": "empty", "sensors": [stereo]}, "x.yaml")


def test_angles_beyond_two_pi_warned_by_key(
    tmp_path: Path, recwarn: pytest.WarningsRecorder
) -> None:
    """Probable degrees in radian fields: one warning per key, naming file, key, value;
    angles within +-2 pi, and non-angle keys (positions, rates), are not warned."""
    import math

    doc = {
        "trajectory": {
            "initial": {"position": [-8.0, 2.0, 7.0], "rpy": [0.0, 20.0, 0.0], "descent_rate": 1.0},
            "goal": {"rpy": [0.0, 0.0, -2 * math.pi]},  # exactly one turn: fine
            "flapping": {"frequency": 5.0, "pitch": 10.0},
        },
        "scene": "empty",
        "sensors": [{"type": "imu", "name": "imu", "rate": 100.0, "pose": {"rpy": [0, 0, 90]}}],
    }  # fmt: skip
    path = tmp_path / "job.yaml"
    path.write_text(yaml.safe_dump(doc), encoding="utf-8")
    load_yaml_model(SimConfig, path)
    lines = sorted(str(w.message) for w in recwarn)
    assert lines == [
        f"{path}: sensors[0].pose.rpy = [0, 0, 90]: beyond +-2 pi; angles are in radians "
        "(if 90 means degrees, write 1.571)",
        f"{path}: trajectory.flapping.pitch = 10: beyond +-2 pi; angles are in radians "
        "(if 10 means degrees, write 0.1745)",
        f"{path}: trajectory.initial.rpy = [0, 20, 0]: beyond +-2 pi; angles are in radians "
        "(if 20 means degrees, write 0.3491)",
    ]


def test_unit_warning_is_one_cli_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from roslan.cli import main

    doc = {"trajectory": {"initial": {"position": [-1.0, 0.5, 1.0], "rpy": [0, 20, 0],
                                      "descent_rate": 1.0}}}  # fmt: skip
    path = tmp_path / "job.yaml"
    path.write_text(yaml.safe_dump(doc), encoding="utf-8")
    assert main(["simulate", str(path), "-o", str(tmp_path / "o"), "--dry-run"]) == 0
    err = [line for line in capsys.readouterr().err.splitlines() if "rpy" in line]
    assert err == [
        f"warning: {path}: trajectory.initial.rpy = [0, 20, 0]: beyond +-2 pi; angles are "
        "in radians (if 20 means degrees, write 0.3491)"
    ]


def test_a_sweep_warns_a_unit_slip_once(tmp_path: Path, recwarn: pytest.WarningsRecorder) -> None:
    """Every task of a sweep carries the base's slip: one warning for all of them."""
    from roslan.batch.tasks import make_tasks

    base = {"trajectory": {"initial": {"position": [-1.0, 0.5, 1.0], "rpy": [0, 20, 0],
                                       "descent_rate": 1.0}}}  # fmt: skip
    configs = [{**base, "seed": s} for s in range(3)]
    tasks = make_tasks(configs, tmp_path, source="sweep.yaml")
    assert all(t.error is None for t in tasks)
    assert [str(w.message) for w in recwarn] == [
        "sweep.yaml (3 tasks): trajectory.initial.rpy = [0, 20, 0]: beyond +-2 pi; angles "
        "are in radians (if 20 means degrees, write 0.3491)"
    ]


def _range(name: str, lo: float, lo_incl: bool, hi: float, hi_incl: bool) -> str:
    """The range as the error states it, written here independently of the formatter."""

    def num(v: float) -> str:
        return str(int(v)) if float(v).is_integer() else f"{v:g}"

    return f"{num(lo)} {'<=' if lo_incl else '<'} {name} {'<=' if hi_incl else '<'} {num(hi)}"


@pytest.mark.parametrize(
    ("yaml_text", "key", "allowed"),
    [
        # the two: one side was stated, now both (k < 1 from the field itself)
        ("trajectory: {k: -1}", "trajectory.k = -1", _range("k", 1e-3, True, 1.0, False)),
        (
            "sensors: [{type: imu, name: imu, rate: -200}]",
            "sensors[0].rate = -200",
            _range("rate", 0.0, False, MAX_RATE_HZ, True),
        ),
        # the upper side broken, both stated
        (
            "output: {ground_truth_rate: 20000}",
            "output.ground_truth_rate = 20000",
            _range("ground_truth_rate", 0.0, False, MAX_RATE_HZ, True),
        ),
        (
            "trajectory: {hold: -1}",
            "trajectory.hold = -1",
            _range("hold", 0.0, True, MAX_DURATION_S, True),
        ),
        (
            "trajectory: {goal: {position: [0, 0, 2.0e+6]}}",
            "trajectory.goal.position[2] = 2000000.0",
            _range("position[2]", -MAX_COORD_M, True, MAX_COORD_M, True),
        ),
        (
            "sensors: [{type: lidar, name: l, preset: vlp16, rate: 10, dropout: 1}]",
            "sensors[0].dropout = 1",
            _range("dropout", 0.0, True, 1.0, False),
        ),
        (  # an optional field (`X | None`): its bounds sit inside the union
            "closed_loop: {observation: {max_imu_samples: 0}}",
            "closed_loop.observation.max_imu_samples = 0",
            _range("max_imu_samples", 1, True, 100_000, True),
        ),
        (
            "closed_loop: {control_rate: 5000}",
            "closed_loop.control_rate = 5000",
            _range("control_rate", 1.0, True, 1000.0, True),
        ),
    ],
)
def test_a_number_out_of_range_states_both_sides(
    tmp_path: Path, yaml_text: str, key: str, allowed: str
) -> None:
    with pytest.raises(ConfigError) as exc:
        _load(tmp_path, yaml_text)
    (line,) = [ln for ln in str(exc.value).splitlines() if key in ln]
    assert line.startswith(f"{tmp_path / 'sim.yaml'}: {key}: Input should be "), line
    assert line.endswith(f"; allowed: {allowed}"), line


def test_a_one_sided_bound_states_its_side_only(tmp_path: Path) -> None:
    """``smoothing`` (>= 0, no upper bound) and a descent rate (> 0): pydantic's own
    text, nothing invented for the open side."""
    for text, key in [
        ("trajectory: {smoothing: -1}", "trajectory.smoothing"),
        ("trajectory: {initial: {position: [1, 2, 3], descent_rate: -1}}", "descent_rate"),
    ]:
        with pytest.raises(ConfigError) as exc:
            _load(tmp_path, text)
        msg = str(exc.value)
        assert key in msg
        assert "greater than" in msg
        assert "allowed:" not in msg


def test_a_scene_file_size_out_of_range_states_both_sides(tmp_path: Path) -> None:
    from roslan.errors import SceneError
    from roslan.limits import MAX_SIZE_M, MIN_SIZE_M
    from roslan.scene import load_scene

    box = {"name": "b", "primitive": {"type": "box", "size": [1.0, 0.0, 1.0]}}
    (tmp_path / "s.yaml").write_text(yaml.safe_dump({"name": "s", "objects": [box]}))
    with pytest.raises(SceneError) as exc:
        load_scene(tmp_path / "s.yaml")
    expected = _range("size[1]", MIN_SIZE_M, True, MAX_SIZE_M, True)
    assert str(exc.value).endswith(f"; allowed: {expected}"), exc.value
