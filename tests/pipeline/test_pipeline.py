"""The pipeline end to end: output folder contract, determinism, atomicity, bad input,
ground-truth content, CLI."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import yaml
from rosbags.highlevel import AnyReader

from pipeline_helpers import SHORT_TRAJECTORY, short_config, tree_bytes
from roslan.cli import main
from roslan.config.sim import SimConfig
from roslan.errors import ConfigError, OutputError, SensorError
from roslan.frames import quat_xyzw_to_matrix
from roslan.pipeline import run_simulation
from roslan.pipeline.context import Context, stream_key
from roslan.sensors import registry
from roslan.sensors.base import Message
from roslan.sensors.imu import Imu, ImuConfig


@pytest.fixture
def no_plot(monkeypatch: pytest.MonkeyPatch) -> None:
    """Skip the trajectory.png rendering (about a second of matplotlib) where a test does not
    look at it; the contract and determinism tests keep it."""
    import roslan.plots.landing as landing

    monkeypatch.setattr(landing, "write_trajectory_plot", lambda traj, path: None)


@pytest.fixture(scope="module")
def out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("pipe") / "out"
    run_simulation(short_config(), d, quiet=True)
    return d


def test_output_folder_contract(out: Path) -> None:
    names = {p.name for p in out.iterdir()}
    expected = {
        "landing.bag", "landing_ros2", "trajectory.csv", "groundtruth.txt", "summary.json",
        "imu.txt", "trajectory.png",
        "calib", "PLAYBACK.md", "run.json", "timing.json",
    }  # fmt: skip
    assert expected <= names
    assert {p.name for p in (out / "landing_ros2").iterdir()} == {
        "metadata.yaml",
        "landing_ros2.mcap",
    }
    assert (out / "calib" / "imu.yaml").is_file()
    ext = yaml.safe_load((out / "calib" / "extrinsics.yaml").read_text())
    T = np.array(ext["sensors"]["imu"]["T_base_link_sensor"])
    np.testing.assert_allclose(T, short_config().sensors[0].pose.matrix())
    run = json.loads((out / "run.json").read_text())
    assert run["complete"] is True
    assert run["seed"] == 3
    assert run["start_time_ns"] == short_config().output.start_time
    assert run["trajectory_duration_s"] == pytest.approx(1.2)
    assert run["versions"]["rosbags"]
    assert run["topics"]["/imu"]["messages"] == 241  # 200 Hz over [0, 1.2] s inclusive
    assert run["topics"]["/tf"]["messages"] == 61
    assert run["topics"]["/tf_static"]["messages"] == 1
    assert run["config"]["sensors"][0]["rate"] == 200.0
    assert not (out / ".plot").exists()  # the background plot's scratch folder is gone
    # no leftover temporary siblings
    assert not [p for p in out.parent.iterdir() if ".partial-" in p.name or ".old-" in p.name]
    timing = json.loads((out / "timing.json").read_text())
    assert timing["wall_time_s"] > 0
    play = (out / "PLAYBACK.md").read_text()
    for needle in ("rosbag play", "ros2 bag play landing_ros2", "Foxglove"):
        assert needle in play


def test_ground_truth_content(out: Path) -> None:
    cfg = short_config()
    from roslan.trajectory import TauTrajectory
    from roslan.vehicle import base_link_trajectory

    # base_link's goal lies above the configured one, by the default feet (8 cm)
    traj = TauTrajectory(base_link_trajectory(cfg.trajectory, cfg.vehicle))
    assert traj.p_world_goal == pytest.approx([0.0, 0.0, 0.08])
    with AnyReader([out / "landing_ros2"]) as reader:
        msgs: dict[str, list] = {}
        for conn, stamp, raw in reader.messages():
            msgs.setdefault(conn.topic, []).append((stamp, reader.deserialize(raw, conn.msgtype)))
    static = msgs["/tf_static"][0][1]
    frames = {(t.header.frame_id, t.child_frame_id) for t in static.transforms}
    assert ("base_link", "imu") in frames
    t_ns = np.array([s for s, _ in msgs["/ground_truth/odometry"]]) - cfg.output.start_time
    st = traj.state_ns(t_ns)
    odo = msgs["/ground_truth/odometry"]
    pos = np.array(
        [[m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z] for _, m in odo]
    )
    np.testing.assert_allclose(pos, st.position, atol=1e-12)
    # twist is in base_link: rotate it back to the world and compare with the world velocity
    q = np.array([[m.pose.pose.orientation.x, m.pose.pose.orientation.y, m.pose.pose.orientation.z,
                   m.pose.pose.orientation.w] for _, m in odo])  # fmt: skip
    v_b = np.array(
        [[m.twist.twist.linear.x, m.twist.twist.linear.y, m.twist.twist.linear.z] for _, m in odo]
    )
    np.testing.assert_allclose(
        np.einsum("nij,nj->ni", quat_xyzw_to_matrix(q), v_b), st.velocity, atol=1e-9
    )
    tf = msgs["/tf"]
    tr = tf[10][1].transforms[0]
    assert (tr.header.frame_id, tr.child_frame_id) == ("world", "base_link")
    assert tr.transform.translation.x == pytest.approx(st.position[10, 0])
    tau = np.array([m.data for _, m in msgs["/tau/state"]])
    np.testing.assert_allclose(tau, st.components(), atol=1e-12)
    acc = msgs["/ground_truth/accel"]
    assert acc[0][1].header.frame_id == "base_link"
    # groundtruth.txt: one row per /ground_truth/pose message (ground_truth_rate = 50 Hz,
    # not the 10 Hz sample_dt of trajectory.csv), same times and poses
    pose = msgs["/ground_truth/pose"]
    bag_t = np.array([s for s, _ in pose]) - cfg.output.start_time
    bag = np.array([[m.pose.position.x, m.pose.position.y, m.pose.position.z,
                     m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z,
                     m.pose.orientation.w] for _, m in pose])  # fmt: skip
    lines = (out / "groundtruth.txt").read_text().splitlines()
    gt_t = np.array([int(ln.split()[0].replace(".", "")) for ln in lines])  # exact ns
    gt = np.loadtxt(out / "groundtruth.txt")
    assert len(pose) == 61  # 50 Hz over [0, 1.2] s inclusive
    np.testing.assert_array_equal(gt_t, bag_t)
    np.testing.assert_allclose(gt[:, 1:], bag, atol=1e-9)  # printed with 9 decimals


def test_same_seed_byte_identical_different_seed_differs(out: Path, tmp_path: Path) -> None:
    again = tmp_path / "again"
    run_simulation(short_config(), again, quiet=True)
    a, b = tree_bytes(out), tree_bytes(again)
    assert a.keys() == b.keys()
    for name in a:
        assert a[name] == b[name], name
    other = tmp_path / "other"
    run_simulation(short_config(seed=4), other, quiet=True)
    c = tree_bytes(other)
    assert c["imu.txt"] != a["imu.txt"]
    assert c["landing.bag"] != a["landing.bag"]
    assert c["trajectory.csv"] == a["trajectory.csv"]


def test_existing_outdir_refused_then_overwritten(tmp_path: Path, no_plot: None) -> None:
    d = tmp_path / "o"
    run_simulation(short_config(), d, quiet=True, formats=["ros1"])
    assert not (d / "landing_ros2").exists()
    before = (d / "run.json").read_bytes()
    with pytest.raises(OutputError, match="exists"):
        run_simulation(short_config(), d, quiet=True)
    assert (d / "run.json").read_bytes() == before
    run_simulation(short_config(), d, quiet=True, overwrite=True, formats=["ros2"])
    assert (d / "landing_ros2").is_dir()
    assert not (d / "landing.bag").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o"]


def test_overwrite_refuses_a_foreign_folder(tmp_path: Path) -> None:
    d = tmp_path / "precious"
    d.mkdir()
    (d / "thesis.tex").write_text("x")
    with pytest.raises(OutputError, match="not a roslan output"):
        run_simulation(short_config(), d, quiet=True, overwrite=True)
    assert (d / "thesis.tex").read_text() == "x"


@pytest.mark.skipif(os.geteuid() == 0, reason="root ignores directory permissions")
def test_unwritable_outdir_nonroot(tmp_path: Path) -> None:  # pragma: no cover - CI runs as root
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        with pytest.raises(OutputError, match="cannot write"):
            run_simulation(short_config(), ro / "out", quiet=True)
    finally:
        ro.chmod(0o700)


def test_unwritable_outdir(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with pytest.raises(OutputError, match="cannot write output folder"):
        run_simulation(short_config(), blocker / "out", quiet=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def _nothing_written(tmp_path: Path) -> None:
    assert list(tmp_path.iterdir()) == [], list(tmp_path.iterdir())


@pytest.mark.parametrize(
    ("sensor", "match"),
    [
        ({"type": "nope", "name": "x", "rate": 10, "topic": "/x"}, "unknown sensor type 'nope'"),
        ({"type": "imu", "name": "x", "rate": 0, "topic": "/x"}, r"sensors\[0\]\.rate"),
        ({"type": "imu", "name": "x", "rate": -1, "topic": "/x"}, r"sensors\[0\]\.rate"),
        ({"type": "imu", "name": "x", "topic": "/x", "bogus": 1}, "bogus"),
    ],
)
def test_bad_sensor_config_cli(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], sensor: dict, match: str
) -> None:
    job = tmp_path / "cfg" / "job.yaml"
    job.parent.mkdir()
    job.write_text(yaml.safe_dump({"trajectory": SHORT_TRAJECTORY, "sensors": [sensor]}))
    work = tmp_path / "work"
    work.mkdir()
    assert main(["simulate", str(job), "-o", str(work / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "job.yaml" in err
    assert __import__("re").search(match, err), err
    assert "Traceback" not in err
    _nothing_written(work)


def test_duplicate_topics(tmp_path: Path) -> None:
    imu = {"type": "imu", "name": "a", "rate": 100, "topic": "/imu"}
    with pytest.raises(Exception, match="duplicate"):
        SimConfig.model_validate({"sensors": [imu, {**imu, "name": "b"}]})
    # a sensor topic colliding with a ground-truth topic
    cfg = short_config(sensors=[{**imu, "topic": "/tf"}])
    with pytest.raises(ConfigError, match=r"'/tf'.*already published by 'ground_truth'"):
        run_simulation(cfg, tmp_path / "out", quiet=True)
    _nothing_written(tmp_path)


def test_malformed_yaml(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    job = tmp_path / "bad.yaml"
    job.write_text("sensors: [\n  - type: imu\n   name: x\n")
    work = tmp_path / "w"
    work.mkdir()
    assert main(["simulate", str(job), "-o", str(work / "out")]) == 2
    err = capsys.readouterr().err
    assert "bad.yaml" in err
    assert "malformed YAML" in err
    _nothing_written(work)


class _Exploding(Imu):
    """An IMU that fails half-way through its stream."""

    def messages(self, ctx: Context) -> Iterator[Message]:  # type: ignore[override]
        for i, m in enumerate(super().messages(ctx)):
            if i == 100:
                raise self.error
            yield m


@pytest.mark.parametrize("error", [RuntimeError("boom"), KeyboardInterrupt()])
def test_interrupted_run_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, error: BaseException, no_plot: None
) -> None:
    old = tmp_path / "out"
    run_simulation(short_config(), old, quiet=True)
    before = tree_bytes(old)
    _Exploding.error = error  # type: ignore[attr-defined]
    monkeypatch.setattr(registry, "sensor_class", lambda name: _Exploding)
    monkeypatch.setattr("roslan.pipeline.plan.sensor_class", lambda name: _Exploding)
    with pytest.raises(type(error)):
        run_simulation(short_config(), old, quiet=True, overwrite=True)
    with pytest.raises(type(error)):
        run_simulation(short_config(), tmp_path / "fresh", quiet=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert tree_bytes(old) == before  # the old complete output is untouched


_SLOW_RUN = textwrap.dedent(
    f"""
    import sys, time
    sys.path.insert(0, {str(Path(__file__).parents[1] / "helpers")!r})
    from pathlib import Path
    from pipeline_helpers import short_config
    from roslan.sensors.imu import Imu
    import roslan.pipeline.plan as plan
    from roslan.pipeline import run_simulation
    class Slow(Imu):
        def messages(self, ctx):
            for i, m in enumerate(super().messages(ctx)):
                if i == 50:
                    print("started", flush=True)
                    time.sleep(60)
                yield m
    plan.sensor_class = lambda name: Slow
    try:
        run_simulation(short_config(), Path(sys.argv[1]), quiet=True)
    except KeyboardInterrupt:
        sys.exit(130)
    """
)


def _start_slow_run(target: Path) -> subprocess.Popen[str]:
    """A simulation in a child process, stopped mid-stream until signalled."""
    proc = subprocess.Popen(
        [sys.executable, "-c", _SLOW_RUN, str(target)], stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout is not None
    assert proc.stdout.readline().strip() == "started"
    return proc


def test_killed_run_leaves_no_complete_outdir(tmp_path: Path) -> None:
    """SIGKILL mid-run: only a hidden .partial folder remains, never OUTDIR or a run.json."""
    target = tmp_path / "out"
    proc = _start_slow_run(target)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    assert not target.exists()
    leftovers = [p for p in tmp_path.iterdir() if p.name != ".out.lock"]
    assert leftovers
    assert all(p.name.startswith(".out.partial-") for p in leftovers)
    assert not any((p / "run.json").exists() for p in leftovers)
    # the next run into the same OUTDIR removes the dead run's partial folder and its lock
    run_simulation(short_config(), target, quiet=True, overview=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_concurrent_run_into_one_outdir_is_refused(tmp_path: Path) -> None:
    """While one run writes OUTDIR, a second one fails at once and leaves everything alone."""
    target = tmp_path / "out"
    proc = _start_slow_run(target)
    try:
        with pytest.raises(OutputError, match="being written by another roslan run"):
            run_simulation(short_config(), target, quiet=True, overview=False)
        partials = [p for p in tmp_path.iterdir() if p.name.startswith(".out.partial-")]
        assert len(partials) == 1  # the live run's folder was not cleaned away
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=30)
    assert not target.exists()


def test_two_concurrent_cli_runs_exactly_one_succeeds(tmp_path: Path) -> None:
    """Two `roslan simulate -o OUT` at once (no --overwrite): exactly one exits 0."""
    cfg = tmp_path / "job.yaml"
    cfg.write_text(
        "trajectory: {initial: {position: [-1, 0.5, 1.0], descent_rate: 1.0}, sample_dt: 0.05}\n"
        "sensors: [{type: imu, name: imu, topic: /imu, rate: 100}]\n",
        encoding="utf-8",
    )
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "roslan", "simulate", str(cfg), "-o", str(out), "--quiet"]
    cmd += ["--no-overview", "--seed"]
    procs = [
        subprocess.Popen([*cmd, str(seed)], stderr=subprocess.PIPE, text=True) for seed in (1, 2)
    ]
    results = [(p.wait(timeout=120), p.stderr.read() if p.stderr else "") for p in procs]
    codes = sorted(rc for rc, _ in results)
    assert codes == [0, 2], results
    loser = next(err for rc, err in results if rc == 2)
    assert loser.startswith("error: ")
    assert "Traceback" not in loser
    assert json.loads((out / "run.json").read_text())["seed"] in (1, 2)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["job.yaml", "out"]


def test_sigterm_cleans_up(tmp_path: Path) -> None:
    proc = _start_slow_run(tmp_path / "out")
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=30) == 130
    assert list(tmp_path.iterdir()) == []


def test_misbehaving_sensor_is_reported(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, no_plot: None
) -> None:
    class Backwards(Imu):
        def messages(self, ctx: Context) -> Iterator[Message]:  # type: ignore[override]
            msgs = list(super().messages(ctx))
            yield msgs[5]
            yield msgs[2]

    monkeypatch.setattr("roslan.pipeline.plan.sensor_class", lambda name: Backwards)
    with pytest.raises(SensorError, match="time-ordered"):
        run_simulation(short_config(), tmp_path / "out", quiet=True)
    assert list(tmp_path.iterdir()) == []


def test_context_rng_streams() -> None:
    from roslan.trajectory import TauTrajectory, TrajectoryConfig

    traj = TauTrajectory(TrajectoryConfig.model_validate(SHORT_TRAJECTORY))
    a = Context(traj, Path("/nonexistent"), seed=1)
    b = Context(traj, Path("/nonexistent"), seed=1)
    assert a.rng("imu").random() == b.rng("imu").random()
    assert a.rng("imu").random() != a.rng("cam").random()
    assert Context(traj, Path("/x"), seed=2).rng("imu").random() != a.rng("imu").random()
    assert stream_key("imu") == stream_key("imu") != stream_key("imu2")
    with pytest.raises(ConfigError, match="needs a scene"):
        _ = a.scene
    with pytest.raises(ValueError, match="inside"):
        a.path("../escape.txt")


def test_cli_default_job_and_seed(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    no_plot: None,
) -> None:
    # the packaged default job, shortened: patch the loader to keep the test fast
    import roslan.cli.simulate as pcli

    cfg, path = pcli.load_config(None)
    assert path is None
    assert any(s.type == "imu" for s in cfg.sensors)
    monkeypatch.setattr(
        pcli,
        "load_config",
        lambda p: (cfg.model_copy(update={"trajectory": short_config().trajectory}), None),
    )
    assert (
        main(
            ["simulate", "-o", str(tmp_path / "o"), "--seed", "7", "--format", "ros2", "--profile"]
        )
        == 0
    )
    captured = capsys.readouterr()
    assert "wrote" in captured.out
    assert "ground_truth" in captured.err  # the profile table
    run = json.loads((tmp_path / "o" / "run.json").read_text())
    assert run["seed"] == 7
    assert run["formats"] == ["ros2"]
    timing = json.loads((tmp_path / "o" / "timing.json").read_text())
    assert set(timing["profile"]["sensors"]) >= {"ground_truth", "imu"}


def test_two_imus_get_separate_files(tmp_path: Path, no_plot: None) -> None:
    imu = {"type": "imu", "name": "imu", "rate": 100, "topic": "/imu"}
    cfg = short_config(
        sensors=[imu, {**imu, "name": "imu2", "topic": "/imu2", "pose": {"position": [0, 0.1, 0]}}]
    )
    run_simulation(cfg, tmp_path / "o", quiet=True)
    assert (tmp_path / "o" / "imu.txt").is_file()
    assert (tmp_path / "o" / "imu_imu2.txt").is_file()
    assert (tmp_path / "o" / "calib" / "imu_imu2.yaml").is_file()
    assert isinstance(ImuConfig.model_validate(imu), ImuConfig)


def test_plot_rendered_in_process_when_threads_run(tmp_path: Path) -> None:
    """With another Python thread alive the plot is not forked but still written."""
    import threading

    stop = threading.Event()
    th = threading.Thread(target=stop.wait)
    th.start()
    try:
        run_simulation(short_config(), tmp_path / "o", quiet=True, formats=["ros2"])
    finally:
        stop.set()
        th.join()
    assert (tmp_path / "o" / "trajectory.png").stat().st_size > 1000
    assert not (tmp_path / "o" / ".plot").exists()


def test_final_rename_never_replaces_an_outdir_that_appeared(tmp_path: Path) -> None:
    """Without overwrite, an OUTDIR created by someone else during the run is kept and the
    finished run is not moved over it; with overwrite it is replaced."""
    from roslan.rundir.folder import finalize

    tmp = tmp_path / ".out.partial-abc"
    tmp.mkdir()
    (tmp / "run.json").write_text("{}")
    outdir = tmp_path / "out"
    outdir.mkdir()  # appeared "meanwhile" (even empty: rename(2) would replace it)
    with pytest.raises(OutputError, match="appeared while this run was writing"):
        finalize(tmp, outdir, overwrite=False)
    assert outdir.is_dir()
    assert list(outdir.iterdir()) == []
    assert (tmp / "run.json").exists()
    finalize(tmp, outdir, overwrite=True)
    assert (outdir / "run.json").exists()
    assert not tmp.exists()
