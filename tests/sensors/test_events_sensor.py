"""Event camera sensor: rendered edge timing, streaming files, ROS packing and bags."""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from event_helpers import run_event_camera
from roslan.events import (
    AdaptiveSampler,
    EventBatch,
    EventGenerator,
    EventModelParams,
    motion_field,
)
from roslan.events.files import format_events_txt
from roslan.events.ros import EVENT_ARRAY, pack_event_array
from roslan.io.messages import Flavor, MessageStore
from roslan.io.text import format_columns
from roslan.scene.mesh import place, plane, pose_matrix
from roslan.scene.model import Material, Scene


def _edge_scene() -> Scene:
    tex = np.full((64, 1024, 3), 40, np.uint8)
    tex[:, 512:] = 220  # bright for world x > 0
    mat = Material(color=(1.0, 1.0, 1.0), texture=tex, texture_scale=1.0 / 20.0, name="edge")
    return Scene("edge", (place("floor", plane((20.0, 20.0)), mat, pose_matrix((0.0, 0.0, 0.0))),))


def test_moving_edge_event_times_per_column() -> None:
    gl = pytest.importorskip("roslan.render.gl")
    renderer = gl.get_renderer(_edge_scene())
    W, H, f, Z, v = 64, 12, 40.0, 2.0, 2.0
    K = np.array([[f, 0, (W - 1) / 2], [0, f, (H - 1) / 2], [0, 0, 1.0]])
    x0 = ((W - 1) / 2 - 70) * Z / f  # camera x at t = 0: the edge (world x = 0) at u = 70

    def pose(t_ns: int) -> np.ndarray:
        T = np.eye(4)
        T[:3, :3] = np.array([[1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]])  # looking down
        T[:3, 3] = (x0 + v * t_ns * 1e-9, 0.0, Z)
        return T

    end = round((76 * Z / f / v) * 1e9)
    sampler = AdaptiveSampler("optical_flow", 0.5, min_rate=10, max_rate=1000, end_ns=end)
    gen = EventGenerator(
        W, H, EventModelParams(threshold_pos=0.2, threshold_neg=0.2), np.random.default_rng(0)
    )
    v_cam = np.array([v, 0.0, 0.0])  # world +x = optical +x
    t: int | None = 0
    batches, steps = [], []
    while t is not None:
        res = renderer.render(pose(t), K, W, H)
        lum = res.color @ np.array([0.2126, 0.7152, 0.0722], np.float32)
        batches.append(gen.update(lum, t))
        flow = motion_field(res.depth, K, v_cam, np.zeros(3))
        np.testing.assert_allclose(flow[..., 0], -f * v / Z, rtol=1e-4)  # exact flow from depth
        nxt = sampler.next_ns(t, float(np.abs(flow).max()))
        if nxt is not None:
            steps.append(nxt - t)
        t = nxt
    ev = EventBatch.concatenate(batches)
    dt = max(steps)
    assert dt == pytest.approx(0.5 / (f * v / Z) * 1e9, rel=1e-3)
    row = ev.y == H // 2
    px_time = 1e9 / (f * v / Z)
    for u in range(2, W - 2):
        sel = row & (ev.x == u)
        assert sel.sum() >= 10
        assert np.all(ev.p[sel] == 1)  # dark -> bright
        t_cross = ((W - 1) / 2 - u) * Z / f - x0
        t_cross_ns = t_cross / v * 1e9
        median = float(np.median(ev.t[sel]))
        assert abs(median - t_cross_ns) <= dt + px_time, u


