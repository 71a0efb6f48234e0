"""A new user's first hour: guiding errors, checks before work, progress, clean figures."""

from __future__ import annotations

import argparse
import os
import re
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from pipeline_helpers import SHORT_TRAJECTORY
from roslan.cli import build_parser, main
from roslan.config.base import validate_model
from roslan.config.sim import SimConfig
from roslan.errors import ConfigError
from roslan.sensors.registry import SENSOR_TYPES, config_class

ROOT = Path(__file__).resolve().parents[2]


def _config_error(data: dict[str, Any]) -> str:
    with pytest.raises(ConfigError) as info:
        validate_model(SimConfig, data, "job.yaml")
    return str(info.value)


# ------------------------------------------------------------------ default topics
@pytest.mark.parametrize("kind", sorted(SENSOR_TYPES))
def test_every_sensor_type_has_a_default_topic(kind: str) -> None:
    cls = config_class(kind)
    declared = cls.model_fields["topic"]
    cfg = SimConfig.model_validate({"sensors": [{"type": kind, "name": "s1", "rate": 10.0}]})
    topic = cfg.sensors[0].topic
    # the type's own default where it has one (LiDAR: /velodyne_points), else /<name>
    assert topic == ("/s1" if declared.is_required() else declared.default)
    assert re.fullmatch(r"/[A-Za-z][A-Za-z0-9_/]*", topic)


def test_an_explicit_topic_wins_and_duplicates_of_defaults_are_caught() -> None:
    cfg = SimConfig.model_validate(
        {"sensors": [{"type": "imu", "name": "imu", "rate": 100, "topic": "/body/imu"}]}
    )
    assert cfg.sensors[0].topic == "/body/imu"
    err = _config_error(
        {
            "sensors": [
                {"type": "imu", "name": "a", "rate": 100, "topic": "/b"},
                {"type": "imu", "name": "b", "rate": 100},
            ]
        }
    )
    assert "topic = '/b': duplicate" in err


def test_errors_of_one_sensor_are_only_its_own() -> None:
    err = _config_error(
        {
            "sensors": [
                {"type": "imu", "name": "imu", "rate": 1000, "foo": 1},
                {"type": "camera", "name": "cam", "rate": 10, "encoding": "rgb9"},
            ]
        }
    )
    lines = err.splitlines()
    assert len(lines) == 2, err
    assert "Field required" not in err
    assert lines[0].startswith("job.yaml: sensors[0].foo = 1: unknown key")
    assert lines[1].startswith("job.yaml: sensors[1].encoding = 'rgb9'")


# ------------------------------------------------------------------ did you mean
@pytest.mark.parametrize(
    ("data", "expected"),
    [
        (
            {"trajectory": {"initial": {"descnt_rate": 2}}},
            "job.yaml: trajectory.initial.descnt_rate = 2: unknown key; "
            "did you mean 'descent_rate'?",
        ),
        (
            {"sensors": [{"type": "camera", "name": "c", "rate": 5, "resolutoin": [64, 48]}]},
            "job.yaml: sensors[0].resolutoin = [64, 48]: unknown key; did you mean 'resolution'?",
        ),
        (
            {"output": {"compresion": "lz4"}},
            "job.yaml: output.compresion = 'lz4': unknown key; did you mean 'compression'",
        ),
        (
            {"output": {"compression": "lz5"}},
            "did you mean 'lz4'?",
        ),
        (
            {"sensors": [{"type": "camera", "name": "c", "rate": 5, "encoding": "RGB8"}]},
            "did you mean 'rgb8'?",
        ),
        (
            {"sensors": [{"type": "imus", "name": "i", "rate": 5}]},
            "unknown sensor type 'imus' (did you mean 'imu'?); allowed:",
        ),
    ],
)
def test_mistakes_suggest_the_closest_allowed_word(data: dict[str, Any], expected: str) -> None:
    err = _config_error(data)
    assert expected in err
    assert len(err.splitlines()) == 1, err


def test_no_suggestion_when_nothing_is_close() -> None:
    err = _config_error({"trajectory": {"zzzzqqq": 1}})
    assert err == "job.yaml: trajectory.zzzzqqq = 1: unknown key (not allowed here)"


def test_scene_files_suggest_keys_too(tmp_path: Path) -> None:
    from roslan.errors import RoslanError
    from roslan.scene import load_scene

    path = tmp_path / "s.yaml"
    path.write_text(
        "name: s\nobjects:\n  - name: box\n    primitive: {type: box, size: [1, 1, 1]}\n"
        "    poes: {position: [0, 0, 0]}\n",
        encoding="utf-8",
    )
    with pytest.raises(RoslanError, match=r"unknown key; did you mean 'pose'\?"):
        load_scene(path)


