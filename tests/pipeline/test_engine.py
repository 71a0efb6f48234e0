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


def _config(type_name: str, **extra: Any) -> Any:
    data = {"type": type_name, "name": f"s_{type_name}", "rate": RATE, "topic": f"/s_{type_name}"}
    return config_class(type_name).model_validate({**data, **extra})


def _engine(type_name: str, outdir: Path, traj: Any, clock: Clock, **extra: Any) -> SensorEngine:
    cfg = _config(type_name, **extra)
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


def _stepped(
    type_name: str, outdir: Path, traj: Any, clock: Clock, step: int = STEP_NS, **extra: Any
) -> tuple[list[Any], list[dict[str, Any]]]:
    """Every message and tap of a run stepped every ``step`` ns on a HorizonGuard; each
    step's messages and taps end at the step's end."""
    end = traj.duration_ns
    guard = HorizonGuard(traj)
    eng = _engine(type_name, outdir, guard, clock, **extra)
    eng.enable_taps()
    msgs: list[Any] = []
    taps: list[dict[str, Any]] = []
    h = 0
    while h + step < end:
        h += step
        guard.set_horizon(h)
        out = eng.advance(h)
        assert all(m.t_ns <= h for m in out.messages)
        step_taps = out.tap(f"s_{type_name}")
        assert all(np.all(np.asarray(tap["t"]) <= h) for tap in step_taps)
        msgs += out.messages
        taps += step_taps
    guard.finish()
    last = eng.finish(end)
    return msgs + last.messages, taps + last.tap(f"s_{type_name}")


@pytest.mark.parametrize("type_name", sorted(SENSOR_TYPES))
def test_every_sensor_type_is_causal_and_stepping_changes_no_byte(
    type_name: str, tmp_path: Path
) -> None:
    """Stepped every 20 ms on a HorizonGuard (a read past the step's end raises) with
    the same end as a one-shot run: the same messages in the same order, byte for byte."""
    traj = _traj()
    end = traj.duration_ns
    whole = _engine(type_name, tmp_path / "one", traj, Clock.fixed(end)).finish(end)
    stepped, taps = _stepped(type_name, tmp_path / "step", traj, Clock(0))
    assert len(stepped) == len(whole.messages)
    assert _wire(stepped) == _wire(whole.messages)
    assert taps


@pytest.mark.parametrize(
    ("type_name", "extra"),
    [
        ("event_camera", {"sampling": "brightness"}),
        ("event_camera", {"optic_flow": True, "depthmap": True, "ground_truth_rate": 50.0}),
        ("camera", {"exposure_time": 0.004, "auto_exposure": {"time_constant": 0.05}}),
    ],
    ids=["brightness", "flow-depth", "auto-exposure"],
)
def test_stateful_sampling_is_causal_too(
    type_name: str, extra: dict[str, Any], tmp_path: Path
) -> None:
    """Brightness sampling (the next instant reads ESIM's state), ground-truth flow and
    depth instants, auto-exposure metered frame by frame: stepped == one-shot."""
    traj = _traj()
    end = traj.duration_ns
    one = _engine(type_name, tmp_path / "one", traj, Clock.fixed(end), **extra).finish(end)
    stepped, _ = _stepped(type_name, tmp_path / "step", traj, Clock(0), **extra)
    assert _wire(stepped) == _wire(one.messages)


@pytest.mark.parametrize("type_name", ["sonar", "altimeter"])
def test_range_readings_come_in_the_step_that_reaches_them(type_name: str, tmp_path: Path) -> None:
    """A range sensor's noise and dropout are drawn per one-second batch, yet every reading
    is sent in the step whose end reaches its instant (no wait for the batch to fill), and
    with dropout on the readings are still the one-shot run's, byte for byte."""
    traj = _traj()
    end = traj.duration_ns
    rate = 200.0  # 200 readings a batch: the whole landing is inside the first one
    extra = {"dropout": 0.3, "noise_sigma": 0.05, "rate": rate}
    topic = f"/s_{type_name}"
    one = _engine(type_name, tmp_path / "one", traj, Clock.fixed(end), **extra).finish(end)
    guard = HorizonGuard(traj)
    eng = _engine(type_name, tmp_path / "step", guard, Clock(0), **extra)
    instants = sample_times_ns(rate, end)
    assert instants.size < rate
    got: list[Any] = []
    h = 0
    while h + STEP_NS < end:
        h += STEP_NS
        guard.set_horizon(h)
        got += [m for m in eng.advance(h).messages if m.topic == topic]
        assert len(got) == np.count_nonzero(instants <= h), h
    guard.finish()
    got += [m for m in eng.finish(end).messages if m.topic == topic]
    whole = [m for m in one.messages if m.topic == topic]
    assert len(got) == len(whole) == instants.size
    assert _wire(got) == _wire(whole)
    values = [m.build(STORES[Flavor.ROS2]).range for m in whole]
    assert 0 < sum(np.isinf(values)) < len(values)  # dropout did drop readings


def test_aligned_event_camera_samples_every_step_end(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Closed loop (``align``): the event camera renders every step's end, so a step's
    events reach it; the camera_info stamps stay the run's grid."""
    from roslan.sensors.cameras.event import EventCamera

    rendered: list[int] = []
    render = EventCamera.render

    def spy(self: Any, ctx: Any, t_ns: int, **kw: Any) -> Any:
        rendered.append(t_ns)
        return render(self, ctx, t_ns, **kw)

    monkeypatch.setattr(EventCamera, "render", spy)
    traj = _traj()
    step = 9_999_999  # (ns: off the sampler's grid of 2 ms steps)
    ends = list(range(step, traj.duration_ns, step))
    _stepped("event_camera", tmp_path / "free", traj, Clock(0), step)
    assert not set(ends) & set(rendered)  # (else this test would prove nothing)
    rendered.clear()
    msgs, taps = _stepped("event_camera", tmp_path / "a", traj, Clock(0, align=True), step)
    assert set(ends) <= set(rendered)
    assert rendered == sorted(set(rendered))
    t = np.concatenate([np.asarray(tap["t"]) for tap in taps])
    assert t.size > 100
    assert np.all(np.diff(t) >= 0)
    info = [m.t_ns for m in msgs if m.topic.endswith("/camera_info")]
    assert info == sample_times_ns(RATE, traj.duration_ns).tolist()


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
