"""Frame and scan sensors on threads (ROSLAN_SENSOR_THREADS): the same files and bags
for any number of threads, errors of a pool thread surface with their message and leave
no OUTDIR, and the thread count follows the CPUs, the processes and the variable."""

from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pipeline_helpers import short_config, tree_bytes
from roslan.config.sim import SimConfig
from roslan.errors import ConfigError, OutputError
from roslan.pipeline import check_run, run_simulation
from roslan.pipeline import threads as threads_mod
from roslan.pipeline.threads import MAX_SENSOR_THREADS, SENSOR_THREADS_ENV, sensor_threads
from roslan.sensors.beams.base import ScanWriter

LENS = {"fx": 50.0, "distortion_model": "plumb_bob", "distortion_coeffs": [-0.15, 0.02, 0, 0, 0]}

SENSORS: list[dict[str, Any]] = [
    # distorted lens, rolling shutter with exposure (bands), shot + read noise, colour
    {"type": "camera", "name": "cam", "rate": 10.0, "topic": "/cam", "resolution": [64, 48],
     **LENS, "readout_time": 0.01, "exposure_time": 0.004, "exposure_samples": 3,
     "full_well": 2000.0, "noise_std": 0.01},
    # global shutter over two renders, auto-exposure, read noise, bgr8
    {"type": "camera", "name": "cam2", "rate": 10.0, "topic": "/cam2", "resolution": [48, 36],
     **LENS, "exposure_time": 0.004, "exposure_samples": 2, "noise_std": 0.02,
     "encoding": "bgr8", "auto_exposure": {"max_exposure": 0.01}},
    {"type": "stereo_camera", "name": "stereo", "rate": 10.0, "topic": "/stereo",
     "resolution": [48, 36], "full_well": 1000.0, "encoding": "mono8"},
    {"type": "depth_camera", "name": "depth", "rate": 10.0, "topic": "/depth",
     "resolution": [48, 36], **LENS, "noise_std": 0.01, "noise_quadratic": 0.002},
    {"type": "depth_camera", "name": "depth2", "rate": 10.0, "topic": "/depth2",
     "resolution": [48, 36], "readout_time": 0.01, "readout_samples": 3, "noise_std": 0.01},
    {"type": "lidar", "name": "velodyne", "rate": 10.0, "preset": "vlp16", "dropout": 0.1},
    {"type": "solid_state_lidar", "name": "livox", "rate": 10.0, "point_rate": 20000.0},
]  # fmt: skip


def _config() -> SimConfig:
    return short_config(scene="empty", sensors=SENSORS)


def _run(out: Path, monkeypatch: pytest.MonkeyPatch, threads: int, **kw: Any) -> dict[str, bytes]:
    monkeypatch.setenv(SENSOR_THREADS_ENV, str(threads))
    run_simulation(_config(), out, quiet=True, overview=False, **kw)
    assert json.loads((out / "timing.json").read_text())["sensor_threads"] == threads
    return tree_bytes(out)


