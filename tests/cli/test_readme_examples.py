"""Every example in README.md works as written.

The YAML, shell and Python blocks are extracted from the README itself (never copied
here), the named YAML files (``# job.yaml`` on their first line) are written into a fresh
folder, and the shell and Python blocks run there in README order through a ``roslan``
command on PATH. The only concession to test time is an environment switch of that
command (``ROSLAN_README_FAST``): every simulation's landing is shortened to 1 s after its
config has been read and validated as written. A few commands cannot run here; each is
listed in ``NOT_RUN`` with the reason.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import pytest
import yaml

from roslan.config.base import validate_model
from roslan.config.sim import SimConfig
from roslan.scene.spec import SceneFile

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
SRC = ROOT / "src"

_BLOCK = re.compile(r"^```(\w+)\n(.*?)^```", re.M | re.S)
_NAMED = re.compile(r"^# ([\w.]+\.yaml)\b")

NOT_RUN: dict[str, str] = {
    "make ": "creates a virtual environment and pip-installs (the suite runs inside one)",
    "sudo apt-get": "installs system packages (needs root; .ci/run installs them)",
    "python3 -m pip install .": "installs roslan (the suite runs inside an installed one)",
    ".venv/bin/roslan": "the clone's .venv (here `roslan` on PATH runs every example)",
    "source .venv/bin/activate": "the clone's .venv (a shell builtin of bash, not sh)",
    "rosbag info": "needs a ROS 1 installation (tests/io/test_bags.py reads the bags instead)",
    "roslan dataset -o paper_ds ": "12 full landings take minutes (its --dry-run runs here)",
    "roslan batch sweep.yaml -o sweep_out --workers": "64 landings (the --dry-run runs here)",
    "roslan batch sweep.yaml -o sweep_out --scheduler": "needs a running Dask scheduler",
}

_FAST_SHIM = """\
#!{python}
import os
import sys

sys.path.insert(0, {src!r})
if os.environ.get("ROSLAN_README_FAST") and __name__ == "__main__":
    import roslan.cli.simulate as _cli
    from roslan.trajectory.config import Initial

    _load = _cli.load_config

    def _short(path):
        config, source = _load(path)  # read and validated as written
        initial = Initial(position=(-1.0, 0.3, 0.5), rpy=(0.05, 0.1, 0.2), descent_rate=1.0)
        update = {{"initial": initial, "approach": None, "hold": 0.0}}
        trajectory = config.trajectory.model_copy(update=update)
        return config.model_copy(update={{"trajectory": trajectory}}), source

    _cli.load_config = _short
if __name__ == "__main__":  # worker processes re-import this file
    from roslan.cli import main

    sys.exit(main())
"""


def readme_blocks() -> list[tuple[str, str]]:
    """``(language, text)`` of every fenced block of README.md, in order."""
    return [(m.group(1), m.group(2)) for m in _BLOCK.finditer(README.read_text("utf-8"))]


def _commands(block: str) -> list[str]:
    """The command lines of a shell block (``\\``-continued lines joined)."""
    lines = block.replace("\\\n", " ").splitlines()
    return [ln.strip() for ln in lines if ln.strip() and not ln.strip().startswith("#")]


def _skipped(command: str) -> str | None:
    return next((why for start, why in NOT_RUN.items() if command.startswith(start)), None)


def _named_yaml() -> dict[str, str]:
    """The README's YAML blocks whose first line names their file (``# job.yaml``)."""
    out = {}
    for lang, text in readme_blocks():
        if lang == "yaml" and (m := _NAMED.match(text)):
            out[m.group(1)] = text
    return out


def _all_commands() -> list[str]:
    return [c for lang, b in readme_blocks() if lang == "bash" for c in _commands(b)]


