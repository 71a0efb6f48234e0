"""Every example in README.md and the user guide (docs/guide/*.md) works as written.

The YAML, shell and Python blocks are extracted from the documents themselves (never
copied here): README.md first, then the guide's pages in the order of its index
(docs/guide/README.md), as a reader would go. Each document's named YAML files (``# job.yaml``
on their first line) are written into one fresh folder, and its shell and Python blocks
run there in order through a ``roslan`` command on PATH, after the equivalent of ``make
demo`` (``roslan simulate -o out --overwrite``), which the guide's pages assume. The only
concession to test time is an environment switch of that command (``ROSLAN_README_FAST``):
every simulation's landing is shortened to 1 s after its config has been read and
validated as written. A few commands cannot run here; each is listed in ``NOT_RUN`` with
the reason. The README and the guide run as two tests (each after its own ``make demo``),
so that the suite's two processes share them; within one, a command shown twice runs once.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
import textwrap
from pathlib import Path, PurePosixPath
from typing import Any

import pytest
import yaml

from roslan.config.base import validate_model
from roslan.config.sim import SimConfig
from roslan.scene.spec import SceneFile

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
GUIDE = ROOT / "docs" / "guide"
SRC = ROOT / "src"

_BLOCK = re.compile(r"^```(\w+)\n(.*?)^```", re.M | re.S)
_NAMED = re.compile(r"^# ([\w.]+\.yaml)\b")

# Commands (without their trailing comment) that are not run, matched in full.
NOT_RUN: dict[str, str] = {
    r"make (demo|test)": "creates a virtual environment and pip-installs (the suite runs in one)",
    r"sudo apt-get .*": "installs system packages (needs root; .ci/run installs them)",
    r"python3 -m pip install \.": "installs roslan (the suite runs inside an installed one)",
    r"pip install -e '\.\[rl\]'": "installs stable-baselines3 and torch (the suite does not)",
    r"python benchmarks/train_landing\.py .*": (
        "trains for 0.3 h and needs the `rl` extra"
        " (tests/env/test_train_landing.py runs its wrapper)"
    ),
    r"\.venv/bin/roslan .*": "the clone's .venv (here `roslan` on PATH runs every example)",
    r"source \.venv/bin/activate": "the clone's .venv (a shell builtin of bash, not sh)",
    r"rosbag info .*": "needs a ROS 1 installation (tests/io/test_bags.py reads the bags instead)",
    r"roslan dataset -o out_paper_ds": "12 full landings take minutes (its --dry-run runs here)",
    r"roslan batch sweep\.yaml -o out_sweep --workers .*": "64 landings (the --dry-run runs here)",
    r"roslan batch sweep\.yaml -o out_sweep --scheduler .*": "needs a running Dask scheduler",
    r"roslan fit-noise out/events\.h5 --quiet-span .*": (
        "the suite's `make demo` is shortened to 1 s without its hold, so it has no quiet span "
        "(tests/cli/test_fit_noise_cli.py fits roslan's own events.h5 and events.txt)"
    ),
}

# `make demo`'s run, which the guide's pages read (`out/`)
DEMO = "roslan simulate -o out --overwrite"
# commands whose -o folder is a run (a folder of its own, never inside another)
_RUN_COMMANDS = (
    "roslan simulate",
    "roslan trajectory",
    "roslan dataset",
    "roslan batch",
    "roslan fly",
)

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
{env_patch}
if __name__ == "__main__":  # worker processes re-import this file
    from roslan.cli import main

    sys.exit(main())
"""


# the closed-loop environment (`roslan fly`, `roslan/Landing-v0` in Python blocks): the same
# shortening, after the config has been read and validated as written
_FAST_ENV = """\
if os.environ.get("ROSLAN_README_FAST"):
    import roslan.env.landing as _landing
    from roslan.trajectory.config import Initial

    _load_env = _landing.load_env_config

    def _short_env(config):
        cfg, source = _load_env(config)
        initial = Initial(position=(-1.0, 0.3, 0.5), rpy=(0.05, 0.1, 0.2), descent_rate=1.0)
        update = {"initial": initial, "approach": None, "hold": 0.0}
        trajectory = cfg.trajectory.model_copy(update=update)
        return cfg.model_copy(update={"trajectory": trajectory}), source

    _landing.load_env_config = _short_env
"""
_PY_PRELUDE = "import os\n" + _FAST_ENV


def guide_pages() -> list[Path]:
    """The guide's pages in the order of its index's links."""
    index = (GUIDE / "README.md").read_text("utf-8")
    names = re.findall(r"\]\(([\w-]+\.md)\)", index)
    return [GUIDE / n for n in dict.fromkeys(names)]


def documents() -> list[Path]:
    return [README, *guide_pages()]


def blocks(doc: Path) -> list[tuple[str, str]]:
    """``(language, text)`` of every fenced block of ``doc``, in order."""
    return [(m.group(1), m.group(2)) for m in _BLOCK.finditer(doc.read_text("utf-8"))]