@pytest.mark.parametrize("flavor", list(Flavor))
@pytest.mark.parametrize(
    ("n", "frame_id"), [(0, "dvs"), (1, "dv"), (2, "dvs_optical"), (7, "a"), (9, "abcd")]
)
@pytest.mark.parametrize("span_ns", [10 * 10**9, 10**6], ids=["10s", "1ms"])
def test_event_array_bytes_match_rosbags(
    flavor: Flavor, n: int, frame_id: str, span_ns: int
) -> None:
    store = MessageStore(flavor)
    rng = np.random.default_rng(n)
    t0 = 1_700_000_000 * 10**9 + 5 * 10**8  # a 1 ms packet within one second
    t = np.sort(rng.integers(t0, t0 + span_ns, n))
    x, y, p = rng.integers(0, 1280, n), rng.integers(0, 720, n), rng.integers(0, 2, n)
    E = store.types["dvs_msgs/msg/Event"]
    events = [
        E(x=int(x[i]), y=int(y[i]), ts=store.time(int(t[i])), polarity=bool(p[i])) for i in range(n)
    ]
    header = (
        store.header(1_700_000_000_123_456_789, frame_id, seq=3)
        if store.is_ros1
        else store.header(1_700_000_000_123_456_789, frame_id)
    )
    msg = store.new(EVENT_ARRAY, header=header, height=720, width=1280, events=events)
    want = store.serialize(msg, EVENT_ARRAY)
    got = pack_event_array(
        flavor, 1_700_000_000_123_456_789, frame_id, 720, 1280, t, x, y, p, seq=3
    )
    assert got == want
    # the sensor's form: trajectory times plus an offset, its uint16 / int8 columns
    u16 = np.uint16
    got_off = pack_event_array(
        flavor, 1_700_000_000_123_456_789, frame_id, 720, 1280, t - t0, x.astype(u16),
        y.astype(u16), p.astype(np.int8), seq=3, t_offset=t0,
    )  # fmt: skip
    assert got_off == want
    back = (
        store.typestore.deserialize_ros1(got, EVENT_ARRAY)
        if store.is_ros1
        else store.typestore.deserialize_cdr(got, EVENT_ARRAY)
    )
    assert [e.x for e in back.events] == x.tolist()


def test_event_msgdefs_match_rpg_dvs_ros() -> None:
    store = MessageStore(Flavor.ROS1)
    _text, md5 = store.typestore.generate_msgdef(EVENT_ARRAY)
    # the md5sum rosbag computes for rpg_dvs_ros dvs_msgs/EventArray (from its field list)
    import hashlib

    ev = hashlib.md5(b"uint16 x\nuint16 y\ntime ts\nbool polarity").hexdigest()
    hdr = hashlib.md5(b"uint32 seq\ntime stamp\nstring frame_id").hexdigest()
    # genmsg rule: a complex field (array or not) becomes "<md5 of its type> <name>"
    want = hashlib.md5(
        f"{hdr} header\nuint32 height\nuint32 width\n{ev} events".encode()
    ).hexdigest()
    assert md5 == want


def test_txt_formatter_matches_shared_text_helper() -> None:
    rng = np.random.default_rng(0)
    n = 5000
    t = np.sort(rng.integers(0, 200 * 10**9, n)).astype(np.int64)
    t[:3] = [0, 1, 999_999_999]
    x, y, p = (
        rng.integers(0, 1280, n),
        rng.integers(0, 720, n),
        rng.integers(0, 2, n).astype(np.int8),
    )
    x[0], y[0] = 0, 10000
    got = format_events_txt(t, x, y, p).decode()
    want = format_columns(t, x, y, p, fmt="%d")
    assert got == want


