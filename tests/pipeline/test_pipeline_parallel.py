"""Sensor worker processes: byte-identical outputs whatever the number of workers, errors and
crashes in a child surface cleanly in the parent, no orphan processes, bounded queues."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import psutil  # type: ignore[import-untyped]
import pytest

from pipeline_helpers import SHORT_TRAJECTORY, short_config, tree_bytes
from roslan.cli import main
from roslan.config.base import load_yaml_model
from roslan.config.sim import SimConfig
from roslan.errors import ConfigError, SensorError
from roslan.io.child import ChildError
from roslan.pipeline import run_simulation
from roslan.pipeline import worker as worker_mod
from roslan.pipeline.worker import ByteQueue, WorkerError, plan_workers, resolve_workers
from roslan.sensors.base import Message
from roslan.sensors.cameras import Camera, EventCamera
from roslan.sensors.registry import SENSOR_TYPES, sensor_class

HERE = Path(__file__).parent

TINY_SENSORS: list[dict[str, Any]] = [
    {"type": "imu", "name": "imu", "rate": 200.0, "topic": "/imu"},
    {"type": "event_camera", "name": "dvs", "rate": 20.0, "topic": "/dvs",
     "resolution": [48, 36], "max_rate": 150.0},
    {"type": "camera", "name": "cam", "rate": 20.0, "topic": "/cam", "resolution": [48, 36]},
]  # fmt: skip


def tiny_config(**kw: Any) -> SimConfig:
    """1.2 s landing over the empty scene: IMU, a 48x36 event camera and camera."""
    return short_config(scene="empty", sensors=TINY_SENSORS, **kw)


_BEFORE: set[int] = set()


@pytest.fixture(autouse=True)
def _children_before() -> None:
    """Processes this test process already had (e.g. a multiprocessing resource tracker
    started by an earlier test on the same xdist worker) are not this test's orphans."""
    _BEFORE.clear()
    _BEFORE.update(p.pid for p in psutil.Process().children(recursive=True))


def _children() -> list[psutil.Process]:
    """Live child processes started since the test began."""
    kids = psutil.Process().children(recursive=True)
    return [p for p in kids if p.pid not in _BEFORE and p.status() != "zombie"]


def _runs(p: psutil.Process, module: str) -> bool:
    """Whether process ``p`` is a child interpreter running roslan module ``module``."""
    try:
        return f"roslan.{module}" in " ".join(p.cmdline())
    except psutil.Error:  # a finished (zombie) helper such as the background plot
        return False


def _is_worker(p: psutil.Process) -> bool:
    return _runs(p, "pipeline.worker")


def _is_helper(p: psutil.Process) -> bool:
    return _runs(p, "sensors.cameras.event_chains")


# ------------------------------------------------------------------ failing sensors (in a child)
class ErrorCamera(Camera):
    """Raises a SensorError (a RoslanError) after a few messages."""

    def messages(self, ctx: Any) -> Iterator[Message]:
        for i, m in enumerate(super().messages(ctx)):
            if i == 3:
                raise SensorError("lens fell off at frame 3")
            yield m


class BoomCamera(Camera):
    """Raises a plain bug (RuntimeError) after a few messages."""

    def messages(self, ctx: Any) -> Iterator[Message]:
        for i, m in enumerate(super().messages(ctx)):
            if i == 3:
                raise RuntimeError("boom in the child")
            yield m


class KilledCamera(Camera):
    """Its process is SIGKILLed mid-stream (a crash, the OOM killer)."""

    def messages(self, ctx: Any) -> Iterator[Message]:
        for i, m in enumerate(super().messages(ctx)):
            if i == 3:
                os.kill(os.getpid(), signal.SIGKILL)
            yield m


class SlowCamera(Camera):
    """Writes its pid to $ROSLAN_TEST_PIDFILE, then hangs (to be interrupted)."""

    def messages(self, ctx: Any) -> Iterator[Message]:
        for i, m in enumerate(super().messages(ctx)):
            if i == 3:
                Path(os.environ["ROSLAN_TEST_PIDFILE"]).write_text(str(os.getpid()))
                time.sleep(120)
            yield m


def _patch_camera(monkeypatch: pytest.MonkeyPatch, cls: type) -> None:
    real = sensor_class
    monkeypatch.setattr(
        "roslan.pipeline.plan.sensor_class", lambda name: cls if name == "camera" else real(name)
    )