def _commands(block: str) -> list[str]:
    """The command lines of a shell block (``\\``-continued lines joined)."""
    lines = block.replace("\\\n", " ").splitlines()
    return [ln.strip() for ln in lines if ln.strip() and not ln.strip().startswith("#")]


def _bare(command: str) -> str:
    """The command without its trailing ``# comment``."""
    return command.split(" #")[0].strip()


def _skipped(command: str) -> str | None:
    bare = _bare(command)
    return next((key for key in NOT_RUN if re.fullmatch(key, bare)), None)


def _named_yaml(doc: Path) -> dict[str, str]:
    """The YAML blocks of ``doc`` whose first line names their file (``# job.yaml``)."""
    out = {}
    for lang, text in blocks(doc):
        if lang == "yaml" and (m := _NAMED.match(text)):
            out[m.group(1)] = text
    return out


def _doc_commands(doc: Path) -> list[str]:
    return [c for lang, b in blocks(doc) if lang == "bash" for c in _commands(b)]


def _all_commands() -> list[str]:
    return [c for doc in documents() for c in _doc_commands(doc)]


def test_the_guide_index_lists_every_page() -> None:
    pages = {p.name for p in GUIDE.glob("*.md")} - {"README.md"}
    assert {p.name for p in guide_pages()} == pages
    assert all(p.exists() for p in guide_pages())


def test_docs_show_every_file_their_commands_use() -> None:
    """A command's YAML file is shown in its document or an earlier one; no two documents
    show different files under one name."""
    shown: dict[str, Path] = {}
    for doc in documents():
        for name in _named_yaml(doc):
            assert name not in shown, f"{name} is shown in {shown[name].name} and {doc.name}"
            shown[name] = doc
        for command in _doc_commands(doc):
            used = set(re.findall(r"\b([\w.]+\.yaml)\b", _bare(command))) - {"default.yaml"}
            assert used <= set(shown), f"{doc.name}: {command} uses YAML files not shown"
    base = re.search(r"^base: (\S+)", _named_yaml(GUIDE / "datasets.md")["sweep.yaml"], re.M)
    assert base is not None
    assert base.group(1) in shown, "the sweep's base config is not shown"
    # every NOT_RUN entry still matches a command (no stale excuses)
    for key in NOT_RUN:
        assert any(_skipped(c) == key for c in _all_commands()), key


def _outputs(command: str) -> list[PurePosixPath]:
    words = shlex.split(_bare(command))
    return [PurePosixPath(words[i + 1]) for i, w in enumerate(words[:-1])
            if w in ("-o", "--output", "--save")]  # fmt: skip


def _inside(path: PurePosixPath, folder: PurePosixPath) -> bool:
    return path != folder and folder in path.parents


def test_no_example_writes_inside_another_run() -> None:
    """``make demo`` replaces ``out/`` with ``--overwrite``: a run nested in a run's folder
    (``-o out/ranges``) would be deleted with it. No ``-o`` target of any example lies
    inside a run's folder."""
    runs = {PurePosixPath("out")}
    targets = []
    for command in _all_commands():
        if _skipped(command) and not command.startswith("roslan"):
            continue
        outs = _outputs(command)
        targets += [(command, o) for o in outs]
        if command.startswith(_RUN_COMMANDS):
            runs |= set(outs)
    assert len(runs) >= 10
    for command, target in targets:
        for run in runs:
            assert not _inside(target, run), f"{command!r} writes inside the run folder {run}"
    # the check itself sees a nested run
    assert _inside(PurePosixPath("out/ranges"), PurePosixPath("out"))
    assert not _inside(PurePosixPath("out_ranges"), PurePosixPath("out"))


