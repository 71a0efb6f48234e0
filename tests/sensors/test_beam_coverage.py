"""Every beam a scanning sensor fires lies within the trajectory, so within the ground-truth
record (which samples [0, duration] inclusive): a scan that would run past the end is not
produced."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from range_helpers import FakeContext, LinearTrajectory, plane, run_sensor, scene
from roslan.config.base import validate_model
from roslan.io.messages import Flavor, MessageStore
from roslan.sensors.beams import (
    Laser,
    LaserConfig,
    Lidar,
    LidarConfig,
    SolidStateLidar,
    SolidStateLidarConfig,
)

DURATION = 0.33  # s: not a multiple of any scan period below


def _last_beam_times(tmp_path: Path, sensor: object, name: str) -> tuple[int, float]:
    """(scans, latest firing instant in s) from the sensor's dataset files."""
    ctx = FakeContext(scene(plane()), LinearTrajectory((0.0, 0.0, 1.0), duration=DURATION),
                      tmp_path)  # fmt: skip
    run_sensor(sensor, ctx)
    files = sorted((tmp_path / "lidar" / name).glob("*.npz"))
    latest = 0.0
    for f in files:
        with np.load(f) as z:
            latest = max(latest, int(z["stamp"]) * 1e-9 + float(z["time"].max()))
    return len(files), latest


@pytest.mark.parametrize("rate", [10.0, 20.0])
def test_spinning_lidar_fires_within_the_trajectory(tmp_path: Path, rate: float) -> None:
    cfg = validate_model(LidarConfig, {"type": "lidar", "name": "velo", "preset": "vlp16",
                                       "rate": rate}, "sim.yaml")  # fmt: skip
    n, latest = _last_beam_times(tmp_path, Lidar(cfg), "velo")
    assert n == int(np.floor((DURATION - 1 / rate) * rate + 1e-9)) + 1
    assert latest <= DURATION
    assert latest > DURATION - 2 / rate  # the last whole scan is kept


def test_solid_state_lidar_fires_within_the_trajectory(tmp_path: Path) -> None:
    cfg = validate_model(SolidStateLidarConfig, {"type": "solid_state_lidar", "name": "livox",
                                                 "rate": 10.0}, "sim.yaml")  # fmt: skip
    n, latest = _last_beam_times(tmp_path, SolidStateLidar(cfg), "livox")
    assert n == 3  # scans at 0, 0.1, 0.2 s; one at 0.3 s would fire until 0.4 s
    assert latest <= DURATION


def test_laser_scans_end_within_the_trajectory(tmp_path: Path) -> None:
    cfg = validate_model(LaserConfig, {"type": "laser", "name": "scan", "rate": 40.0},
                         "sim.yaml")  # fmt: skip
    ctx = FakeContext(scene(plane()), LinearTrajectory((0.0, 0.0, 1.0), duration=DURATION),
                      tmp_path)  # fmt: skip
    msgs = run_sensor(Laser(cfg), ctx)
    store = MessageStore(Flavor.ROS1)
    assert len(msgs) == int(np.floor((DURATION - 1 / cfg.rate) * cfg.rate + 1e-9)) + 1
    for m in msgs:
        scan = m.build(store)
        last_beam = m.t_ns * 1e-9 + (len(scan.ranges) - 1) * scan.time_increment
        assert last_beam <= DURATION
        assert m.t_ns * 1e-9 + scan.scan_time <= DURATION + 1e-9