# ------------------------------------------------------------------ roslan trajectory
def test_trajectory_command_reads_only_the_trajectory_block(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    job = tmp_path / "job.yaml"
    job.write_text(
        yaml.safe_dump(
            {
                "trajectory": SHORT_TRAJECTORY,
                "scene": 42,  # not even a string
                "sensors": [{"type": "bogus"}, {"name": "no type"}],
                "unrelated": True,
            }
        ),
        encoding="utf-8",
    )
    assert main(["trajectory", str(job), "-o", str(tmp_path / "t"), "--no-plot"]) == 0
    assert (tmp_path / "t" / "trajectory.csv").is_file()
    bad = tmp_path / "bad.yaml"
    bad.write_text("trajectory: {k: 0.5, kapa: {x: 0.4}}\nsensors: 3\n", encoding="utf-8")
    capsys.readouterr()
    assert main(["trajectory", str(bad), "-o", str(tmp_path / "u")]) == 2
    err = capsys.readouterr().err
    assert err == (f"error: {bad}: trajectory.kapa: unknown key; did you mean 'kappa'?\n")
    assert not (tmp_path / "u").exists()


# ------------------------------------------------------------------ pre-flight
def test_a_sensor_without_scene_stops_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import roslan.pipeline.record as record_mod
    import roslan.pipeline.run as run_mod

    job = tmp_path / "job.yaml"
    job.write_text(
        yaml.safe_dump(
            {
                "trajectory": SHORT_TRAJECTORY,
                "sensors": [
                    {"type": "imu", "name": "imu", "rate": 100},
                    {"type": "lidar", "name": "velo", "preset": "vlp16", "rate": 10},
                ],
            }
        ),
        encoding="utf-8",
    )
    started: list[str] = []
    monkeypatch.setattr(run_mod, "WorkerPool", lambda *a: started.append("pool"))
    monkeypatch.setattr(record_mod, "make_temp", lambda *a: started.append("tmp"))
    assert main(["simulate", str(job), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {job}: sensors[1] ('velo', type lidar) needs a scene")
    assert "scene: warehouse" in err
    assert "simulating" not in err
    assert "roslan:" not in err
    assert started == []
    assert not (tmp_path / "out").exists()


def test_preflight_accepts_scene_free_sensors() -> None:
    from roslan.pipeline import preflight
    from roslan.trajectory.generator import TauTrajectory

    cfg = SimConfig.model_validate(
        {"trajectory": SHORT_TRAJECTORY, "sensors": [{"type": "imu", "name": "imu", "rate": 50}]}
    )
    preflight(cfg, TauTrajectory(cfg.trajectory))  # no error
    needs = {k for k in SENSOR_TYPES if config_class(k).needs_scene}
    assert needs == set(SENSOR_TYPES) - {"imu"}


# ------------------------------------------------------------------ progress
def _imu_job(tmp_path: Path, scene: str | None = "empty") -> Path:
    job = tmp_path / "job.yaml"
    data: dict[str, Any] = {
        "trajectory": SHORT_TRAJECTORY,
        "sensors": [{"type": "imu", "name": "imu", "rate": 100}],
        "output": {"ground_truth_rate": 20},
    }
    if scene is not None:
        data["scene"] = scene
    job.write_text(yaml.safe_dump(data), encoding="utf-8")
    return job


def test_progress_names_each_phase_and_quiet_silences_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    job = _imu_job(tmp_path)
    assert main(["simulate", str(job), "-o", str(tmp_path / "a"), "--workers", "0"]) == 0
    err = capsys.readouterr().err.splitlines()
    phases = [ln for ln in err if ln.startswith("roslan: ")]
    # not a terminal: one line per phase, in order
    expected = [
        "roslan: loading scene 'empty'...",
        "roslan: checking the path's clearance...",
        "roslan: preparing sensors",
        "roslan: simulating 1.",
        "roslan: closing sensors and bags...",
        "roslan: drawing overview.png...",
    ]
    assert len(phases) == len(expected), err
    for line, start in zip(phases, expected, strict=True):
        assert line.startswith(start), (line, start)
    assert main(["simulate", str(job), "-o", str(tmp_path / "b"), "--quiet"]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    assert captured.out == ""


def test_progress_bar_on_a_terminal_shows_the_time_left() -> None:
    from rich.progress import TimeRemainingColumn

    from roslan.pipeline.report import Progress

    p = Progress(quiet=False)
    p._console.is_terminal  # noqa: B018 - a property
    p._console._force_terminal = True
    p.phase("loading scene 'x'")
    assert p._status is not None
    p.start(2.0)
    try:
        assert any(isinstance(c, TimeRemainingColumn) for c in p._bar.columns)
        p.update(1.0)
        assert p._bar.tasks[0].completed == pytest.approx(1.0)
    finally:
        p.stop()
    assert p._bar is None
    assert p._status is None


@pytest.mark.parametrize("width", [80, 120])
def test_progress_bar_keeps_the_time_left_at_80_columns(width: int) -> None:
    import re

    from rich.console import Console

    from roslan.pipeline.report import Progress

    p = Progress(quiet=False)
    p._console = Console(
        width=width,
        force_terminal=True,
        record=True,
        file=open(os.devnull, "w"),  # noqa: SIM115
    )
    p.start(12.5)
    try:
        p._t0 -= 40.0  # 40 s of wall time for 3.25 s of trajectory: a long run
        p.update(3.25)
        line = "".join(seg.text for seg in p._console.render(p._bar.get_renderable()))
    finally:
        p.stop()
    row = line.splitlines()[0]
    assert len(row) <= width
    assert "3.25/12.50 s" in row
    assert re.search(r"RTF 12\.\d\d ", row), row
    # elapsed, then the time left (rich's estimate, '-:--:--' until it has a speed)
    assert re.search(r"\d:\d\d:\d\d (\d:\d\d:\d\d|-:--:--) left$", row.rstrip()), row


def test_overwrite_message_is_plain(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    job = _imu_job(tmp_path, scene=None)
    out = tmp_path / "o"
    assert main(["simulate", str(job), "-o", str(out), "--quiet", "--no-overview"]) == 0
    assert main(["simulate", str(job), "-o", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err == f"error: output folder {out} exists; pass --overwrite to replace it\n"


# ------------------------------------------------------------------ CLI texts, packaging
def _parsers(parser: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
    out = [parser]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in dict.fromkeys(action.choices.values()):
                out += _parsers(sub)
    return out


def test_help_texts_are_plain_and_complete() -> None:
    parsers = _parsers(build_parser())
    assert len(parsers) > 10
    for p in parsers:
        text = p.format_help()
        assert "``" not in text, p.prog
        for action in p._actions:
            if action.option_strings and action.help is None:
                pytest.fail(f"{p.prog} {action.option_strings}: no help text")


def test_pyproject_license_is_an_spdx_string_for_a_setuptools_that_reads_it() -> None:
    data = tomllib.loads((ROOT / "pyproject.toml").read_text("utf-8"))
    assert data["project"]["license"] == "MIT"
    requires = data["build-system"]["requires"]
    spec = next(r for r in requires if r.startswith("setuptools"))
    m = re.fullmatch(r"setuptools>=(\d+)(\.\d+)*", spec)
    # PEP 639 license expressions are read (without the table deprecation) from 77 on
    assert m is not None
    assert int(m.group(1)) >= 77


# ------------------------------------------------------------------ figures
@pytest.fixture(scope="module")
def sensor_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from roslan.pipeline import run_simulation

    cfg = SimConfig.model_validate(
        {
            "trajectory": {
                "k": 0.5,
                "initial": {"position": [-3.0, 0.4, 0.6], "rpy": [0.05, 0.1, 0.2],
                            "descent_rate": 1.2},
            },
            "scene": "empty",
            "sensors": [
                {"type": "imu", "name": "imu", "rate": 200},
                {"type": "camera", "name": "cam", "rate": 5, "resolution": [64, 48],
                 "pose": {"rpy": [0, 0.5, 0]}},
                {"type": "lidar", "name": "velo", "preset": "vlp16", "rate": 5},
            ],
            "output": {"ground_truth_rate": 20, "formats": ["ros1"]},
        }
    )  # fmt: skip
    out = tmp_path_factory.mktemp("first_hour") / "run"
    run_simulation(cfg, out, quiet=True, workers=0, overview=False)
    return out


class _Figures:
    """Captures the matplotlib figures a plotting module saves."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, module: Any) -> None:
        self.saved: list[tuple[Any, dict[str, Any]]] = []
        original = module.save_figure

        def capture(fig: Any, path: Path, **kw: Any) -> Path:
            self.saved.append((fig, kw))
            return original(fig, path, **kw)  # type: ignore[no-any-return]

        monkeypatch.setattr(module, "save_figure", capture)


def _inside(fig: Any, artist: Any) -> bool:
    renderer = fig.canvas.get_renderer()
    box = artist.get_window_extent(renderer)
    return bool(box.x0 >= -1 and box.y0 >= -1 and box.x1 <= fig.bbox.x1 + 1
                and box.y1 <= fig.bbox.y1 + 1)  # fmt: skip


def test_overview_names_the_camera_before_run_json_exists(
    sensor_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import shutil

    import roslan.plots.overview as ov

    # roslan simulate draws the overview before it writes run.json
    folder = tmp_path / "no_run_json"
    shutil.copytree(sensor_run, folder)
    (folder / "run.json").unlink()
    figs = _Figures(monkeypatch, ov)
    ov.write_overview(folder)
    fig = figs.saved[0][0]
    titles = [ax.get_title() for ax in fig.axes]
    assert any(t.startswith("Camera 'cam'") for t in titles), titles
    assert not any("images" in t for t in titles), titles


def test_overview_3d_panel_ticks_do_not_overlap_and_markers_match_the_legend(
    sensor_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import roslan.plots.overview as ov

    figs = _Figures(monkeypatch, ov)
    ov.write_overview(sensor_run, tmp_path / "o.png")
    fig = figs.saved[0][0]
    ax3 = next(ax for ax in fig.axes if ax.name == "3d")
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    from mpl_toolkits.mplot3d import proj3d

    lims = np.array([ax3.get_xlim(), ax3.get_ylim(), ax3.get_zlim()])
    for k, axis in enumerate((ax3.xaxis, ax3.yaxis, ax3.zaxis)):
        lo, hi = sorted(lims[k])
        locs = [v for v in axis.get_majorticklocs() if lo - 1e-9 <= v <= hi + 1e-9]
        assert len(locs) >= 2
        # neighbouring ticks, projected on screen, are further apart than a label is wide
        pts = []
        for v in locs:
            p3 = lims[:, 0].copy()
            p3[k] = v
            px, py, _ = proj3d.proj_transform(*p3, ax3.get_proj())
            pts.append(ax3.transData.transform((px, py)))
        gaps = np.linalg.norm(np.diff(np.array(pts), axis=0), axis=1)
        font = axis.get_ticklabels()[0].get_fontproperties()
        width = max(
            renderer.get_text_width_height_descent(f"{v:.1f}", font, ismath=False)[0] for v in locs
        )
        assert gaps.min() > width, (k, locs, gaps, width)
    handles, labels = ax3.get_legend_handles_labels()
    start = handles[labels.index("start")]
    # a plain line marker (no depth shading): what is drawn is what the legend shows
    from matplotlib.colors import to_rgba
    from matplotlib.lines import Line2D

    assert isinstance(start, Line2D)
    assert to_rgba(start.get_color()) == to_rgba("k")
    # the legend does not cover the start point
    legend = ax3.get_legend().get_window_extent(renderer)
    xs, ys, zs = (float(np.ravel(v)[0]) for v in start.get_data_3d())
    px, py, _ = proj3d.proj_transform(xs, ys, zs, ax3.get_proj())
    sx, sy = ax3.transData.transform((px, py))
    assert not legend.contains(sx, sy)


def test_imu_only_overview_shows_the_imu(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import roslan.plots.overview as ov
    from roslan.pipeline import run_simulation

    cfg = SimConfig.model_validate(
        {
            "trajectory": SHORT_TRAJECTORY,
            "sensors": [{"type": "imu", "name": "imu", "rate": 100}],
            "output": {"ground_truth_rate": 20, "formats": ["ros1"]},
        }
    )
    run_simulation(cfg, tmp_path / "r", quiet=True, overview=False)
    placeholders: list[str] = []
    real = ov._placeholder
    monkeypatch.setattr(
        ov, "_placeholder", lambda ax, t, x: (placeholders.append(t), real(ax, t, x))
    )
    figs = _Figures(monkeypatch, ov)
    ov.write_overview(tmp_path / "r")
    assert placeholders == []
    fig = figs.saved[0][0]
    titles = " | ".join(ax.get_title() for ax in fig.axes)
    assert "IMU accelerometer" in titles
    assert "IMU gyroscope" in titles
    imu = np.loadtxt(tmp_path / "r" / "imu.txt")
    acc_ax = next(ax for ax in fig.axes if ax.get_title().startswith("IMU accelerometer"))
    # the panel plots the recorded samples themselves
    for i, line in enumerate(acc_ax.get_lines()[:3]):
        np.testing.assert_allclose(line.get_ydata(), imu[:, 1 + i])


def test_imu_and_lidar_titles_fit_their_figures(
    sensor_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import roslan.plots.imu as imu_mod
    import roslan.plots.lidar as lidar_mod

    figs = _Figures(monkeypatch, imu_mod)
    imu_mod.plot_imu(sensor_run, tmp_path / "imu.png")
    fig = figs.saved[0][0]
    fig.canvas.draw()
    for ax in fig.axes:
        assert _inside(fig, ax.title), ax.get_title()
    figs = _Figures(monkeypatch, lidar_mod)
    lidar_mod.plot_lidar(sensor_run, tmp_path / "lidar.png")
    fig, kw = figs.saved[0]
    fig.canvas.draw()
    # saved to the bounding box of everything drawn: nothing can be cut off
    assert kw.get("tight") is True
    titles = [ax.title for ax in fig.axes if ax.get_title()]
    assert titles
    assert fig.get_suptitle()


def test_event_frames_have_labelled_axes(
    sensor_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("numba")
    import roslan.plots.events as ev
    from roslan.pipeline import run_simulation

    cfg = SimConfig.model_validate(
        {
            "trajectory": {"k": 0.5, "initial": {"position": [-0.4, 0.1, 0.3],
                                                 "descent_rate": 1.5}},
            "scene": "empty",
            "sensors": [{"type": "event_camera", "name": "dvs", "rate": 10, "max_rate": 100,
                         "pose": {"rpy": [0, 0.6, 0]}}],
            "output": {"ground_truth_rate": 20, "formats": ["ros1"]},
        }
    )  # fmt: skip
    run_simulation(cfg, tmp_path / "ev", quiet=True, workers=0, overview=False)
    figs = _Figures(monkeypatch, ev)
    ev.plot_events(tmp_path / "ev", tmp_path / "plots", frames=2)
    frames = next(f for f, _ in figs.saved if len(f.axes) == 2)
    for ax in frames.axes:
        assert ax.get_xlabel() == "u [px]"
        assert ax.get_ylabel() == "v [px]"
        assert ax.axison


def test_trajectory_png_uses_the_axis_colours(tmp_path: Path) -> None:
    from PIL import Image

    from roslan.plots.style import AXIS_COLORS

    job = _imu_job(tmp_path, scene=None)
    assert main(["trajectory", str(job), "-o", str(tmp_path / "t")]) == 0
    img = np.asarray(Image.open(tmp_path / "t" / "trajectory.png").convert("RGB")).astype(int)
    for hexcolor in AXIS_COLORS:
        rgb = np.array([int(hexcolor[i : i + 2], 16) for i in (1, 3, 5)])
        near = np.abs(img - rgb).max(axis=2) <= 12
        # two gap curves per colour (x and roll, y and pitch, z and yaw)
        assert near.sum() > 400, hexcolor


def test_scene_preview_top_view_is_scaled_to_the_plant(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import matplotlib.figure

    from roslan.plots.scene import write_preview
    from roslan.scene import load_scene

    scene = load_scene("refinery", seed=0)
    captured: list[Any] = []
    real = matplotlib.figure.Figure.savefig

    def keep(self: Any, *a: Any, **k: Any) -> Any:
        captured.append(self)
        return real(self, *a, **k)

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", keep)
    write_preview(scene, tmp_path / "p.png", rendered=False)
    ax = captured[0].axes[0]
    x0, x1 = ax.get_xlim()
    lo, hi = scene.bounds
    # the plant's objects, not the ground slab (the bounds of the whole scene)
    objs = [o for o in scene.objects if np.ptp(o.vertices[:, 2]) >= 1.0]
    vx = np.concatenate([o.vertices[:, 0] for o in objs])
    assert x1 - x0 < 0.8 * float(hi[0] - lo[0])
    assert x0 <= vx.min()
    assert x1 >= vx.max()


def test_help_texts_carry_no_rest_markup() -> None:
    """Every command's --help reads as plain text: no Sphinx roles, no double backticks."""
    import argparse
    import re

    from roslan.cli.app import build_parser, plain

    assert plain("see :func:`~roslan.plots.overview.write_overview` in :mod:`roslan.plots`") == (
        "see write_overview in roslan.plots"
    )
    pending, seen = [build_parser()], 0
    while pending:
        parser = pending.pop()
        text = parser.format_help()
        assert not re.search(r":[a-z]+:`", text), (parser.prog, text)
        assert "``" not in text, parser.prog
        seen += 1
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                pending.extend(dict.fromkeys(action.choices.values()))
    assert seen >= 15  # roslan, its commands and the plot and scene subcommands