# ------------------------------------------------------------------ identical outputs
def test_workers_give_byte_identical_outputs(tmp_path: Path) -> None:
    cfg = tiny_config()
    outs = {}
    # in-process; both render sensors in one child; one child each; and two render helpers
    for w in (0, 1, 2, 4):
        outs[w] = tmp_path / f"w{w}"
        run_simulation(cfg, outs[w], quiet=True, workers=w, profile=True, overview=False)
    ref = tree_bytes(outs[0])
    assert "events.txt" in ref
    assert "images.txt" in ref
    assert "landing.bag" in ref
    for w in (1, 2, 4):
        got = tree_bytes(outs[w])
        assert got.keys() == ref.keys()
        assert [k for k in ref if got[k] != ref[k]] == []
        timing = json.loads((outs[w] / "timing.json").read_text())
        assert timing["workers"] == min(w, 2)
        assert timing["render_helpers"] == ({"dvs": 2} if w == 4 else {})
        assert sorted(n for g in timing["worker_sensors"] for n in g) == ["cam", "dvs"]
        per = timing["profile"]["sensors"]
        # child-side figures, reported under every sensor's name, in config order
        assert list(per) == ["ground_truth", "imu", "dvs", "cam"]
        assert per["dvs"]["messages"] > 0
        assert per["dvs"]["generator_s"] > 0
        assert per["dvs"]["worker_pid"] != os.getpid()
        # the event camera's own counters: every instant of its chains became a frame
        st = per["dvs"]["stats"]
        assert st["frames"] >= st["chains"] > 1
        assert 0 <= st["chains_rendered_here"] <= st["chains"]
        # with two workers the camera's runs below the event camera's priority
        base = os.nice(0)
        assert per["dvs"]["worker_nice"] == base
        light = min(19, base + worker_mod.LIGHT_NICE)  # Linux caps nice at 19
        assert per["cam"]["worker_nice"] == (light if w >= 2 else base)
        assert "worker_pid" not in per["imu"]
    run0 = json.loads((outs[0] / "timing.json").read_text())
    assert run0["workers"] == 0
    # run.json (deterministic) records the config, not how this run was parallelized
    assert (outs[0] / "run.json").read_bytes() == (outs[2] / "run.json").read_bytes()
    assert _children() == []


EVERY_SENSOR: list[dict[str, Any]] = [
    {"type": "imu", "name": "imu", "rate": 200.0, "topic": "/imu"},
    {"type": "event_camera", "name": "dvs", "rate": 20.0, "topic": "/dvs",
     "resolution": [40, 30], "max_rate": 120.0, "pose": {"rpy": [0.0, 0.6, 0.0]}},
    {"type": "camera", "name": "cam", "rate": 10.0, "topic": "/cam", "resolution": [40, 30],
     "pose": {"rpy": [0.0, 0.6, 0.0]}},
    {"type": "depth_camera", "name": "depth", "rate": 10.0, "topic": "/depth",
     "resolution": [32, 24], "pose": {"rpy": [0.0, 0.6, 0.0]}},
    {"type": "stereo_camera", "name": "pair", "rate": 5.0, "topic": "/pair",
     "resolution": [32, 24], "fx": 20.0, "baseline": 0.1, "pose": {"rpy": [0.0, 0.6, 0.0]}},
    {"type": "lidar", "name": "velo", "rate": 10.0, "topic": "/velo", "preset": "vlp16"},
    {"type": "solid_state_lidar", "name": "livox", "rate": 10.0, "topic": "/livox"},
    {"type": "laser", "name": "scan", "rate": 20.0, "topic": "/scan"},
    {"type": "sonar", "name": "son", "rate": 20.0, "topic": "/son"},
    {"type": "altimeter", "name": "alt", "rate": 20.0, "topic": "/alt"},
]  # fmt: skip