def test_outputs_are_identical_for_any_number_of_threads(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every file (PNGs, .npz scans, index files, both bags with every message) of a job
    with each frame/scan sensor type: 1 thread (all inline) = 3 threads in each of 2
    worker processes (rolling-shutter renders composed on the pool) = 3 threads in this
    process with the rolling-shutter renders composed on the sensor's thread (more rows
    than RAW_ROWS_FACTOR allows)."""
    ref = _run(tmp_path / "t1", monkeypatch, 1, workers=0)
    for name in ("images/00000009.png", "cam2/images/00000009.png", "depth/depth/00000009.png",
                 "depth/depth2/00000009.png", "stereo_right/images/00000009.png",
                 "lidar/velodyne/000009.npz", "lidar/livox/000009.npz", "landing.bag"):  # fmt: skip
        assert name in ref
    scan = np.load(tmp_path / "t1" / "lidar/velodyne/000003.npz")
    assert scan["x"].size > 1000  # a real scan of the ground
    got = _run(tmp_path / "t3w2", monkeypatch, 3, workers=2)
    assert got.keys() == ref.keys()
    assert [k for k in ref if got[k] != ref[k]] == []
    # (this process only: the workers import their own; the depth camera's readout forms
    # its rows from its band renders itself, sensors/cameras/depth_readout.py)
    monkeypatch.setattr("roslan.sensors.cameras.frame.RAW_ROWS_FACTOR", 0)
    got = _run(tmp_path / "t3", monkeypatch, 3, workers=0)
    assert got.keys() == ref.keys()
    assert [k for k in ref if got[k] != ref[k]] == []


@pytest.mark.parametrize("where", ["camera", "lidar"])
def test_an_error_on_a_pool_thread_surfaces_with_its_message(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, where: str
) -> None:
    """A PNG or scan file that cannot be written on a pool thread: the run raises that
    OutputError (same type and message) and leaves neither OUTDIR nor a partial folder."""
    threads: list[str] = []
    if where == "camera":
        import roslan.sensors.cameras.common as common

        real_png = common.write_png

        def failing_png(path: Path, image: Any) -> None:
            if path.name == "00000004.png":
                threads.append(threading.current_thread().name)
                msg = f"{path}: cannot write image: disk full"
                raise OutputError(msg)
            real_png(path, image)

        monkeypatch.setattr(common, "write_png", failing_png)
        match = r"00000004\.png: cannot write image: disk full$"
    else:
        real_file = ScanWriter.write_file

        def failing_file(self: ScanWriter, count: int, t_ns: int, points: Any) -> None:
            if count == 4:
                threads.append(threading.current_thread().name)
                msg = f"lidar/velodyne/{count:06d}.npz: disk full"
                raise OutputError(msg)
            real_file(self, count, t_ns, points)

        monkeypatch.setattr(ScanWriter, "write_file", failing_file)
        match = r"^lidar/velodyne/000004\.npz: disk full$"
    monkeypatch.setenv(SENSOR_THREADS_ENV, "3")
    out = tmp_path / "out"
    cfg = short_config(scene="empty", sensors=[SENSORS[0], SENSORS[5]])
    with pytest.raises(OutputError, match=match):
        run_simulation(cfg, out, quiet=True, overview=False, workers=0)
    assert threads[0] != threading.current_thread().name  # raised on a pool thread
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir()] == []  # no hidden partial folder either


def test_thread_count_follows_cpus_processes_and_the_variable(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.delenv(SENSOR_THREADS_ENV, raising=False)
    monkeypatch.setattr(threads_mod, "usable_cpus", lambda: 2)
    assert sensor_threads(1) == 1  # --workers 0 on two cores: inline, as before
    assert sensor_threads(3) == 1  # two workers and the main process: inline, as before
    monkeypatch.setattr(threads_mod, "usable_cpus", lambda: 16)
    assert sensor_threads(4) == 3  # three workers and the main process: 16 // 5
    assert sensor_threads(7) == 2
    assert sensor_threads(1) == MAX_SENSOR_THREADS
    monkeypatch.setattr(threads_mod, "usable_cpus", lambda: 1)
    assert sensor_threads(1) == 1
    monkeypatch.setenv(SENSOR_THREADS_ENV, "6")
    assert sensor_threads(3) == 6
    for bad in ("0", "-2", "two", "1.5", "999"):
        monkeypatch.setenv(SENSOR_THREADS_ENV, bad)
        with pytest.raises(ConfigError, match=rf"{SENSOR_THREADS_ENV} = '{bad}': allowed an"):
            sensor_threads(1)


def test_a_bad_variable_is_refused_before_anything_is_written(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(SENSOR_THREADS_ENV, "many")
    out = tmp_path / "out"
    with pytest.raises(ConfigError, match="ROSLAN_SENSOR_THREADS = 'many'"):
        check_run(short_config(), out)
    with pytest.raises(ConfigError, match="ROSLAN_SENSOR_THREADS = 'many'"):
        run_simulation(short_config(), out, quiet=True)
    assert list(tmp_path.iterdir()) == []


def test_render_helpers_leave_the_sensor_threads_as_they_were(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The default job on 16 CPUs: three sensor workers, five render helpers of the event
    camera (processes within half the CPUs), and 3 threads for each frame/scan sensor, as
    without helpers (16 // (3 workers + main + 1))."""
    from roslan.cli.simulate import load_config
    from roslan.pipeline import worker as worker_mod
    from roslan.pipeline.plan import make_plan

    monkeypatch.delenv(SENSOR_THREADS_ENV, raising=False)
    monkeypatch.setattr(threads_mod, "usable_cpus", lambda: 16)
    monkeypatch.setattr(worker_mod, "usable_cpus", lambda: 16)
    cfg, _ = load_config(None)
    plan = make_plan(cfg, tmp_path / "out", workers="auto")
    dvs = next(s.name for s in cfg.sensors if s.type == "event_camera")
    assert len(plan.groups) == 3
    assert plan.render_helpers == {dvs: 5}
    assert plan.sensor_threads == 3
    plan = make_plan(cfg, tmp_path / "out", workers=3)
    assert (plan.render_helpers, plan.sensor_threads) == ({}, 3)