def test_readme_shows_every_file_its_commands_use() -> None:
    named = _named_yaml()
    used = {f for c in _all_commands() for f in re.findall(r"\b(\w+\.yaml)\b", c.split(" #")[0])}
    assert used - {"default.yaml"} <= set(named), "commands use YAML files the README lacks"
    base = re.search(r"^base: (\S+)", named["sweep.yaml"], re.M)
    assert base is not None
    assert base.group(1) in named, "the sweep's base config is not shown"
    # every NOT_RUN entry still matches a README command (no stale excuses)
    for start in NOT_RUN:
        assert any(c.startswith(start) for c in _all_commands()), start


def _validate_yaml(text: str, tmp_path: Path) -> None:
    data: Any = yaml.safe_load(text)
    assert isinstance(data, dict), text
    if "objects" in data:  # a scene file
        SceneFile.model_validate(data)
    elif "axes" in data:  # a sweep: checked when the shell examples run it
        assert "base" in data
    else:  # a simulation config (or a part of one: a trajectory, a sensor list)
        validate_model(SimConfig, data, "README", context={"base_dir": tmp_path})


def test_every_yaml_example_is_a_valid_config(tmp_path: Path) -> None:
    yamls = [b for lang, b in readme_blocks() if lang == "yaml"]
    for text in yamls:
        _validate_yaml(text, tmp_path)


def _roslan_command(tmp_path: Path) -> dict[str, str]:
    bin_dir = tmp_path / ".bin"
    bin_dir.mkdir()
    shim = bin_dir / "roslan"
    shim.write_text(_FAST_SHIM.format(python=sys.executable, src=str(SRC)), encoding="utf-8")
    shim.chmod(0o755)
    env = dict(os.environ)
    env["PATH"] = f"{bin_dir}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = str(SRC) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    env["ROSLAN_README_FAST"] = "1"
    env["MPLBACKEND"] = "Agg"
    return env


@pytest.mark.slow
def test_every_shell_and_python_example_runs_as_written(tmp_path: Path) -> None:
    work = tmp_path / "clone"
    work.mkdir()
    # the README's paths are relative to a clone's root
    (work / "src" / "roslan").mkdir(parents=True)
    (work / "src" / "roslan" / "data").symlink_to(SRC / "roslan" / "data")
    env = _roslan_command(tmp_path)
    blocks = readme_blocks()
    for lang, text in blocks:
        if lang == "yaml" and (m := _NAMED.match(text)):
            (work / m.group(1)).write_text(text, encoding="utf-8")
    ran, skipped = 0, set()
    for lang, text in blocks:
        if lang == "bash":
            for command in _commands(text):
                if _skipped(command):
                    skipped.add(next(k for k in NOT_RUN if command.startswith(k)))
                    continue
                proc = subprocess.run(
                    command, shell=True, cwd=work, env=env, capture_output=True, text=True,
                    timeout=300, check=False,
                )  # fmt: skip
                assert proc.returncode == 0, f"README command failed: {command}\n{proc.stderr}"
                assert "Traceback" not in proc.stderr, proc.stderr
                ran += 1
        elif lang == "python":
            proc = subprocess.run(
                [sys.executable, "-c", textwrap.dedent(text)], cwd=work, env=env,
                capture_output=True, text=True, timeout=300, check=False,
            )  # fmt: skip
            assert proc.returncode == 0, f"README Python example failed:\n{text}\n{proc.stderr}"
            ran += 1
    assert ran >= 15
    assert skipped == set(NOT_RUN)
    # what the examples promise is there
    for path in (
        "out/landing.bag",
        "out/overview.png",
        "out/plots/trajectory.png",
        "out/plots/imu.png",
        "out/preview.mp4",
        "landing/trajectory.csv",
        "job_out/run.json",
        "cam_out/run.json",
        "events_out/plots/event_frames.png",
        "out/ranges/lidar/velodyne/timestamps.txt",
        "view.png",
        "wh/scene.yaml",
        "small",
    ):
        assert (work / path).exists(), path