def test_every_example_output_is_ignored_by_git() -> None:
    """A clone's ``git status`` stays clean after the examples: every ``-o``/``--save``
    target of the README and the guide starts with ``out`` and git ignores it (asked of
    git itself, with the repository's .gitignore)."""
    import shutil

    targets = sorted({str(o) for c in _all_commands() for o in _outputs(c)})
    assert len(targets) >= 30
    assert [t for t in targets if not t.startswith("out")] == []
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    paths = [t.rstrip("/") for t in targets] + [t.rstrip("/") + "/run.json" for t in targets]
    proc = subprocess.run(
        ["git", "check-ignore", "--no-index", "--verbose", "--non-matching", *paths],
        cwd=ROOT, capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert proc.returncode in (0, 1), proc.stderr
    not_ignored = [ln.split("\t")[-1] for ln in proc.stdout.splitlines() if ln.startswith("::")]
    assert not_ignored == []
    assert len(proc.stdout.splitlines()) == len(paths)


def _validate_yaml(text: str, tmp_path: Path, where: str) -> None:
    data: Any = yaml.safe_load(text)
    assert isinstance(data, dict), text
    if "objects" in data:  # a scene file
        SceneFile.model_validate(data)
    elif "axes" in data:  # a sweep: checked when the shell examples run it
        assert "base" in data
    else:  # a simulation config (or a part of one: a trajectory, a sensor list)
        validate_model(SimConfig, data, where, context={"base_dir": tmp_path})


def test_every_yaml_example_is_a_valid_config(tmp_path: Path) -> None:
    checked = 0
    for doc in documents():
        for lang, text in blocks(doc):
            if lang == "yaml":
                _validate_yaml(text, tmp_path, doc.name)
                checked += 1
    assert checked >= 15


def _roslan_command(tmp_path: Path) -> dict[str, str]:
    bin_dir = tmp_path / ".bin"
    bin_dir.mkdir()
    shim = bin_dir / "roslan"
    text = _FAST_SHIM.format(python=sys.executable, src=str(SRC), env_patch=_FAST_ENV)
    shim.write_text(text, encoding="utf-8")
    shim.chmod(0o755)
    env = dict(os.environ)
    env["PATH"] = f"{bin_dir}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = str(SRC) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    env["ROSLAN_README_FAST"] = "1"
    env["MPLBACKEND"] = "Agg"
    return env


def _run_shell(command: str, work: Path, env: dict[str, str], doc: Path) -> str:
    proc = subprocess.run(
        command, shell=True, cwd=work, env=env, capture_output=True, text=True,
        timeout=300, check=False,
    )  # fmt: skip
    assert proc.returncode == 0, f"{doc.name} command failed: {command}\n{proc.stderr}"
    assert "Traceback" not in proc.stderr, proc.stderr
    return proc.stdout + proc.stderr


def _run_documents(docs: list[Path], tmp_path: Path) -> tuple[Path, dict[str, str], int]:
    """Run the examples of ``docs`` in order in a fresh clone-like folder, after
    ``make demo``'s run: the folder, what each command printed, how many examples ran."""
    work = tmp_path / "clone"
    work.mkdir()
    # the examples' paths are relative to a clone's root
    (work / "src" / "roslan").mkdir(parents=True)
    (work / "src" / "roslan" / "data").symlink_to(SRC / "roslan" / "data")
    env = _roslan_command(tmp_path)
    _run_shell(DEMO, work, env, README)  # make demo
    printed: dict[str, str] = {DEMO: ""}
    ran = 0
    for doc in docs:
        for name, text in _named_yaml(doc).items():
            (work / name).write_text(text, encoding="utf-8")
        for lang, text in blocks(doc):
            if lang == "bash":
                for command in _commands(text):
                    if not _skipped(command) and _bare(command) not in printed:
                        printed[_bare(command)] = _run_shell(command, work, env, doc)
                        ran += 1
            elif lang == "python":
                proc = subprocess.run(
                    [sys.executable, "-c", _PY_PRELUDE + textwrap.dedent(text)], cwd=work, env=env,
                    capture_output=True, text=True, timeout=300, check=False,
                )  # fmt: skip
                assert proc.returncode == 0, (
                    f"{doc.name} Python example failed:\n{text}\n{proc.stderr}"
                )
                ran += 1
    return work, printed, ran


@pytest.mark.slow
def test_every_readme_example_runs_as_written(tmp_path: Path) -> None:
    work, _, ran = _run_documents([README], tmp_path)
    assert ran >= 12
    # what the examples promise is there
    for path in (
        "out/plots/trajectory.png",
        "out_landing/trajectory.csv",
        "out_tau_family.png",
        "out_job/run.json",
        "out_perch/run.json",
        "out_vision/depth_depth.txt",
        "out_vision_plots",
        "out_ranges/lidar/velodyne/timestamps.txt",
        "out_lidar.png",
        "out_view.png",
        "out_preview.mp4",
    ):
        assert (work / path).exists(), path
    # the disk switch the README shows: events.h5 without events.txt
    assert (work / "out_vision" / "events.h5").exists()
    assert not (work / "out_vision" / "events.txt").exists()


@pytest.mark.slow
def test_every_guide_example_runs_as_written(tmp_path: Path) -> None:
    """The guide's pages need only ``make demo``'s ``out/``, not the README's examples."""
    work, printed, ran = _run_documents(guide_pages(), tmp_path)
    assert ran >= 25
    for path in (
        "out_tau_landing/summary.json",
        "out_flown/trajectory.csv",
        "out_perch_guide/run.json",
        "out_perch_trajectory.png",
        "out_full_job/landing_ros2",
        "out_imu/imu.txt",
        "out_imu.png",
        "out_warehouse_view.png",
        "out_wh/scene.yaml",
        "out_cam/run.json",
        "out_event_camera/events.txt",
        "out_event_frames",
        "out_range_suite/lidar/velodyne/timestamps.txt",
        "out/plots/trajectory.png",
        "out_preview.mp4",
        "out_landing.rrd",
        "out_small",
    ):
        assert (work / path).exists(), path
    assert not (work / "out_full_job" / "landing.bag").exists()  # --format ros2
    # the small-disk job's plan: the switches drop events.txt and the ROS 1 bag
    plan = printed["roslan simulate small_disk.yaml -o out_small_disk --dry-run"]
    for shown in ("events.h5", "landing_ros2/"):
        assert shown in plan, plan
    for dropped in ("events.txt", "landing.bag"):
        assert dropped not in plan, plan
