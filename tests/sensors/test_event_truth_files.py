"""Event-camera ground truth as files: DSEC flow PNGs and MVSEC-style depth.h5 agree with
the bag messages of the same instants."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from event_helpers import START_NS, run_event_camera
from roslan.io.messages import Flavor, MessageStore
from roslan.sensors.cameras.event_truth import decode_dsec_flow, encode_dsec_flow


def _run(tmp: Path) -> list[Any]:
    # pitched up: part of every image is sky (NaN depth; flow of the rotation only)
    _, msgs = run_event_camera(
        tmp, 1, pose={"rpy": (0.0, -0.2, 0.0)}, max_rate=100, optic_flow=True,
        depthmap=True, ground_truth_rate=20,
    )  # fmt: skip
    return msgs


@pytest.fixture(scope="module")
def truth_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Any]]:
    pytest.importorskip("roslan.render.gl")
    tmp = tmp_path_factory.mktemp("truth")
    return tmp, _run(tmp)


def test_truth_files_are_deterministic(truth_run: tuple[Path, list[Any]], tmp_path: Path) -> None:
    tmp, _ = truth_run
    _run(tmp_path)
    names = ["depth.h5", "flow/forward_timestamps.txt"]
    names += [f"flow/forward/{p.name}" for p in sorted((tmp / "flow" / "forward").glob("*"))]
    for name in names:
        assert (tmp_path / name).read_bytes() == (tmp / name).read_bytes(), name


def _images(msgs: list[Any], topic: str) -> list[tuple[int, np.ndarray]]:
    store = MessageStore(Flavor.ROS2)
    out = []
    for m in msgs:
        if m.topic != topic:
            continue
        img = store.typestore.deserialize_cdr(m.build(store), "sensor_msgs/msg/Image")
        stamp = img.header.stamp.sec * 10**9 + img.header.stamp.nanosec
        if img.encoding == "rgb8":
            data = img.data.reshape(img.height, img.width, 3)
        else:
            ch = 2 if img.encoding == "32FC2" else 1
            data = np.frombuffer(img.data.tobytes(), np.float32).reshape(img.height, img.width, ch)
        out.append((stamp, data))
    return out


def _read_png16(path: Path) -> np.ndarray:
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert img is not None
    assert img.dtype == np.uint16
    return np.ascontiguousarray(img[..., ::-1])  # DSEC's loaders read RGB


def test_dsec_flow_pngs_beside_the_bag(truth_run: tuple[Path, list[Any]]) -> None:
    """The flow maps start at ground-truth stamps of the bag's ``optic_flow`` (the motion
    field, px/s), span ``flow_interval`` (0.1 s) and end by the end of the run; where
    nothing is hit (the sky, ``flow_sky: invalid`` by default) they are invalid.
    (Their values: tests/sensors/test_flow_truth.py, against an independent reference.)"""
    import h5py

    tmp, msgs = truth_run
    bag = _images(msgs, "/dvs/optic_flow")
    assert len(bag) >= 5
    lines = (tmp / "flow" / "forward_timestamps.txt").read_text().splitlines()
    assert lines[0] == "# from_timestamp_us, to_timestamp_us"
    rows = np.array([[int(v) for v in ln.split(", ")] for ln in lines[1:]], dtype=np.int64)
    pngs = sorted((tmp / "flow" / "forward").glob("*.png"))
    assert len(pngs) == rows.shape[0] >= 3
    assert [p.name for p in pngs] == [f"{i:06d}.png" for i in range(len(pngs))]
    stamps = np.array([s for s, _ in bag], dtype=np.int64) // 1000
    assert set(rows[:, 0].tolist()) <= set(stamps.tolist())
    np.testing.assert_array_equal(rows[:, 1] - rows[:, 0], 100_000)
    assert rows[-1, 1] <= stamps[-1]  # (the last ground-truth stamp is the run's end)
    assert rows[-1, 1] + 50_000 > stamps[-1]  # the last one that fits (20 Hz)
    with h5py.File(tmp / "depth.h5", "r") as f:
        depth = f["davis/left/depth_image_raw"][:]
        depth_us = (f["davis/left/depth_image_raw_t_ns"][:] + START_NS) // 1000
    n_valid = n_sky = 0
    for path, (a, _) in zip(pngs, rows, strict=True):
        disp, valid = decode_dsec_flow(_read_png16(path))
        sky = np.isnan(depth[int(np.flatnonzero(depth_us == a)[0])])
        assert not np.any(valid & sky)
        assert np.all(disp[~valid] == 0)  # DSEC's invalid pixels: code 2**15, flow 0
        n_valid += int(valid.sum())
        n_sky += int(sky.sum())
    assert n_sky > 0
    assert n_valid > 0.4 * len(pngs) * 30 * 40


def test_depth_h5_matches_the_bag(truth_run: tuple[Path, list[Any]]) -> None:
    import h5py

    tmp, msgs = truth_run
    bag = _images(msgs, "/dvs/depthmap")
    with h5py.File(tmp / "depth.h5", "r") as f:
        g = f["davis/left"]
        img = g["depth_image_raw"][:]
        ts = g["depth_image_raw_ts"][:]
        t_ns = g["depth_image_raw_t_ns"][:]
        assert img.dtype == np.float32
    assert img.shape == (len(bag), 30, 40)
    for i, (stamp, d) in enumerate(bag):
        np.testing.assert_array_equal(img[i], d[..., 0])  # NaN where NaN, else identical
        assert t_ns[i] == stamp - START_NS
        assert ts[i] == pytest.approx(stamp * 1e-9, abs=1e-6)
    assert np.isnan(img).any()
    assert np.isfinite(img).any()


def test_dsec_encoding_round_trip_and_range() -> None:
    rng = np.random.default_rng(0)
    d = rng.uniform(-200, 200, (7, 9, 2))
    d[0, 0] = np.nan
    d[1, 1, 0] = 300.0  # beyond DSEC's +-256 px
    raw = encode_dsec_flow(d)
    assert raw.dtype == np.uint16
    back, valid = decode_dsec_flow(raw)
    assert not valid[0, 0]
    assert not valid[1, 1]
    assert valid.sum() == 7 * 9 - 2
    assert np.abs(back[valid] - d[valid]).max() <= 0.5 / 128 + 1e-12
    # the formula itself: 2**15 + 128 * flow
    np.testing.assert_array_equal(raw[2, 2, :2], np.rint(d[2, 2] * 128) + 2**15)


def test_event_image_shows_the_last_window_of_events(truth_run: tuple[Path, list[Any]]) -> None:
    """``/dvs/event_image`` (for bag viewers): at each camera_info instant, white, with the
    events of the last 10 ms from events.txt, the last one of a pixel deciding blue (ON)
    or red (OFF)."""
    tmp, msgs = truth_run
    frames = _images(msgs, "/dvs/event_image")
    infos = [m.t_ns for m in msgs if m.topic == "/dvs/camera_info"]
    assert len(frames) == len(infos) >= 10
    lines = (tmp / "events.txt").read_text().split()
    ev = np.array(lines, dtype=np.float64).reshape(-1, 4)
    t_ns = np.array([int(v.replace(".", "")) for v in lines[0::4]], dtype=np.int64)
    n_colored = 0
    for stamp, img in frames:
        t = stamp - START_NS
        sel = np.flatnonzero((t_ns > t - 10_000_000) & (t_ns <= t))
        expect = np.full((30, 40, 3), 255, np.uint8)
        for i in sel:  # independent: event by event, in time order
            x, y, p = int(ev[i, 1]), int(ev[i, 2]), int(ev[i, 3])
            expect[y, x] = (0, 0, 255) if p == 1 else (255, 0, 0)
        np.testing.assert_array_equal(img, expect)
        n_colored += int(np.any(expect != 255, axis=-1).sum())
    assert n_colored > 50
