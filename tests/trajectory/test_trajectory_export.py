"""Trajectory files, shared text/atomic helpers and the `roslan trajectory` / `roslan plot
tau-family` commands."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pytest

import roslan.cli.app
import roslan.cli.plot
from roslan.errors import OutputError
from roslan.frames import quat_xyzw_to_matrix
from roslan.io.files import atomic_write
from roslan.io.text import format_seconds, write_columns
from roslan.plots.landing import write_trajectory_plot
from roslan.trajectory import TauTrajectory, Trajectory, TrajectoryConfig
from roslan.trajectory.export import write_trajectory_files
from roslan.vehicle import VehicleConfig, base_link_trajectory

HEADER = "t,x,y,z,roll,pitch,yaw,vx,vy,vz,vroll,vpitch,vyaw,ax,ay,az,aroll,apitch,ayaw"

CONFIG = """
trajectory:
  k: 0.5
  kappa: {x: 0.4, y: 0.6, roll: 0.5, pitch: 0.5, yaw: 0.5}
  initial:
    position: [-8.0, 2.0, 4.6]
    rpy: [0.05, 0.15, 0.3]
    descent_rate: 2.0
  goal: {position: [10.0, 5.0, 0.0], rpy: [0.0, 0.0, 1.57]}
  sample_dt: 0.1
  hold: 0.25