def test_txt_formatter_edges_and_writers_round_trip(tmp_path: Path) -> None:
    """The numba formatter against Python formatting and the NumPy reference on extreme
    values; events.txt and events.h5 (every compression) read back equal."""
    import h5py

    from roslan.events.files import EventH5Writer, EventTextWriter, _format_events_txt_numpy

    rng = np.random.default_rng(3)
    n = 3000
    t = np.sort(rng.integers(0, 2**62, n)).astype(np.int64)
    t[:4] = [0, 9, 1_000_000_000, 1_000_000_001]
    x = rng.integers(0, 2**16, n).astype(np.uint16)
    y = rng.integers(0, 2**16, n).astype(np.uint16)
    x[:3], y[:3] = [0, 9, 65535], [10, 99, 100]
    p = rng.integers(0, 2, n).astype(np.int8)
    want = "".join(
        f"{a // 10**9}.{a % 10**9:09d} {b} {c} {d}\n"
        for a, b, c, d in zip(t.tolist(), x.tolist(), y.tolist(), p.tolist(), strict=True)
    ).encode()
    assert format_events_txt(t, x, y, p) == want
    assert _format_events_txt_numpy(t, x, y, p) == want
    big = np.array([2**40 + 7], np.int64)  # int64 coordinates too
    assert (
        format_events_txt(t[:1], big, big, p[:1])
        == f"0.000000000 {big[0]} {big[0]} {p[0]}\n".encode()
    )
    with pytest.raises(ValueError, match="non-negative"):
        format_events_txt(np.array([-1]), x[:1], y[:1], p[:1])
    assert format_events_txt(t[:0], x[:0], y[:0], p[:0]) == b""
    # streamed writers, batches across chunk boundaries
    ev = EventBatch(t, x, y, p)
    cuts = [0, 1, 700, 701, 2500, n]
    tw = EventTextWriter(tmp_path / "e.txt")
    hw = {c: EventH5Writer(tmp_path / f"e_{c}.h5", 346, 260, chunk=512, compression=c)
          for c in ("gzip", "lzf", None)}  # fmt: skip
    # events.h5 gets times below 4.3 s (its ms_to_idx has an entry per millisecond)
    ev_h5 = EventBatch(t >> 30, x, y, p)
    for a, b in itertools.pairwise(cuts):
        tw.write(ev.slice(a, b))
        for w in hw.values():
            w.write(ev_h5.slice(a, b))
    for w in (tw, *hw.values()):
        w.close()
    assert (tmp_path / "e.txt").read_bytes() == want
    for c in hw:
        with h5py.File(tmp_path / f"e_{c}.h5", "r") as f:
            g = f["events"]
            assert g["t"].compression == c
            np.testing.assert_array_equal(g["t_ns"][:], ev_h5.t)
            np.testing.assert_array_equal(g["t"][:], ev_h5.t // 1000)  # DSEC: microseconds
            for name, col in zip("xyp", ev[1:], strict=True):
                np.testing.assert_array_equal(g[name][:], col)
            _check_dsec_ms_to_idx(f)
    with pytest.raises(ValueError, match="compression"):
        EventH5Writer(tmp_path / "bad.h5", 1, 1, compression="zstd")  # type: ignore[arg-type]


def _check_dsec_ms_to_idx(f: Any) -> None:
    """DSEC's index, recomputed independently: entry m = first event with t >= m ms
    (t in microseconds), one entry per millisecond up to one past the last event."""
    t_us = f["events/t"][:]
    ms_to_idx = f["ms_to_idx"][:]
    assert ms_to_idx.dtype == np.uint64
    assert ms_to_idx.size == (int(t_us[-1]) // 1000 + 2 if t_us.size else 1)
    for m in range(ms_to_idx.size):  # independent scan (no searchsorted)
        first = next((i for i, v in enumerate(t_us.tolist()) if v >= 1000 * m), t_us.size)
        if m % 97 == 0 or m == ms_to_idx.size - 1:  # spot-check: the scan is O(N) each
            assert int(ms_to_idx[m]) == first, m
    assert np.all(np.diff(ms_to_idx.astype(np.int64)) >= 0)
    idx = ms_to_idx.astype(np.int64)
    for m in range(ms_to_idx.size - 1):  # every window holds exactly its millisecond
        w = t_us[idx[m] : idx[m + 1]]
        assert np.all((w >= 1000 * m) & (w < 1000 * (m + 1)))


def test_events_h5_is_dsec_and_evlib_reads_both_files(tmp_path: Path) -> None:
    """evlib (a third-party event library) loads events.h5 and events.txt with the same
    events and the right time span; DSEC's t_offset and ms_to_idx follow the format."""
    evlib = pytest.importorskip("evlib")
    import h5py

    from roslan.events.files import EventH5Writer, EventTextWriter

    rng = np.random.default_rng(8)
    n = 30_000
    t = np.sort(rng.integers(0, 2_600_000_000, n)).astype(np.int64)  # 2.6 s, ns
    x = rng.integers(0, 346, n).astype(np.uint16)
    y = rng.integers(0, 260, n).astype(np.uint16)
    p = rng.integers(0, 2, n).astype(np.int8)
    ev = EventBatch(t, x, y, p)
    start = 1_700_000_000_123_456_789
    hw = EventH5Writer(tmp_path / "events.h5", 346, 260, chunk=4096, t_offset_ns=start)
    tw = EventTextWriter(tmp_path / "events.txt")
    for a in range(0, n, 7000):
        hw.write(ev.slice(a, a + 7000))
        tw.write(ev.slice(a, a + 7000))
    hw.close()
    tw.close()
    with h5py.File(tmp_path / "events.h5", "r") as f:
        assert int(f["t_offset"][()]) == start // 1000
        _check_dsec_ms_to_idx(f)
    for name in ("events.h5", "events.txt"):
        df = evlib.load_events(str(tmp_path / name)).collect()
        t_us = df["t"].dt.total_microseconds().to_numpy()
        assert df.height == n
        np.testing.assert_array_equal(t_us, t // 1000)
        assert (t_us[-1] - t_us[0]) * 1e-6 == pytest.approx((t[-1] - t[0]) * 1e-9, abs=2e-6)
        np.testing.assert_array_equal(df["x"].to_numpy(), x)
        np.testing.assert_array_equal(df["y"].to_numpy(), y)
        np.testing.assert_array_equal(df["polarity"].to_numpy() > 0, p > 0)


# ------------------------------------------------------------------ end to end
def _run(tmp: Path, seed: int, **over: Any) -> tuple[Any, list[Any]]:
    from roslan.rundir.calibration import write_calibration

    sensor, msgs = run_event_camera(tmp, seed, **over)
    write_calibration(tmp, [sensor.config])  # once per run, as the pipeline does
    return sensor, msgs


def _write_bags(tmp: Path, sensor: Any, msgs: list[Any]) -> dict[str, Path]:
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2

    start = 1_700_000_000_000_000_000
    out = {}
    for flavor in Flavor:
        store = MessageStore(flavor)
        path = tmp / ("bag.bag" if flavor is Flavor.ROS1 else "bag2")
        writer: Any = (
            Writer1(path)
            if flavor is Flavor.ROS1
            else Writer2(path, version=8, storage_plugin=StoragePlugin.MCAP)
        )
        with writer:
            conns = {
                spec.topic: writer.add_connection(
                    spec.topic, spec.msgtype, typestore=store.typestore
                )
                for spec in sensor.topics()
            }
            for m in msgs:
                data = m.build(store)
                if not isinstance(data, bytes):
                    data = store.serialize(data, m.msgtype)
                writer.write(conns[m.topic], start + m.t_ns, data)
        out[flavor.value] = path
    return out


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Any, list[Any]]:
    pytest.importorskip("roslan.render.gl")
    tmp = tmp_path_factory.mktemp("evrun")
    sensor, msgs = _run(tmp, 3, optic_flow=True, depthmap=True)
    return tmp, sensor, msgs


def test_timestamp_resolution_floors_the_exact_times(
    run_dir: tuple[Path, Any, list[Any]], tmp_path: Path
) -> None:
    """Same seed, exact ns times (``timestamp_resolution: 0``): the same events, and the
    default run's times are these floored to the sensor's 1 us tick."""
    import h5py

    tmp, sensor, _ = run_dir
    exact, _ = _run(tmp_path, 3, optic_flow=True, depthmap=True, timestamp_resolution=0)
    assert exact.stats["events"] == sensor.stats["events"]
    with h5py.File(tmp_path / "events.h5", "r") as fe, h5py.File(tmp / "events.h5", "r") as fq:
        ge, gq = fe["events"], fq["events"]
        t_exact = ge["t_ns"][:]
        np.testing.assert_array_equal(ge["t"][:], t_exact // 1000)
        assert np.count_nonzero(t_exact % 1000) > 0.9 * t_exact.size  # really sub-us
        np.testing.assert_array_equal(gq["t"][:], t_exact // 1000)
        for name in "xyp":
            np.testing.assert_array_equal(gq[name][:], ge[name][:])
    lines = (tmp / "events.txt").read_text().splitlines()
    assert all(line.split()[0].endswith("000") for line in lines)
    # (the same render instants: optic_flow forces its intervals' ends)
    _run(tmp_path / "t10", 3, optic_flow=True, depthmap=True, timestamp_resolution=1e-5)
    with h5py.File(tmp_path / "t10" / "events.h5", "r") as f:
        assert "t_ns" not in f["events"]
        np.testing.assert_array_equal(f["events/t"][:], t_exact // 10_000 * 10)


@pytest.mark.parametrize(
    ("value", "match"),
    [(1.5e-9, "whole number of nanoseconds"), (1e-10, "at least 1e-9"), (0.01, "less than")],
)
def test_timestamp_resolution_is_checked(value: float, match: str) -> None:
    from roslan.sensors.cameras import EventCameraConfig

    with pytest.raises(ValueError, match=match):
        EventCameraConfig.model_validate(
            {"type": "event_camera", "name": "dvs", "rate": 25, "timestamp_resolution": value}
        )


def test_stream_is_ordered_and_complete(run_dir: tuple[Path, Any, list[Any]]) -> None:
    tmp, sensor, msgs = run_dir
    stamps = [m.t_ns for m in msgs]
    assert stamps == sorted(stamps)
    topics = {m.topic for m in msgs}
    assert topics == {
        "/dvs/events",
        "/dvs/camera_info",
        "/dvs/image_raw",
        "/dvs/event_image",
        "/dvs/optic_flow",
        "/dvs/depthmap",
    }
    assert sensor.stats["events"] > 1000
    assert (tmp / "images.txt").read_text().count("\n") == sum(
        m.topic == "/dvs/image_raw" for m in msgs
    )
    assert (tmp / "calib" / "dvs.yaml").is_file()


def test_txt_h5_and_bags_agree(run_dir: tuple[Path, Any, list[Any]]) -> None:
    import h5py
    from rosbags.highlevel import AnyReader

    tmp, sensor, msgs = run_dir
    txt = np.loadtxt(tmp / "events.txt", dtype=np.float64, ndmin=2)
    with open(tmp / "events.txt") as fh:
        t_txt = np.array([int(line.split()[0].replace(".", "")) for line in fh], dtype=np.int64)
    with h5py.File(tmp / "events.h5", "r") as f:
        g = f["events"]
        # the realistic preset stamps whole microseconds: events/t is exact, no t_ns
        assert "t_ns" not in g
        t, x, y, p = g["t"][:] * 1000, g["x"][:], g["y"][:], g["p"][:]
        assert g["t"].dtype == np.int64
        assert g["x"].dtype == np.uint16
        assert g["p"].dtype == np.uint8
        _check_dsec_ms_to_idx(f)
        assert g["t"].compression == "gzip"
        assert g["t"].chunks is not None
        assert f.attrs["width"] == 40
        assert f.attrs["height"] == 30
    assert t.size == sensor.stats["events"] == txt.shape[0]
    np.testing.assert_array_equal(t_txt, t)
    np.testing.assert_array_equal(txt[:, 1:].astype(np.int64), np.stack([x, y, p], 1))
    assert np.all(np.diff(t) >= 0)
    assert set(np.unique(p).tolist()) <= {0, 1}
    bags = _write_bags(tmp, sensor, msgs)
    start = 1_700_000_000_000_000_000
    for path in bags.values():
        with AnyReader([path]) as reader:
            conns = [c for c in reader.connections if c.topic == "/dvs/events"]
            assert conns[0].msgtype == EVENT_ARRAY
            bt, bx, by, bp = [], [], [], []
            for conn, stamp, raw in reader.messages(connections=conns):
                m = reader.deserialize(raw, conn.msgtype)
                assert m.width == 40
                assert m.height == 30
                assert m.header.frame_id == "dvs_optical"
                ts = [e.ts.sec * 10**9 + e.ts.nanosec for e in m.events]
                assert stamp == ts[-1] == m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
                bt += ts
                bx += [e.x for e in m.events]
                by += [e.y for e in m.events]
                bp += [int(e.polarity) for e in m.events]
            np.testing.assert_array_equal(np.array(bt) - start, t)
            np.testing.assert_array_equal(bx, x)
            np.testing.assert_array_equal(by, y)
            np.testing.assert_array_equal(bp, p)
            # packets are 1 ms: no packet spans two milliseconds
            info = [c for c in reader.connections if c.topic == "/dvs/camera_info"]
            for conn, _, raw in reader.messages(connections=info):
                ci = reader.deserialize(raw, conn.msgtype)
                assert ci.width == 40
                break


def test_same_seed_same_bytes(tmp_path: Path, run_dir: tuple[Path, Any, list[Any]]) -> None:
    tmp, _sensor, msgs = run_dir
    _other, msgs2 = _run(tmp_path, 3, optic_flow=True, depthmap=True)
    assert (tmp_path / "events.txt").read_bytes() == (tmp / "events.txt").read_bytes()
    assert (tmp_path / "events.h5").read_bytes() == (tmp / "events.h5").read_bytes()
    store = MessageStore(Flavor.ROS2)
    a = [m.build(store) for m in msgs if m.topic == "/dvs/events"]
    b = [m.build(store) for m in msgs2 if m.topic == "/dvs/events"]
    assert a == b


def test_packets_by_event_count(tmp_path: Path) -> None:
    pytest.importorskip("roslan.render.gl")
    _, msgs = _run(tmp_path, 0, packet_events=100, preset="clean", write_h5=False)
    store = MessageStore(Flavor.ROS1)
    sizes = [
        len(store.typestore.deserialize_ros1(m.build(store), EVENT_ARRAY).events)
        for m in msgs
        if m.topic == "/dvs/events"
    ]
    assert all(s == 100 for s in sizes[:-1])
    assert 0 < sizes[-1] <= 100
    assert not (tmp_path / "events.h5").exists()


def test_plot_events(run_dir: tuple[Path, Any, list[Any]], tmp_path: Path) -> None:
    from roslan.cli import main
    from roslan.plots.events import event_rate
    from roslan.rundir.events import open_events

    tmp, _, _ = run_dir
    assert main(["plot", "events", str(tmp), "-o", str(tmp_path / "plots"), "--frames", "2"]) == 0
    names = sorted(p.name for p in (tmp_path / "plots").iterdir())
    assert names == [
        "event_frame_00.png",
        "event_frame_01.png",
        "event_frames.png",
        "event_rate.png",
    ]
    with open_events(tmp, "test") as src:
        _, on, off = event_rate(src, 0, 2_000_000_000, 10_000_000)
    with h5py_file(tmp / "events.h5") as f:
        p = f["events/p"][:]
    assert int(on.sum()) == int((p == 1).sum())
    assert int(off.sum()) == int((p == 0).sum())


def h5py_file(path: Path) -> Any:
    import h5py

    return h5py.File(path, "r")


def test_distorted_camera_flow_matches_projection() -> None:
    from roslan.sensors.cameras import EventCamera, EventCameraConfig

    cfg = EventCameraConfig.model_validate(
        {
            "type": "event_camera",
            "name": "dvs",
            "rate": 25,
            "topic": "/dvs",
            "resolution": (60, 40),
            "fx": 40.0,
            "fy": 41.0,
            "distortion_model": "plumb_bob",
            "distortion_coeffs": (-0.25, 0.06, 0.001, -0.002),
        }
    )
    cam = EventCamera(cfg).camera
    rng = np.random.default_rng(0)
    depth = rng.uniform(1.0, 6.0, (40, 60))
    v, w = np.array([0.4, -0.2, 1.0]), np.array([0.3, 0.1, -0.2])
    flow = cam.flow(depth, v, w)
    x, y = cam.rays
    P = np.stack([x * depth, y * depth, depth], -1).reshape(-1, 3)
    h = 1e-6
    P2 = P - (v + np.cross(w, P)) * h
    uv1 = cam.model.project(P)
    uv2 = cam.model.project(P2)
    u, vv = np.meshgrid(np.arange(60.0), np.arange(40.0))
    np.testing.assert_allclose(
        uv1, np.stack([u.ravel(), vv.ravel()], 1), atol=1e-6
    )  # rays are exact
    np.testing.assert_allclose(flow.reshape(-1, 2), (uv2 - uv1) / h, rtol=1e-3, atol=1e-2)


@pytest.mark.parametrize(
    "over",
    [
        {"sampling": "brightness"},
        {"distortion_model": "equidistant", "distortion_coeffs": (0.01, -0.005, 0.0, 0.0)},
    ],
)
def test_sensor_variants_run(tmp_path: Path, over: dict[str, Any]) -> None:
    pytest.importorskip("roslan.render.gl")
    sensor, _ = _run(tmp_path, 1, preset="clean", **over)
    assert sensor.stats["events"] > 100
    assert sensor.stats["frames"] <= 0.8 * 300 + 2
    with __import__("h5py").File(tmp_path / "events.h5", "r") as f:
        assert f["events/x"][:].max() < 40
        assert f["events/y"][:].max() < 30
