"""Statements of the docs checked against the code: the tau-dot range, the v2e figures of
docs/event-model.md, the one name of the simulation's speed, and ``-o`` = ``--output`` in
every command."""

from __future__ import annotations

import argparse
import math
import os
import re
import shutil
import subprocess
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


def _make_n(target: str, venv: Path) -> str:
    if shutil.which("make") is None:
        pytest.skip("no make")
    # under `make test` the environment carries the outer make's MAKEFLAGS and MAKELEVEL
    # (a sub-make then prints "Entering directory" lines): run it as a fresh clone would
    env = {k: v for k, v in os.environ.items() if k not in ("MAKEFLAGS", "MAKELEVEL", "MFLAGS")}
    proc = subprocess.run(
        ["make", "--no-print-directory", "-n", target, f"VENV={venv}"], cwd=ROOT,
        capture_output=True, text=True, check=True, env=env,
    )  # fmt: skip
    return proc.stdout


def test_make_demo_installs_no_dev_extras_and_make_test_does(tmp_path: Path) -> None:
    """From a fresh clone (no venv): the demo installs the runtime only, the tests the
    dev extras too; once installed, ``make demo`` only simulates."""
    venv = tmp_path / "venv"
    demo, test = _make_n("demo", venv), _make_n("test", venv)
    assert f"-m venv {venv}" in demo
    assert "pip install -e .\n" in demo
    assert "[dev]" not in demo
    assert demo.strip().endswith("roslan simulate -o out --overwrite")
    assert "pip install -e .\n" in test
    assert "pip install -e '.[dev]'" in test
    assert test.strip().endswith("pytest -n 2 tests")
    (venv / "bin").mkdir(parents=True)
    for name in ("bin/python", ".installed", ".installed-dev"):  # oldest first
        (venv / name).touch()
        stamp = (venv / name).stat().st_mtime_ns + 10**9
        os.utime(venv / name, ns=(stamp, stamp))
    assert "pip" not in _make_n("demo", venv)
    assert "pip" not in _make_n("test", venv)


def test_readme_install_facts() -> None:
    """The Install section names the prerequisites .ci/run installs, how to reach roslan
    afterwards, a runtime-only install and what ``make test`` costs."""
    install = README.split("## Install", 1)[1].split("\n## ", 1)[0]
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    pkgs = re.search(r'SYS_PKGS="([^"]+)"', ci)
    assert pkgs is not None
    flat = " ".join(install.split())
    for pkg in pkgs.group(1).split():
        assert pkg in flat, pkg
    for fact in ("Python >= 3.11", ".venv/bin/roslan --help", "source .venv/bin/activate",
                 "python3 -m pip install .", "pip install -e '.[dev]'"):  # fmt: skip
        assert fact in install, fact
    assert re.search(r"make test.*?\d+-\d+ min on a 2-core machine", flat), "make test's duration"
    quick = README.split("## Quick start", 1)[1].split("```bash\n", 1)[1].split("```", 1)[0]
    assert [ln.split("#")[0].strip() for ln in quick.splitlines()] == ["make demo", "make test"]
    requires = re.search(r'requires-python = ">=([\d.]+)"', (ROOT / "pyproject.toml").read_text())
    assert requires is not None
    assert f"Python >= {requires.group(1)}" in install


# --- the README, the user guide and docs/performance.md agree (issue 38) ---------------

GUIDE = ROOT / "docs" / "guide"
PERFORMANCE = (ROOT / "docs" / "performance.md").read_text(encoding="utf-8")


def _guide(name: str) -> str:
    return (GUIDE / name).read_text(encoding="utf-8")


def _docs() -> dict[Path, str]:
    paths = [ROOT / "README.md", *sorted(GUIDE.glob("*.md"))]
    return {p: p.read_text(encoding="utf-8") for p in paths}


def test_readme_and_performance_page_stay_short() -> None:
    assert len(README.splitlines()) <= 250
    assert len(PERFORMANCE.splitlines()) <= 300


def _anchors(text: str) -> set[str]:
    """GitHub's heading anchors: lower case, punctuation dropped, spaces to hyphens."""
    out = set()
    for heading in re.findall(r"^#+ (.+)$", text, re.M):
        slug = re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")
        out.add(slug)
    return out


def test_every_relative_link_of_the_readme_and_guide_resolves() -> None:
    """Each link to a file of the repository names a file that exists, and its
    ``#anchor`` a heading of that file."""
    checked = 0
    for path, text in _docs().items():
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"\w+://", target):
                continue
            file, _, anchor = target.partition("#")
            dest = (path.parent / file).resolve() if file else path
            assert dest.exists(), f"{path.name}: link to {target}: no such file"
            if anchor:
                assert anchor in _anchors(dest.read_text(encoding="utf-8")), (
                    f"{path.name}: link to {target}: no such heading"
                )
            checked += 1
    assert checked >= 40


def _size_table(text: str, title: str) -> dict[str, float]:
    """``output -> MB`` of the table that follows ``title``."""
    lines = text.split(title, 1)[1].splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("|"))
    rows = {}
    for line in lines[start:]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip("|").split("|")]
        size = re.fullmatch(r"\**([\d.]+) MB\**", cells[1])
        if size is None:
            continue
        name = re.search(r"`([^`]+)`|(OUTDIR|rest)", cells[0])
        assert name is not None, line
        rows[name.group(1) or name.group(2)] = float(size.group(1))
    return rows