def test_every_sensor_type_identical_for_workers_0_to_3(tmp_path: Path) -> None:
    """A job with every sensor type: every output byte is the same in one process, with one,
    two or three worker processes (only timing.json and PLAYBACK.md report the run)."""
    assert {s["type"] for s in EVERY_SENSOR} == set(SENSOR_TYPES)  # a new type joins here
    cfg = short_config(scene="empty", sensors=EVERY_SENSOR)
    outs = {w: tmp_path / f"w{w}" for w in (0, 1, 2, 3)}
    for w, out in outs.items():
        run_simulation(cfg, out, quiet=True, workers=w, overview=False)
    ref = tree_bytes(outs[0])
    assert {"landing.bag", "events.h5", "depth_depth.txt"} <= set(ref)
    assert any(k.startswith("lidar/livox/") for k in ref)
    for w in (1, 2, 3):
        got = tree_bytes(outs[w])
        assert got.keys() == ref.keys()
        assert [k for k in ref if got[k] != ref[k]] == []
        assert json.loads((outs[w] / "timing.json").read_text())["workers"] == w
    assert _children() == []


def test_resolve_and_plan_workers(monkeypatch: pytest.MonkeyPatch) -> None:
    cfg = SimConfig.model_validate(
        {
            "sensors": [
                {"type": "imu", "name": "imu", "rate": 100, "topic": "/imu"},
                {"type": "camera", "name": "c1", "rate": 10, "topic": "/c1"},
                {"type": "event_camera", "name": "dvs", "rate": 10, "topic": "/dvs"},
                {"type": "lidar", "name": "lid", "rate": 10, "topic": "/lid"},
                {"type": "sonar", "name": "son", "rate": 10, "topic": "/son"},
            ]
        }
    )
    s = cfg.sensors
    H = worker_mod.MAX_RENDER_HELPERS
    monkeypatch.setattr(worker_mod, "usable_cpus", lambda: 2)
    assert resolve_workers("auto", s) == 2
    assert resolve_workers(0, s) == 0
    # the render-heavy sensors, then render helpers of the event camera
    assert resolve_workers(8, s) == 8
    assert resolve_workers(100, s) == 3 + H
    no_chains = [c.model_copy(update={"sampling": "brightness"}) if c.type == "event_camera"
                 else c for c in s]  # fmt: skip
    assert resolve_workers(8, no_chains) == 3  # never more than the render-heavy sensors
    monkeypatch.setattr(worker_mod, "usable_cpus", lambda: 1)
    assert resolve_workers("auto", s) == 0  # one CPU: nothing to overlap with
    monkeypatch.setattr(worker_mod, "usable_cpus", lambda: 6)
    assert resolve_workers("auto", s) == 3  # renders keep 6 CPUs busy: no helper
    monkeypatch.setattr(worker_mod, "usable_cpus", lambda: 16)
    assert resolve_workers("auto", s) == 3 + 5  # helpers up to half the CPUs in all
    assert resolve_workers("auto", no_chains) == 3
    monkeypatch.setattr(worker_mod, "usable_cpus", lambda: 64)
    assert resolve_workers("auto", s) == 3 + H
    assert resolve_workers("auto", s[:1]) == 0  # no render-heavy sensor
    # the processes beyond one per render-heavy sensor go to the event cameras in turn
    assert worker_mod.plan_helpers(s, 3) == {}
    assert worker_mod.plan_helpers(s, 5) == {"dvs": 2}
    assert worker_mod.plan_helpers(s, 100) == {"dvs": H}
    assert worker_mod.plan_helpers(no_chains, 8) == {}
    two = [*s, s[2].model_copy(update={"name": "dvs2", "topic": "/dvs2"})]
    assert worker_mod.plan_helpers(two, 4 + 3) == {"dvs": 2, "dvs2": 1}
    # inside a multiprocessing worker (roslan dataset's Dask workers): already parallel
    monkeypatch.setattr("multiprocessing.parent_process", lambda: object())
    assert resolve_workers("auto", s) == 0
    assert resolve_workers(2, s) == 2  # an explicit count is obeyed
    for bad in (-1, "many", True):
        with pytest.raises(ConfigError, match="workers"):
            resolve_workers(bad, s)
    # longest first onto the least loaded: event camera alone, camera + lidar together
    assert plan_workers(s, 2) == [[1, 3], [2]]
    assert plan_workers(s, 1) == [[1, 2, 3]]
    assert plan_workers(s, 3) == [[1], [2], [3]]
    assert plan_workers(s, 0) == []
    # only the costliest group (the event camera) keeps its priority
    L = worker_mod.LIGHT_NICE
    assert L > 0
    assert worker_mod.worker_nice([[1, 3], [2]], s) == [L, 0]
    assert worker_mod.worker_nice([[1], [2], [3]], s) == [L, 0, L]
    assert worker_mod.worker_nice([[1, 2, 3]], s) == [0]
    assert worker_mod.worker_nice([], s) == []
    groups = plan_workers(s, 3)
    assert sorted(i for g in groups for i in g) == [i for i, c in enumerate(s) if c.type != "imu"
                                                    and c.type != "sonar"]  # fmt: skip