"""


@pytest.fixture(autouse=True)
def _only_our_commands(monkeypatch: pytest.MonkeyPatch) -> None:
    # other command modules are not under test here
    monkeypatch.setattr(
        roslan.cli.app, "COMMAND_MODULES", ("roslan.cli.trajectory", "roslan.cli.plot")
    )


def run_cli(*argv: str) -> int:
    return roslan.cli.main(list(argv))


# ---------------------------------------------------------------- text helpers
def test_format_seconds_is_exact_from_integers() -> None:
    rng = np.random.default_rng(1)
    t = np.concatenate([[0, 1, 999_999_999, 10**9, -1, -(10**9) - 5], rng.integers(0, 2**62, 100)])
    out = format_seconds(t.astype(np.int64))
    for ns, text in zip(t.tolist(), out.tolist(), strict=True):
        sign = -1 if text.startswith("-") else 1
        sec, frac = text.lstrip("-").split(".")
        assert len(frac) == 9
        assert sign * (int(sec) * 10**9 + int(frac)) == ns
    assert format_seconds(np.array([1_500_000_000])).tolist() == ["1.500000000"]


def test_write_columns_round_trip_and_chunks(monkeypatch: pytest.MonkeyPatch) -> None:
    import roslan.io.text as text

    monkeypatch.setattr(text, "CHUNK_ROWS", 7)
    n = 50
    t = np.arange(n, dtype=np.int64) * 12_345_678
    a = np.linspace(-1, 1, n)
    a[3] = -0.0
    b = np.arange(n) % 3
    fh = io.StringIO()
    assert write_columns(fh, t, a, b, fmt=["%.17g", "%d"], sep=",") == n
    lines = fh.getvalue().splitlines()
    assert len(lines) == n
    assert lines[3].split(",")[1] == "0"
    back = np.loadtxt(io.StringIO(fh.getvalue()), delimiter=",")
    np.testing.assert_array_equal(np.round(back[:, 0] * 1e9).astype(np.int64), t)
    np.testing.assert_array_equal(back[:, 1], a)
    np.testing.assert_array_equal(back[:, 2], b)
    with pytest.raises(OutputError, match="NaN"):
        write_columns(io.StringIO(), t[:2], np.array([1.0, np.nan]))


def test_atomic_write_keeps_old_file_on_error(tmp_path: Path) -> None:
    p = tmp_path / "f.txt"
    p.write_text("old")

    def fail() -> None:
        with atomic_write(p) as fh:
            fh.write("half")
            raise RuntimeError("boom")

    with pytest.raises(RuntimeError):
        fail()
    assert p.read_text() == "old"
    assert [x.name for x in tmp_path.iterdir()] == ["f.txt"]
    with atomic_write(p, "wb") as fb:
        fb.write(b"new")
    assert p.read_bytes() == b"new"


# ---------------------------------------------------------------- trajectory files
def _check_outputs(out: Path, traj: Trajectory) -> None:
    lines = (out / "trajectory.csv").read_text().splitlines()
    assert lines[0] == HEADER
    table = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1)
    assert table.shape[1] == 19
    t_ns = np.array([round(float(r.split(",")[0]) * 1e9) for r in lines[1:]])
    expected = np.round(traj.table_times() * 1e9).astype(np.int64)
    np.testing.assert_array_equal(t_ns, expected)
    assert np.all(np.diff(t_ns) > 0)
    # rows every 0.1 s up to T, the landing row at T, then the hold
    i_T = int(np.flatnonzero(t_ns == round(traj.T * 1e9))[0])
    np.testing.assert_array_equal(t_ns[:i_T], np.arange(i_T) * 100_000_000)
    np.testing.assert_array_equal(table[i_T, 1:7], 0.0)  # every gap closed exactly at T
    st = traj.state(traj.table_times())
    np.testing.assert_allclose(table[:, 1:], st.components(), rtol=1e-10, atol=1e-12)
    # TUM: t px py pz qx qy qz qw, single spaces, world frame
    gt_lines = (out / "groundtruth.txt").read_text().splitlines()
    body = [ln for ln in gt_lines if not ln.startswith("#")]
    assert all(len(ln.split(" ")) == 8 for ln in body)
    gt = np.loadtxt(out / "groundtruth.txt")
    # at the ground-truth rate (default 200 Hz, as /ground_truth/pose), not every sample_dt:
    # every 5 ms from 0, then the end of the run exactly
    gt_ns = np.round(gt[:, 0] * 1e9).astype(np.int64)
    end = round(traj.duration * 1e9)
    every = np.arange(0, end + 1, 5_000_000, dtype=np.int64)
    np.testing.assert_array_equal(gt_ns, every if every[-1] == end else np.append(every, end))
    st = traj.state(gt_ns * 1e-9)
    np.testing.assert_allclose(gt[:, 1:4], st.position, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(gt[:, 4:], axis=1), 1.0, atol=1e-8)
    np.testing.assert_allclose(quat_xyzw_to_matrix(gt[:, 4:]), st.R_world_body, atol=1e-8)
    np.testing.assert_allclose(gt[-1, 1:4], traj.config.goal.position, atol=1e-9)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["T"] == pytest.approx(traj.T)
    assert summary["tau0"] == pytest.approx(traj.tau0)
    assert summary["terminal"]["z"] == "constant_deceleration"


def test_write_trajectory_files(tmp_path: Path) -> None:
    cfg = TrajectoryConfig.model_validate(
        {"goal": {"position": [10.0, 5.0, 0.0], "rpy": [0.0, 0.0, 1.57]}, "hold": 0.25}
    )
    traj = TauTrajectory(cfg)
    write_trajectory_files(traj, tmp_path)
    write_trajectory_plot(traj, tmp_path / "trajectory.png")
    _check_outputs(tmp_path, traj)
    png = (tmp_path / "trajectory.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    # the velocity arrows (dark orange, thick) stand out on the 3-D panel (left half)
    import imageio.v3 as iio

    img = iio.imread(tmp_path / "trajectory.png")[:, :, :3].astype(int)
    left = img[:, : img.shape[1] // 2]
    assert (np.abs(left - [255, 140, 0]).sum(axis=-1) < 60).sum() > 1000
    # deterministic: byte-identical on a second run
    second = tmp_path / "again"
    second.mkdir()
    write_trajectory_files(traj, second)
    write_trajectory_plot(traj, second / "trajectory.png")
    for name in ("trajectory.csv", "groundtruth.txt", "summary.json", "trajectory.png"):
        assert (second / name).read_bytes() == (tmp_path / name).read_bytes(), name


def test_cli_trajectory(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = tmp_path / "sim.yaml"
    cfg.write_text(CONFIG)
    out = tmp_path / "out"
    assert run_cli("trajectory", str(cfg), "-o", str(out)) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "groundtruth.txt",
        "summary.json",
        "trajectory.csv",
        "trajectory.png",
    ]
    # as roslan simulate flies it: base_link above the goal by the default vehicle's feet
    traj = TauTrajectory(
        base_link_trajectory(
            TrajectoryConfig.model_validate({**_yaml(CONFIG)["trajectory"]}), VehicleConfig()
        )
    )
    _check_outputs(out, traj)
    assert "T = 4.6" in capsys.readouterr().out
    # an existing OUTDIR is refused without --overwrite, accepted with it
    assert run_cli("trajectory", str(cfg), "-o", str(out)) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert run_cli("trajectory", str(cfg), "-o", str(out), "--overwrite", "--no-plot") == 0


def test_cli_trajectory_follows_the_ground_truth_rate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """groundtruth.txt of `roslan trajectory CONFIG` is written at the YAML's
    output.ground_truth_rate, as `roslan simulate` writes it; a bad rate names the key."""
    cfg = tmp_path / "sim.yaml"
    cfg.write_text(CONFIG + "output: {ground_truth_rate: 40.0, formats: [ros2]}\n")
    assert run_cli("trajectory", str(cfg), "-o", str(tmp_path / "out"), "--no-plot") == 0
    t = np.loadtxt(tmp_path / "out" / "groundtruth.txt")[:, 0]
    np.testing.assert_allclose(np.diff(t)[:-1], 0.025, atol=1e-9)
    assert t[-1] == pytest.approx(4.6 + 0.25)  # touchdown plus hold
    cfg.write_text(CONFIG + "output: {ground_truth_rate: -1}\n")
    assert run_cli("trajectory", str(cfg), "-o", str(tmp_path / "bad")) == 2
    assert "ground_truth_rate" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def _yaml(text: str) -> dict[str, dict[str, object]]:
    import yaml

    data = yaml.safe_load(text)
    assert isinstance(data, dict)
    return data


@pytest.mark.parametrize(
    ("block", "key"),
    [
        ("{k: 0}", "trajectory.k"),
        ("{k: -1}", "trajectory.k"),
        ("{k: 1.2}", "trajectory.k"),
        ("{k: 1.0}", "trajectory.k"),
        ("{kappa: {x: 0}}", "trajectory.kappa.x"),
        ("{kappa: {yaw: -0.5}}", "trajectory.kappa.yaw"),
        ("{initial: {position: [1, 1, 0], descent_rate: 1}}", "trajectory.initial.position"),
        ("{initial: {position: [1, 1, -2], descent_rate: 1}}", "trajectory.initial.position"),
        ("{initial: {position: [1, 1, 2], descent_rate: 0}}", "trajectory.initial.descent_rate"),
        ("{sample_dt: 0}", "trajectory.sample_dt"),
        ("{sample_dt: -0.1}", "trajectory.sample_dt"),
        ("{k: .nan}", "trajectory.k"),
        ("{kappa: {pitch: .nan}}", "trajectory.kappa.pitch"),
        ("{goal: {position: [0, .inf, 0]}}", "trajectory.goal.position[1]"),
        ("{colour: red}", "trajectory.colour"),
    ],
)
def test_cli_invalid_inputs_exit_nonzero_naming_key(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], block: str, key: str
) -> None:
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(f"trajectory: {block}\n")
    out = tmp_path / "out"
    assert run_cli("trajectory", str(cfg), "-o", str(out)) != 0
    err = capsys.readouterr().err
    assert err.startswith("error: ")
    assert "Traceback" not in err
    assert str(cfg) in err
    assert key in err
    assert not out.exists()  # nothing half-written
    if block == "{k: 1.0}":
        assert "constant speed" in err
        assert "crash" in err


def test_cli_malformed_and_missing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = tmp_path / "bad.yaml"
    cfg.write_text("trajectory: {k: [0.5\n")
    assert run_cli("trajectory", str(cfg), "-o", str(tmp_path / "o")) != 0
    assert "malformed YAML" in capsys.readouterr().err
    assert run_cli("trajectory", str(tmp_path / "missing.yaml"), "-o", str(tmp_path / "o")) != 0
    assert "file not found" in capsys.readouterr().err


def test_cli_warnings_are_one_line_each(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = tmp_path / "hard.yaml"
    cfg.write_text("trajectory: {k: 0.7, kappa: {x: 1.0}}\n")
    assert run_cli("trajectory", str(cfg), "-o", str(tmp_path / "o"), "--no-plot") == 0
    err = capsys.readouterr().err.splitlines()
    warn = [ln for ln in err if ln.startswith("warning: ")]
    assert len(warn) == 2
    assert len(err) == 2
    assert any("z gap" in ln and "without bound" in ln for ln in warn)
    assert any("x gap" in ln for ln in warn)
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert len(summary["warnings"]) == 2
    assert summary["peak_deceleration"] is None


def test_cli_plot_tau_family(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "fig1.png"
    assert run_cli("plot", "tau-family", "-o", str(out), "--k", "0.3", "0.5", "1.0") == 0
    assert out.read_bytes()[:4] == b"\x89PNG"
    assert run_cli("plot", "tau-family", "-o", str(tmp_path / "x.png"), "--k", "0") != 0
    assert "--k" in capsys.readouterr().err
    assert run_cli("plot", "tau-family", "-o", str(tmp_path / "x.png"), "--k", "nan") != 0
    assert not (tmp_path / "x.png").exists()


def test_tau_family_axes_name_their_units(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each panel's y axis says what it plots and in which unit (the gap's included)."""
    from matplotlib.figure import Figure

    from roslan.plots.tau_family import plot_tau_family

    saved: list[Figure] = []
    savefig = Figure.savefig
    monkeypatch.setattr(
        Figure, "savefig", lambda fig, *a, **k: saved.append(fig) or savefig(fig, *a, **k)
    )
    plot_tau_family([0.3, 0.5], tmp_path / "f.png")
    (fig,) = saved
    assert [ax.get_ylabel() for ax in fig.axes] == ["χ [m]", "-χ' [m/s]", "χ'' [m/s²]"]
    assert all(ax.get_xlabel() == "t [s]" for ax in fig.axes)
