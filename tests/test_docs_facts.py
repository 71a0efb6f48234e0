"""Statements of the docs checked against the code: the tau-dot range, the v2e figures of
docs/event-model.md, the one name of the simulation's speed, and ``-o`` = ``--output`` in
every command."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from roslan.cli.app import build_parser
from roslan.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]
DESIGN = (ROOT / "docs" / "design.md").read_text(encoding="utf-8")
EVENT_MODEL = (ROOT / "docs" / "event-model.md").read_text(encoding="utf-8")
README = (ROOT / "README.md").read_text(encoding="utf-8")


def _k_valid(k: float) -> bool:
    from roslan.config.base import validate_model
    from roslan.trajectory import TrajectoryConfig

    try:
        validate_model(TrajectoryConfig, {"k": k, "kappa": {"x": 0.4, "y": 0.4, "roll": 0.4,
                                                            "pitch": 0.4, "yaw": 0.4}})  # fmt: skip
    except ConfigError:
        return False
    return True


def test_design_states_the_k_range_the_config_enforces() -> None:
    """design.md: ``0 < k < 1``, the config accepts ``0.001 <= k < 1`` and refuses k = 1."""
    assert "tau-dot `0 < k < 1` (the config accepts `0.001 <= k < 1`" in DESIGN
    assert "`k = 1` | contact at constant speed, a crash: refused by the config" in DESIGN
    assert "0 < k <= 1" not in DESIGN
    assert [_k_valid(k) for k in (0.0009, 0.001, 0.5, 0.999, 1.0, 1.2)] == [
        False, True, True, True, False, False,
    ]  # fmt: skip


def test_event_model_v2e_figures_are_the_arithmetic_of_v2e_and_roslan() -> None:
    """v2e's darkest 8-bit pixel has inten01 = (0 + 20) / 275; its shot-noise factor is
    ``(f - 1) inten01 + 1`` with f = 0.25; roslan's black pixel has factor 1."""
    from roslan.events.model import EventModelParams

    f = EventModelParams().shot_noise_intensity_factor
    assert f == 0.25
    v2e_dark = (f - 1.0) * (0 + 20) / 275 + 1.0
    assert f"{(0 + 20) / 275:.4f}" in EVENT_MODEL  # 0.0727
    assert f"{v2e_dark:.4f}" in EVENT_MODEL  # 0.9455
    assert f"{(1 / v2e_dark - 1) * 100:.1f} %" in EVENT_MODEL  # 5.8 %
    assert "(DN + 20) / 275" in EVENT_MODEL
    # the statements item 8 of the review found untrue are gone
    assert "follows current v2e" not in EVENT_MODEL
    assert "likewise randomises" not in EVENT_MODEL
    assert "subtraction is commented" in EVENT_MODEL or "commented out" in EVENT_MODEL


def test_playback_names_the_real_time_factor_and_plays_at_its_inverse() -> None:
    from roslan.pipeline.report import playback_text

    text = playback_text(2.0, 8.0, ("ros1", "ros2"), {})
    assert "real-time factor = wall time / trajectory time = 4.00" in text
    assert "rosbag play --clock landing.bag -r 0.25" in text
    assert "ros2 bag play landing_ros2 --clock -r 0.25" in text
    assert not re.search(r"\bR = |speedup", text)


def test_timing_json_has_one_speed_name() -> None:
    from roslan.rundir.manifest import Timing

    keys = set(Timing.__annotations__)
    assert {"real_time_factor", "stream_real_time_factor"} <= keys
    assert not {k for k in keys if "speed" in k}
    assert "speedup" not in (ROOT / "src" / "roslan" / "pipeline" / "run.py").read_text()


def _subparsers(
    parser: argparse.ArgumentParser, prefix: str = "roslan"
) -> list[tuple[str, argparse.ArgumentParser]]:
    out = [(prefix, parser)]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out += _subparsers(sub, f"{prefix} {name}")
    return out


def test_every_o_option_is_output() -> None:
    """``-o`` is ``--output`` in every command (``simulate`` also keeps ``--outdir``)."""
    seen = []
    for name, parser in _subparsers(build_parser()):
        for action in parser._actions:
            if "-o" in action.option_strings:
                seen.append(name)
                assert "--output" in action.option_strings, (name, action.option_strings)
    assert "roslan simulate" in seen
    assert len(seen) >= 7


@pytest.mark.parametrize("flag", ["-o", "--output", "--outdir"])
def test_simulate_accepts_output_and_the_old_outdir(flag: str) -> None:
    args = build_parser().parse_args(["simulate", flag, "somewhere"])
    assert args.outdir == Path("somewhere")


def test_readme_speed_name() -> None:
    assert "real-time factor" in README
    assert not re.search(r"\bspeedup\b|\bR = trajectory", README)
