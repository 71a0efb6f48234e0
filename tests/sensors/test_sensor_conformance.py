"""Conformance of every registered sensor type (SENSOR_TYPES), on the ``empty`` scene over a
short landing: minimal config validates, topics and frames as configured, stamps monotone and
equal to the header stamps, messages decode in both flavours, same seed => same bytes, and the
sensor runs through the whole pipeline into readable bags."""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from roslan.config.sim import SimConfig
from roslan.io.messages import Flavor, MessageStore
from roslan.pipeline import run_simulation
from roslan.pipeline.context import Context
from roslan.rundir.extrinsics import static_transforms
from roslan.sensors.base import Sensor
from roslan.sensors.registry import SENSOR_TYPES, config_class, sensor_class
from roslan.trajectory import TauTrajectory, TrajectoryConfig
from roslan.vehicle import VehicleConfig, base_link_trajectory

# T = z0 / (k v0) = 0.1 s plus 0.05 s at rest: a few samples of every sensor at 20 Hz, and a
# bounded cost for sensors that sample adaptively (the event camera renders up to 2 kHz)
TRAJ = {
    "k": 0.5,
    "initial": {"position": [-0.2, 0.1, 0.1], "rpy": [0.02, 0.05, 0.1], "descent_rate": 2.0},
    "hold": 0.05,
}
RATE = 20.0
START = 1_600_000_000_123_456_789
SEED = 5
STORES = {f: MessageStore(f) for f in Flavor}


def _minimal(type_name: str) -> dict[str, Any]:
    return {"type": type_name, "name": f"s_{type_name}", "rate": RATE, "topic": f"/s_{type_name}"}


def _load(type_name: str) -> tuple[Any, Any]:
    try:
        return config_class(type_name), sensor_class(type_name)
    except (ImportError, AttributeError) as err:
        pytest.skip(
            f"sensor type {type_name!r} is registered but its module is not available yet: {err}"
        )


def _scene() -> Any:
    try:
        scene_mod = importlib.import_module("roslan.scene")
        return scene_mod.load_scene("empty", seed=SEED)
    except (ImportError, AttributeError) as err:  # pragma: no cover - scene package present
        pytest.skip(f"the 'empty' scene is not available yet: {err}")


def _run_sensor(
    type_name: str, outdir: Path | None, seed: int = 5
) -> tuple[Sensor, list[Any], dict[str, bytes]]:
    cfg_cls, cls = _load(type_name)
    cfg = cfg_cls.model_validate(_minimal(type_name))
    # as the pipeline flies it: the default vehicle's feet on the goal
    traj = TauTrajectory(
        base_link_trajectory(TrajectoryConfig.model_validate(TRAJ), VehicleConfig(), _scene())
    )
    ctx = Context(
        traj,
        outdir,
        seed=seed,
        start_time_ns=START,
        sensors=[cfg],
        scene_spec="empty",
        scene=_scene(),
    )
    sensor = cls(cfg)
    msgs = list(sensor.messages(ctx))
    sensor.close(ctx)
    if outdir is None:
        return sensor, msgs, {}
    files = {
        str(p.relative_to(outdir)): p.read_bytes() for p in sorted(outdir.rglob("*")) if p.is_file()
    }
    return sensor, msgs, files


def _decode(store: MessageStore, msg: Any) -> Any:
    data = msg.build(store)
    if not isinstance(data, bytes | bytearray | memoryview):
        data = store.serialize(data, msg.msgtype)
    raw = bytes(data)
    if store.is_ros1:
        return store.typestore.deserialize_ros1(raw, msg.msgtype), raw
    return store.typestore.deserialize_cdr(raw, msg.msgtype), raw


@pytest.fixture(params=sorted(SENSOR_TYPES))
def type_name(request: pytest.FixtureRequest) -> str:
    return str(request.param)


def test_minimal_config_and_protocol(type_name: str) -> None:
    cfg_cls, cls = _load(type_name)
    cfg = cfg_cls.model_validate(_minimal(type_name))
    assert cfg.type == type_name
    assert cfg.frame == f"s_{type_name}"
    # it also validates inside a SimConfig (the registry dispatch)
    sim = SimConfig.model_validate({"sensors": [_minimal(type_name)]})
    assert type(sim.sensors[0]) is cfg_cls
    sensor = cls(cfg)
    assert isinstance(sensor, Sensor)
    topics = sensor.topics()
    assert topics, "a sensor publishes at least one topic"
    for t in topics:
        assert t.topic == cfg.topic or t.topic.startswith(cfg.topic + "/"), t
        assert t.msgtype in STORES[Flavor.ROS1].types, t
        assert t.msgtype in STORES[Flavor.ROS2].types, t