def test_output_sizes_agree_and_add_up() -> None:
    guide = _size_table(_guide("outputs.md"), "## Sizes: where the disk goes")
    perf = _size_table(PERFORMANCE, "## Output sizes")
    assert guide == perf
    total = guide.pop("OUTDIR")
    assert len(guide) >= 8
    # each figure rounded to 0.1 MB: the sum within half a unit per row
    assert abs(sum(guide.values()) - total) <= 0.05 * len(guide), (sum(guide.values()), total)
    # the README's rounded figures are the table's
    mb = {k: math.floor(v + 0.5) for k, v in guide.items()}  # rounded half up, as people do
    total_mb = math.floor(total + 0.5)
    assert f"`out/` ({total_mb} MB)" in README
    assert f"{mb['events.txt']} MB of those {total_mb} MB are `events.txt`" in README
    assert f"`events.h5` ({mb['events.h5']} MB)" in README
    assert f"no `events.txt` (-{mb['events.txt']} MB on the default job)" in _guide("outputs.md")
    # the dry-run estimate is stated once, the same everywhere
    estimate = re.search(r"`--dry-run` estimate (\d+) MB", PERFORMANCE)
    assert estimate is not None
    assert f"{estimate.group(1)} MB estimated, {total} MB" in " ".join(_guide("outputs.md").split())


def test_speed_and_dataset_figures_agree() -> None:
    flat = " ".join(README.split())
    rtf = re.search(r"real-time factor \(wall time / trajectory time\) was (\d\.\d)–(\d\.\d)", flat)
    assert rtf is not None, "the README's one speed figure"
    figure = f"{rtf.group(1)}-{rtf.group(2)}"
    assert f"**{figure}**" in PERFORMANCE
    assert f"**{figure}**" in _guide("performance.md")
    assert len(re.findall(r"real-time factor", README)) == 1, "one speed figure in the README"
    plan = re.search(r"estimated ([\d.]+ GB) of disk and ([\d.]+ min)", _guide("datasets.md"))
    assert plan is not None
    assert f"**{plan.group(1)} and {plan.group(2)}**" in PERFORMANCE
    events = re.search(r"\| events of the default job \| \*\*([\d,]+)\*\*", PERFORMANCE)
    assert events is not None
    assert f"{events.group(1)} events" in _guide("outputs.md")


def test_no_stale_figure_is_left() -> None:
    """Figures issue 38 found stale or contradictory are gone from the README and guide."""
    for path, text in _docs().items():
        flat = " ".join(text.split())
        for stale in ("35,358", "6.7 GB", "4.8 min", "3.0-3.3", "about 7 real-time", "-o out/"):
            assert stale not in flat, f"{path.name}: {stale}"


def _readme_yaml(name: str, folder: Path) -> Path:
    m = re.search(rf"```yaml\n# {name}\.yaml\n(.*?)```", README, re.S)
    assert m is not None, name
    path = folder / f"{name}.yaml"
    path.write_text(m.group(1), encoding="utf-8")
    return path


def test_run_time_figures_are_the_estimators_on_two_cores(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The demo's time in the README and the guide (measured on the quiet machine, and
    the dry run's estimate) and the estimate column of docs/performance.md's table are
    what the estimator gives for those configs on an idle 2-core machine."""
    from roslan.config.base import load_yaml_model
    from roslan.config.sim import SimConfig
    from roslan.pipeline.estimate import estimate_run, format_seconds

    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    flat = " ".join(README.split())
    rtf = re.search(r"was (\d\.\d)–(\d\.\d) on a quiet 2-core .*?: ([\d.]+)–([\d.]+) s;", flat)
    assert rtf is not None
    # the measured seconds are the real-time factors times the 5.1 s landing
    assert float(rtf.group(3)) == pytest.approx(float(rtf.group(1)) * 5.1, abs=0.05)
    assert float(rtf.group(4)) == pytest.approx(float(rtf.group(2)) * 5.1, abs=0.05)
    default = ROOT / "src" / "roslan" / "data" / "default.yaml"
    est = estimate_run(load_yaml_model(SimConfig, default))
    quoted = f"`--dry-run` estimates {format_seconds(est.seconds)}"
    assert quoted in flat
    assert quoted in " ".join(_guide("performance.md").split())
    assert f"{rtf.group(3)}-{rtf.group(4)} s" in " ".join(_guide("performance.md").split())
    table = PERFORMANCE.split("## Run-time estimates", 1)[1].split("\n## ", 1)[0]
    rows = re.findall(r"^\| `?(\w+)`? \| [^|]+ \| ([\d.]+) s \| ([\d.]+) \|", table, re.M)
    assert [r[0] for r in rows] == ["job", "perch", "vision", "ranges", "default"]
    for name, seconds, cpu in rows:
        path = default if name == "default" else _readme_yaml(name, tmp_path)
        e = estimate_run(load_yaml_model(SimConfig, path), base_dir=path.parent)
        assert f"{e.seconds:.1f}" == seconds, name
        assert f"{e.cpu:.1f}" == cpu, name