def test_workers_config_and_cli_validation(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    f = tmp_path / "job.yaml"
    f.write_text("output:\n  workers: -2\n")
    with pytest.raises(ConfigError, match=r"output\.workers"):
        load_yaml_model(SimConfig, f)
    f.write_text("output:\n  workers: 3\n")
    assert load_yaml_model(SimConfig, f).output.workers == 3
    assert SimConfig().output.workers == "auto"
    with pytest.raises(SystemExit):
        main(["simulate", "-o", str(tmp_path / "o"), "--workers", "lots"])
    assert "--workers" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------------------ errors in a child
def test_sensor_error_in_child_is_reraised(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _patch_camera(monkeypatch, ErrorCamera)
    with pytest.raises(SensorError, match="lens fell off at frame 3") as info:
        run_simulation(tiny_config(), tmp_path / "out", quiet=True, workers=2, overview=False)
    assert "test_pipeline_parallel.py" in str(info.value.__cause__)  # the child's traceback
    assert list(tmp_path.iterdir()) == []  # no OUTDIR, no .partial folder
    assert _children() == []
    # the CLI prints the message, no traceback
    monkeypatch.setattr("roslan.cli.simulate.load_config", lambda p: (tiny_config(), None))
    code = main(["simulate", "-o", str(tmp_path / "cli"), "--quiet", "--workers", "1"])
    assert code == 2
    assert list(tmp_path.iterdir()) == []


def test_failed_run_stops_the_event_cameras_file_thread(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # in one process, another sensor fails while the event camera's background thread
    # still has queued writes: they must not land (or recreate folders) after the
    # temporary OUTDIR is removed
    import threading

    from roslan.sensors.cameras import EventCamera

    real_write = EventCamera._write_events

    def slow_write(self: EventCamera, batch: Any, labels: Any = None) -> None:
        time.sleep(0.05)
        real_write(self, batch, labels)

    monkeypatch.setattr(EventCamera, "_write_events", slow_write)
    _patch_camera(monkeypatch, ErrorCamera)
    with pytest.raises(SensorError, match="lens fell off at frame 3"):
        run_simulation(tiny_config(), tmp_path / "out", quiet=True, workers=0, overview=False)
    assert not [t for t in threading.enumerate() if t.name.endswith("-files")]
    time.sleep(0.3)  # a write that escaped would show up now
    assert list(tmp_path.iterdir()) == []


def test_bug_in_child_keeps_type_and_traceback(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _patch_camera(monkeypatch, BoomCamera)
    with pytest.raises(RuntimeError, match="boom in the child") as info:
        run_simulation(tiny_config(), tmp_path / "out", quiet=True, workers=1, overview=False)
    tb = str(info.value.__cause__)
    assert "in the worker process" in tb
    assert "Traceback" in tb
    assert 'raise RuntimeError("boom in the child")' in tb
    assert list(tmp_path.iterdir()) == []
    assert _children() == []


def test_killed_child_fails_the_run_cleanly(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _patch_camera(monkeypatch, KilledCamera)
    t0 = time.perf_counter()
    with pytest.raises(WorkerError, match=r"running cam was killed by signal 9"):
        run_simulation(tiny_config(), tmp_path / "out", quiet=True, workers=2, overview=False)
    assert time.perf_counter() - t0 < 60  # no hang
    assert list(tmp_path.iterdir()) == []
    assert _children() == []


def test_killed_render_helper_fails_the_run_cleanly(tmp_path: Path) -> None:
    """A render helper of the event camera (a grandchild: the camera runs in a worker)
    killed mid-run: the run fails with an error naming it, leaves no OUTDIR and no
    process behind."""
    import threading

    killed: list[int] = []
    stop = threading.Event()

    def assassin() -> None:
        while not stop.is_set() and not killed:
            for p in _children():
                if _is_helper(p):
                    with contextlib.suppress(psutil.Error):
                        p.kill()
                        killed.append(p.pid)
                        return
            time.sleep(0.005)

    watcher = threading.Thread(target=assassin, daemon=True)
    watcher.start()
    try:
        with pytest.raises(ChildError, match=r"render helper \d \(pid \d+\) of event camera dvs"):
            run_simulation(tiny_config(), tmp_path / "out", quiet=True, workers=4, overview=False)
    finally:
        stop.set()
        watcher.join()
    assert killed
    assert list(tmp_path.iterdir()) == []
    assert _children() == []


@pytest.mark.parametrize("workers", [0, 2])
def test_bag_writer_failure_leaves_no_outdir(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, workers: int
) -> None:
    """A bag writer failing on its own thread (disk full while writing an MCAP chunk) fails
    the run with that error: no OUTDIR, no partial folder, no worker left behind."""
    from roslan.io import bag

    seen: list[int] = []

    def full(self: Any, chunk: Any, compressed: bytes) -> None:
        seen.append(len(compressed))
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(bag._FastMcapWriter, "_write_out", full)
    with pytest.raises(OSError, match="No space left on device"):
        run_simulation(tiny_config(), tmp_path / "out", quiet=True, workers=workers, overview=False)
    assert len(seen) == 1
    assert list(tmp_path.iterdir()) == []
    assert _children() == []


def _patched_run(
    out: Path, sensor_type: str, cls: str, workers: int, env: dict[str, str]
) -> subprocess.Popen[bytes]:
    """A child interpreter running :func:`tiny_config` into ``out`` with ``workers``, the
    sensors of ``sensor_type`` replaced by this module's class ``cls``; it exits 130 on
    SIGTERM (the run's KeyboardInterrupt)."""
    script = textwrap.dedent(
        f"""
        import sys
        sys.path[:0] = [{str(HERE)!r}, {str(HERE.parent / "helpers")!r}]
        from pathlib import Path
        import roslan.pipeline.plan as plan
        from roslan.pipeline import run_simulation
        from roslan.sensors.registry import sensor_class
        from test_pipeline_parallel import {cls}, tiny_config
        plan.sensor_class = lambda n: {cls} if n == {sensor_type!r} else sensor_class(n)
        try:
            run_simulation(tiny_config(), Path(sys.argv[1]), quiet=True, workers={workers},
                           overview=False)
        except KeyboardInterrupt:
            sys.exit(130)
        """
    )
    return subprocess.Popen([sys.executable, "-c", script, str(out)], env=env)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_stopping_the_parent_stops_the_children(tmp_path: Path, sig: signal.Signals) -> None:
    """SIGTERM: the parent terminates its children and removes its partial folder; SIGKILL:
    the children die with it (no orphans either way)."""
    pidfile = tmp_path / "pid"
    out = tmp_path / "runs"
    out.mkdir()
    env = {**os.environ, "ROSLAN_TEST_PIDFILE": str(pidfile)}
    proc = _patched_run(out / "o", "camera", "SlowCamera", 2, env)
    deadline = time.monotonic() + 60
    while not pidfile.exists() or not pidfile.read_text():
        assert proc.poll() is None, "the run ended before the slow camera started"
        assert time.monotonic() < deadline
        time.sleep(0.05)
    child = psutil.Process(int(pidfile.read_text()))
    workers = [p for p in psutil.Process(proc.pid).children() if _is_worker(p)]
    assert child.pid in {p.pid for p in workers}
    assert len(workers) == 2
    proc.send_signal(sig)
    code = proc.wait(timeout=30)
    _gone, alive = psutil.wait_procs(workers, timeout=15)
    assert [p for p in alive if p.status() != "zombie"] == []
    if sig == signal.SIGTERM:
        assert code == 130
        assert list(out.iterdir()) == []
    else:
        assert not (out / "o").exists()


class HangingEventCamera(EventCamera):
    """In a render helper (which imports this class by name), every render notes the
    helper's pid in $ROSLAN_TEST_PIDDIR, then hangs."""

    def render(self, ctx: Any, t_ns: int, *, need_depth: bool, **kw: Any) -> Any:
        if "event_chains" in " ".join(psutil.Process().cmdline()):
            (Path(os.environ["ROSLAN_TEST_PIDDIR"]) / str(os.getpid())).write_text("")
            time.sleep(120)
        return super().render(ctx, t_ns, need_depth=need_depth, **kw)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_stopping_the_parent_stops_the_render_helpers(tmp_path: Path, sig: signal.Signals) -> None:
    """The event camera's render helpers are grandchildren (the camera runs in a worker):
    stopping the run stops them too."""
    piddir = tmp_path / "pids"
    piddir.mkdir()
    out = tmp_path / "runs"
    out.mkdir()
    env = {**os.environ, "ROSLAN_TEST_PIDDIR": str(piddir)}
    proc = _patched_run(out / "o", "event_camera", "HangingEventCamera", 4, env)
    deadline = time.monotonic() + 90
    while len(list(piddir.iterdir())) < 2:  # both helpers render
        assert proc.poll() is None, "the run ended before the renders hung"
        assert time.monotonic() < deadline
        time.sleep(0.05)
    tree = psutil.Process(proc.pid).children(recursive=True)
    helpers = [p for p in tree if _is_helper(p)]
    assert len(helpers) == 2
    assert {p.pid for p in helpers} == {int(f.name) for f in piddir.iterdir()}
    proc.send_signal(sig)
    code = proc.wait(timeout=30)
    _gone, alive = psutil.wait_procs(tree, timeout=15)
    assert [p for p in alive if p.status() != "zombie"] == []
    if sig == signal.SIGTERM:
        assert code == 130
        assert list(out.iterdir()) == []


# ------------------------------------------------------------------ bounded queue
def test_byte_queue_is_bounded() -> None:
    q = ByteQueue(100)
    q.put(b"x" * 60)
    q.put(b"x" * 40)
    with pytest.raises(TimeoutError):
        q.put(b"y", timeout=0.05)  # full: a producer would wait here
    assert q.nbytes == 100
    assert q.get() == b"x" * 60
    with pytest.raises(TimeoutError):
        q.put(b"y" * 50, timeout=0.05)  # the blob being sent still counts
    q.sent()
    q.put(b"y" * 50)
    assert q.nbytes == 90
    assert q.get() == b"x" * 40
    q.sent()
    assert q.get() == b"y" * 50
    with pytest.raises(TimeoutError):
        q.put(b"z" * 500, timeout=0.05)  # too large beside the one being sent
    q.sent()
    q.put(b"z" * 500)  # one larger message passes when nothing waits or is being sent
    with pytest.raises(TimeoutError):
        q.put(b"w", timeout=0.05)
    assert q.get() == b"z" * 500
    q.sent()
    assert q.peak_bytes == 500
    q.put(None)
    assert q.get() is None
    q.fail(BrokenPipeError("reader gone"))
    with pytest.raises(BrokenPipeError):
        q.put(b"v")


def test_file_trajectory_in_worker_processes(tmp_path: Path) -> None:
    """A pose file (given relative to the config's folder) drives rendering sensors in
    worker processes exactly as in one process: the workers rebuild the same spline."""
    from roslan.trajectory import TauTrajectory
    from roslan.vehicle import base_link_trajectory

    # the poses of base_link, which lands above the goal on the vehicle's feet
    base = short_config(trajectory=SHORT_TRAJECTORY)
    tau = TauTrajectory(base_link_trajectory(base.trajectory, base.vehicle), warn=False)
    t = np.arange(0.0, tau.T, 0.01)
    st = tau.state(t)
    (tmp_path / "job").mkdir()
    np.savetxt(
        tmp_path / "job" / "flight.txt", np.column_stack([t, st.position, st.quat_xyzw]), "%.12f"
    )
    config = short_config(
        scene="empty", sensors=TINY_SENSORS, trajectory={"file": "flight.txt", "hold": 0.2}
    )
    outs = {}
    for w in (0, 2):
        outs[w] = tmp_path / f"w{w}"
        run_simulation(
            config, outs[w], quiet=True, overview=False, workers=w,
            config_path=tmp_path / "job" / "job.yaml",
        )  # fmt: skip
    ref, got = tree_bytes(outs[0]), tree_bytes(outs[2])
    assert got.keys() == ref.keys()
    assert [k for k in ref if got[k] != ref[k]] == []
    assert json.loads((outs[2] / "timing.json").read_text())["workers"] == 2
    summary = json.loads((outs[0] / "summary.json").read_text())
    assert summary["source"] == "file"
    assert (outs[0] / "events.txt").stat().st_size > 0
    assert len((outs[0] / "cam" / "images.txt").read_text().splitlines()) > 0
    assert _children() == []