def test_stream_conformance_and_determinism(
    type_name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """One direct run of the sensor, one run through the pipeline with the same seed: the
    checks run on the first, the second must reproduce its bytes (bags and dataset files)."""
    sensor, msgs, files = _run_sensor(type_name, tmp_path / "direct")
    cfg = sensor.config
    declared = {t.topic: t.msgtype for t in sensor.topics()}
    assert msgs, "no messages over a 0.15 s landing at 20 Hz"
    duration_ns = TauTrajectory(TrajectoryConfig.model_validate(TRAJ)).duration_ns
    t = np.array([m.t_ns for m in msgs])
    assert (np.diff(t) >= 0).all(), "stamps must be non-decreasing"
    assert t[0] >= 0
    assert t[-1] <= duration_ns + round(1e9 / RATE)  # within the landing (+ one period)
    frames = {cfg.frame} | {tf.child for tf in static_transforms([sensor])}
    for m in msgs:
        assert declared.get(m.topic) == m.msgtype, (m.topic, m.msgtype)
    # decode a sample of messages in both flavours: header stamp/frame as configured
    sample = msgs[:: max(1, len(msgs) // 20)]
    for flavor, store in STORES.items():
        for m in sample:
            decoded, _ = _decode(store, m)
            header = getattr(decoded, "header", None)
            if header is not None:
                stamp = header.stamp.sec * 10**9 + header.stamp.nanosec
                assert stamp == START + m.t_ns, (flavor, m.topic)
                assert header.frame_id in frames, (m.topic, header.frame_id, frames)

    # the same job through the pipeline (same seed): identical messages and files
    import roslan.plots.landing as landing

    monkeypatch.setattr(landing, "write_trajectory_plot", lambda traj, path: None)
    sim = SimConfig.model_validate(
        {
            "trajectory": TRAJ,
            "scene": "empty",
            "seed": SEED,
            "sensors": [_minimal(type_name)],
            "output": {"start_time": START, "formats": ["ros1"]},
        }
    )
    out = tmp_path / "out"
    run = run_simulation(sim, out, quiet=True, allow_collision=True)
    assert (out / "scene").is_dir()
    with AnyReader([out / "landing.bag"]) as reader:
        conns = [c for c in reader.connections if c.topic in declared]
        bagged = [(ts, c.topic, bytes(raw)) for c, ts, raw in reader.messages(connections=conns)]
        assert sum(1 for _ in reader.messages()) == run["messages_total"]
    ours = sorted(
        ((START + m.t_ns, m.topic, _decode(STORES[Flavor.ROS1], m)[1]) for m in msgs),
        key=lambda x: (x[0], x[1]),
    )
    assert sorted(bagged, key=lambda x: (x[0], x[1])) == ours
    for rel, data in files.items():
        assert (out / rel).read_bytes() == data, rel


def test_without_a_file_sink_the_same_messages_and_no_file(
    type_name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A run that records no files (``ctx.files is None``, an unrecorded closed-loop
    episode): every sensor publishes the same bytes and creates no file or folder, neither
    in the temporary folder nor in the working folder."""
    import tempfile

    _, recorded, files = _run_sensor(type_name, tmp_path / "recorded")
    assert files, "the recorded run writes the sensor's dataset files"
    quiet = tmp_path / "quiet"
    (quiet / "tmp").mkdir(parents=True)
    monkeypatch.setenv("TMPDIR", str(quiet / "tmp"))
    monkeypatch.setattr(tempfile, "tempdir", None)  # gettempdir() reads TMPDIR again
    monkeypatch.chdir(quiet)
    assert tempfile.gettempdir() == str(quiet / "tmp")
    _, unrecorded, none = _run_sensor(type_name, None)
    assert none == {}
    assert list(quiet.rglob("*")) == [quiet / "tmp"]
    store = STORES[Flavor.ROS1]
    assert [(m.t_ns, m.topic, _decode(store, m)[1]) for m in unrecorded] == [
        (m.t_ns, m.topic, _decode(store, m)[1]) for m in recorded
    ]
