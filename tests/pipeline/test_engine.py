"""The causal sensor engine: every sensor type runs on a trajectory that raises when read
past its horizon (HorizonGuard), stepped every 20 ms, and the steps' messages concatenated
are a one-shot run's messages, wire byte for wire byte; the clock's grids; taps."""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from roslan.io.messages import Flavor, MessageStore
from roslan.pipeline.context import Context
from roslan.pipeline.engine import SensorEngine
from roslan.rundir.extrinsics import static_transforms
from roslan.sensors.clock import Clock
from roslan.sensors.ground_truth import GroundTruth
from roslan.sensors.registry import SENSOR_TYPES, config_class, sensor_class
from roslan.trajectory import TauTrajectory, TrajectoryConfig
from roslan.trajectory.base import HorizonError, HorizonGuard, sample_times_ns
from roslan.vehicle import VehicleConfig, base_link_trajectory

TRAJ = {
    "k": 0.5,
    "initial": {"position": [-0.2, 0.1, 0.1], "rpy": [0.02, 0.05, 0.1], "descent_rate": 2.0},
    "hold": 0.05,
}
RATE = 20.0
START = 1_600_000_000_123_456_789
SEED = 5
STEP_NS = 20_000_000
STORES = {f: MessageStore(f) for f in Flavor}


def _scene() -> Any:
    return importlib.import_module("roslan.scene").load_scene("empty", seed=SEED)


def _traj() -> TauTrajectory:
    return TauTrajectory(
        base_link_trajectory(TrajectoryConfig.model_validate(TRAJ), VehicleConfig(), _scene())
    )


def _config(type_name: str) -> Any:
    data = {"type": type_name, "name": f"s_{type_name}", "rate": RATE, "topic": f"/s_{type_name}"}
    return config_class(type_name).model_validate(data)


def _engine(type_name: str, outdir: Path, traj: Any, clock: Clock) -> SensorEngine:
    cfg = _config(type_name)
    sensor = sensor_class(type_name)(cfg)
    ctx = Context(
        traj,
        outdir,
        seed=SEED,
        start_time_ns=START,
        sensors=[cfg],
        scene_spec="empty",
        scene=_scene(),
        clock=clock,
    )
    gt = GroundTruth(200.0, static_transforms([sensor]), scene=False)
    return SensorEngine(ctx, [sensor], gt)


def _wire(msgs: list[Any]) -> list[tuple[int, str, bytes, bytes]]:
    out = []
    for m in msgs:
        pair = []
        for f in Flavor:
            data = m.build(STORES[f])
            if not isinstance(data, (bytes, bytearray, np.ndarray)):
                data = STORES[f].serialize(data, m.msgtype)
            pair.append(bytes(data))
        out.append((m.t_ns, m.topic, pair[0], pair[1]))
    return out


@pytest.mark.parametrize("type_name", sorted(SENSOR_TYPES))
def test_every_sensor_type_is_causal_and_stepping_changes_no_byte(
    type_name: str, tmp_path: Path
) -> None:
    """Stepped every 20 ms on a HorizonGuard (a read past the step's end raises) with
    the same end as a one-shot run: the same messages in the same order, byte for byte."""
    traj = _traj()
    end = traj.duration_ns
    one = _engine(type_name, tmp_path / "one", traj, Clock.fixed(end))
    whole = one.finish(end)

    guard = HorizonGuard(traj)
    eng = _engine(type_name, tmp_path / "step", guard, Clock(0))
    eng.enable_taps()
    stepped = []
    taps = 0
    h = 0
    while h + STEP_NS < end:
        h += STEP_NS
        guard.set_horizon(h)
        out = eng.advance(h)
        assert all(m.t_ns <= h for m in out.messages)
        stepped += out.messages
        taps += len(out.tap(f"s_{type_name}"))
    guard.finish()
    last = eng.finish(end)
    stepped += last.messages
    taps += len(last.tap(f"s_{type_name}"))
    assert len(stepped) == len(whole.messages)
    assert _wire(stepped) == _wire(whole.messages)
    assert taps > 0


def test_horizon_guard_raises_past_its_horizon() -> None:
    guard = HorizonGuard(_traj(), horizon_ns=10_000_000)
    guard.state_ns(np.array([0, 10_000_000]))
    with pytest.raises(HorizonError, match="past its horizon"):
        guard.state_ns(np.array([10_000_001]))
    with pytest.raises(HorizonError, match="past its horizon"):
        guard.state(np.array([0.0105]))
    with pytest.raises(HorizonError, match="before the run's end"):
        _ = guard.duration_ns


def test_grid_reveals_a_prefix_of_the_final_instants() -> None:
    """Before the end, a grid hands out only instants every later end keeps, in chunks
    cut at the one-shot chunk boundaries; after it, exactly the one-shot array."""
    clock = Clock(0)
    rate, end = 30.0, 1_234_567_891
    grid = clock.grid(lambda e: sample_times_ns(rate, e))
    got: list[np.ndarray] = []
    for h in range(0, end, 7_000_000):
        clock.advance(h)
        while (item := grid.take(8)) is not None and item[1].size:
            i0, t = item
            assert (t <= h).all()
            assert i0 // 8 == (i0 + t.size - 1) // 8
            got.append(t)
    clock.end(end)
    while (item := grid.take(8)) is not None and item[1].size:
        got.append(item[1])
    assert np.array_equal(np.concatenate(got), sample_times_ns(rate, end))
