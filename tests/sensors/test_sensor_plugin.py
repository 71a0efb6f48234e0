"""Adding a sensor as docs/guide/architecture.md says: one module
(tests/example_barometer.py) plus one ``SensorSpec``. Nothing else in roslan changes: the
config schema, the pipeline, the bags, run.json and the dataset folder pick it up."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from example_barometer import SPEC, isa_pressure
from pipeline_helpers import SHORT_TRAJECTORY
from roslan.config.sim import SimConfig
from roslan.errors import ConfigError
from roslan.pipeline import run_simulation
from roslan.sensors import registry
from roslan.trajectory.spline import make_trajectory
from roslan.vehicle import base_link_trajectory


@pytest.fixture
def barometer_registered(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Register the example as one more SensorSpec (what a line in registry.py does)."""
    monkeypatch.setitem(registry.SENSOR_TYPES, SPEC.type, SPEC)
    registry.config_class.cache_clear()
    registry.sensor_class.cache_clear()
    yield
    registry.config_class.cache_clear()
    registry.sensor_class.cache_clear()


def _config(**sensor: object) -> SimConfig:
    return SimConfig.model_validate(
        {
            "trajectory": SHORT_TRAJECTORY,
            "sensors": [{"type": "barometer", "name": "baro", "rate": 25.0, **sensor}],
            "output": {"ground_truth_rate": 50.0},
        }
    )


def test_unregistered_type_is_refused_with_the_allowed_list() -> None:
    with pytest.raises(ValueError, match=r"unknown sensor type 'barometer'.*allowed: altimeter"):
        _config()


@pytest.mark.usefixtures("barometer_registered")
def test_example_sensor_runs_through_the_pipeline(tmp_path: Path) -> None:
    mount = [0.0, 0.0, 0.1]
    config = _config(noise_pa=0.0, pose={"position": mount})
    out = tmp_path / "out"
    run = run_simulation(config, out, quiet=True, overview=False)
    duration = 1.2  # SHORT_TRAJECTORY: touchdown 1.0 s + hold 0.2 s
    n = round(25.0 * duration) + 1  # 25 Hz, both ends included

    # run.json and the bags know the new topic, with its publisher
    assert run["topics"]["/baro"] == {
        "type": "sensor_msgs/msg/FluidPressure",
        "messages": n,
        "publisher": "baro",
    }
    traj = make_trajectory(base_link_trajectory(config.trajectory, config.vehicle))
    for bag in (out / "landing.bag", out / "landing_ros2"):
        with AnyReader([bag]) as reader:
            conns = [c for c in reader.connections if c.topic == "/baro"]
            msgs = [
                (stamp, reader.deserialize(raw, c.msgtype))
                for c, stamp, raw in reader.messages(connections=conns)
            ]
        t_ns = np.array([s for s, _ in msgs]) - config.output.start_time
        assert [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, m in msgs] == [
            s for s, _ in msgs
        ]
        # independent check: the mount's height from the closed-form state, ISA formula
        state = traj.state_ns(t_ns)
        z = state.position[:, 2] + state.R_world_body[:, 2, :] @ np.array(mount)
        got = np.array([m.fluid_pressure for _, m in msgs])
        np.testing.assert_allclose(got, isa_pressure(z), rtol=0, atol=1e-6)
        # descending: the pressure rises until touchdown
        assert got[-1] > got[0]
    table = np.loadtxt(out / "baro_baro.txt")
    assert table.shape == (n, 2)
    np.testing.assert_array_equal(np.rint(table[:, 0] * 1e9).astype(np.int64), t_ns)
    np.testing.assert_allclose(table[:, 1], got, atol=5e-4)


@pytest.mark.usefixtures("barometer_registered")
def test_example_sensor_keys_are_validated_like_any_other() -> None:
    with pytest.raises(ValueError, match="noise_pa"):
        _config(noise_pa="loud")
    with pytest.raises((ValueError, ConfigError), match="rate"):
        _config(rate=-1)
