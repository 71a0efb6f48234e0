"""Spinning LiDAR: HDL-32E geometry over flat ground, timing, cloud layout, bags, errors."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from range_helpers import FakeContext, LinearTrajectory, plane, run_sensor, scene
from roslan.config.base import validate_model
from roslan.errors import ConfigError
from roslan.io.messages import Flavor, MessageStore
from roslan.sensors.beams import Lidar, LidarConfig

# Velodyne HDL-32E manual: laser ids 0..31 (firing order) -> elevation, deg
DATASHEET = [-30.67, -9.33, -29.33, -8.00, -28.00, -6.67, -26.67, -5.33, -25.33, -4.00,
             -24.00, -2.67, -22.67, -1.33, -21.33, 0.00, -20.00, 1.33, -18.67, 2.67,
             -17.33, 4.00, -16.00, 5.33, -14.67, 6.67, -13.33, 8.00, -12.00, 9.33,
             -10.67, 10.67]  # fmt: skip
H = 1.8  # sensor height above the ground, m


def _cfg(**kw: object) -> LidarConfig:
    data = {"type": "lidar", "name": "velodyne", **kw}
    return validate_model(LidarConfig, data, "sim.yaml")


def _ground_turn(tmp_path: Path, **kw: object) -> tuple[Lidar, np.ndarray]:
    lid = Lidar(_cfg(**kw))
    ctx = FakeContext(scene(plane()), LinearTrajectory((0.0, 0.0, H)), tmp_path)
    pts = lid.scan(ctx.trajectory, ctx.raycaster(), 0, ctx.rng("velodyne"))
    return lid, pts


def test_rings_over_flat_ground(tmp_path: Path) -> None:
    sigma = 0.02
    lid, pts = _ground_turn(tmp_path, noise_sigma=sigma)
    r = np.sqrt(pts["x"] ** 2 + pts["y"] ** 2 + pts["z"] ** 2)
    elev = np.degrees(np.arcsin(pts["z"] / r))
    sorted_el = sorted(DATASHEET)
    down = [e for e in sorted_el if e < 0]
    steps = lid.spec.azimuth_steps
    assert steps == math.floor(0.1 / 46.08e-6)
    # every downward beam returns once per column, nothing else does
    assert pts.shape[0] == len(down) * steps
    for ring, e in enumerate(sorted_el):
        sel = pts["ring"] == ring
        if e >= 0:
            assert not sel.any()
            continue
        assert sel.sum() == steps
        np.testing.assert_allclose(elev[sel], e, atol=0.01)
        expected = H / math.sin(math.radians(-e))
        assert np.abs(r[sel] - expected).max() < 5 * sigma + 1e-4
        assert abs(r[sel].mean() - expected) < 4 * sigma / math.sqrt(steps) + 1e-4
        assert 0.5 * sigma < r[sel].std() < 1.5 * sigma


def test_time_and_azimuth_follow_the_firing_sequence(tmp_path: Path) -> None:
    rate = 10.0
    _, pts = _ground_turn(tmp_path, noise_sigma=0.0, rate=rate)
    t = pts["time"].astype(np.float64)
    assert t.min() >= 0.0
    assert t.max() < 1.0 / rate
    # firing offsets are multiples of the 1.152 us laser spacing inside 46.08 us cycles
    laser = np.array(DATASHEET)
    ring_of_laser = np.argsort(np.argsort(laser, kind="stable"), kind="stable")
    laser_of_ring = np.argsort(ring_of_laser)
    lid_id = laser_of_ring[pts["ring"]]
    col = np.round((t - lid_id * 1.152e-6) / 46.08e-6)
    np.testing.assert_allclose(t, col * 46.08e-6 + lid_id * 1.152e-6, atol=1e-9)
    # clockwise rotation from +x: azimuth = -2 pi rate t
    az = np.arctan2(pts["y"], pts["x"])
    err = np.angle(np.exp(1j * (az + 2 * np.pi * rate * t)))
    assert np.abs(err).max() < 1e-4


def test_rate_changes_azimuth_steps(tmp_path: Path) -> None:
    for rate in (5.0, 20.0):
        lid = Lidar(_cfg(rate=rate))
        assert lid.spec.azimuth_steps == math.floor(1.0 / rate / 46.08e-6)


def test_organized_cloud(tmp_path: Path) -> None:
    lid, pts = _ground_turn(tmp_path, organized=True, noise_sigma=0.0)
    steps = lid.spec.azimuth_steps
    assert pts.shape == (32 * steps,)
    grid = pts.reshape(32, steps)
    np.testing.assert_array_equal(grid["ring"], np.arange(32)[:, None] * np.ones(steps))
    up = np.array(sorted(DATASHEET)) >= 0
    assert np.isnan(grid["x"][up]).all()
    assert np.isfinite(grid["x"][~up]).all()
    assert (grid["intensity"][up] == 0).all()


def test_dropout_and_intensity(tmp_path: Path) -> None:
    _, full = _ground_turn(tmp_path, noise_sigma=0.0)
    _, dropped = _ground_turn(tmp_path, noise_sigma=0.0, dropout=0.3)
    frac = dropped.shape[0] / full.shape[0]
    assert 0.67 < frac < 0.73
    # flat ground, reflectivity 0.5: intensity = 255 * 0.5 * cos(incidence) = 127.5 |z|/r,
    # reported as the sensor's integer codes by default (intensity_step 1)
    r = np.sqrt(full["x"] ** 2 + full["y"] ** 2 + full["z"] ** 2)
    want = 127.5 * np.abs(full["z"]) / r
    codes = full["intensity"]
    np.testing.assert_array_equal(codes, np.rint(codes))
    assert np.abs(codes - want).max() <= 0.5 + 1e-3
    assert np.unique(codes).size > 20  # many levels, not a constant
    _, cont = _ground_turn(tmp_path, noise_sigma=0.0, intensity_step=0)
    np.testing.assert_allclose(cont["intensity"], want, rtol=1e-4)
    assert np.count_nonzero(cont["intensity"] != np.rint(cont["intensity"])) > 0.9 * want.size
    _, half = _ground_turn(tmp_path, noise_sigma=0.0, intensity_step=0.5)
    np.testing.assert_array_equal(half["intensity"] * 2, np.rint(half["intensity"] * 2))
    assert np.abs(half["intensity"] - want).max() <= 0.25 + 1e-3


def test_pointcloud2_roundtrip_through_rosbags(tmp_path: Path) -> None:
    from rosbags.rosbag1 import Reader as Reader1
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import Reader as Reader2
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2

    lid = Lidar(_cfg(rate=20.0))
    ctx = FakeContext(scene(plane()), LinearTrajectory((0, 0, H), duration=0.15), tmp_path)
    msgs = run_sensor(lid, ctx)
    assert [m.t_ns for m in msgs] == [0, 50_000_000, 100_000_000]
    for flavor in Flavor:
        store = MessageStore(flavor)
        path = tmp_path / f"bag_{flavor.value}"
        if flavor is Flavor.ROS1:
            with Writer1(path.with_suffix(".bag")) as w:
                conn = w.add_connection(
                    "/velodyne_points", msgs[0].msgtype, typestore=store.typestore
                )
                for m in msgs:
                    w.write(conn, ctx.stamp(m.t_ns), store.serialize(m.build(store), m.msgtype))
            reader = Reader1(path.with_suffix(".bag"))
        else:
            with Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
                conn = w.add_connection(
                    "/velodyne_points", msgs[0].msgtype, typestore=store.typestore
                )
                for m in msgs:
                    w.write(conn, ctx.stamp(m.t_ns), store.serialize(m.build(store), m.msgtype))
            reader = Reader2(path)
        with reader as r:
            got = []
            for conn, ts, raw in r.messages():
                msg = (
                    store.typestore.deserialize_ros1(raw, conn.msgtype)
                    if flavor is Flavor.ROS1
                    else store.typestore.deserialize_cdr(raw, conn.msgtype)
                )
                got.append((ts, msg))
        assert len(got) == 3
        clouds = []
        for k, (ts, msg) in enumerate(got):
            stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            assert stamp == ts == ctx.start_time_ns + k * 50_000_000
            assert msg.header.frame_id == "velodyne"
            # velodyne_pointcloud XYZIRT layout
            layout = [(f.name, f.offset, f.datatype, f.count) for f in msg.fields]
            assert layout == [
                ("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1),
                ("intensity", 12, 7, 1), ("ring", 16, 4, 1), ("time", 18, 7, 1),
            ]  # fmt: skip
            assert msg.point_step == 22
            assert msg.height == 1
            assert msg.row_step == 22 * msg.width
            assert msg.is_bigendian is False
            dt = np.dtype({"names": ["x", "y", "z", "intensity", "ring", "time"],
                           "formats": ["<f4"] * 4 + ["<u2", "<f4"],
                           "offsets": [0, 4, 8, 12, 16, 18], "itemsize": 22})  # fmt: skip
            cloud = np.frombuffer(bytes(msg.data), dtype=dt)
            clouds.append(cloud)
            assert cloud.shape == (msg.width,)
            assert np.isfinite(cloud["x"]).all()
            rr = np.sqrt(cloud["x"] ** 2 + cloud["y"] ** 2 + cloud["z"] ** 2)
            assert (rr > 0.05).all()
            assert (rr <= 100).all()
            assert (cloud["time"] >= 0).all()
            assert (cloud["time"] < 0.05).all()
    # dataset files: one npz per scan with the same points as the cloud
    files = sorted((tmp_path / "lidar" / "velodyne").glob("*.npz"))
    assert [f.name for f in files] == ["000000.npz", "000001.npz", "000002.npz"]
    import zipfile

    with zipfile.ZipFile(files[1]) as zf:  # compressed scans (np.savez_compressed)
        assert {i.compress_type for i in zf.infolist()} == {zipfile.ZIP_DEFLATED}
    with np.load(files[1]) as z:
        assert int(z["stamp"]) == 50_000_000
        for name in ("x", "y", "z", "intensity", "ring", "time"):
            np.testing.assert_array_equal(z[name], clouds[1][name])
    lines = (tmp_path / "lidar" / "velodyne" / "timestamps.txt").read_text().splitlines()
    assert lines == ["0.000000000 velodyne/000000.npz", "0.050000000 velodyne/000001.npz",
                         "0.100000000 velodyne/000002.npz"]  # fmt: skip


def test_same_seed_same_bytes(tmp_path: Path) -> None:
    outs = []
    for k in range(2):
        lid = Lidar(_cfg(dropout=0.1))
        ctx = FakeContext(
            scene(plane()), LinearTrajectory((0, 0, H), duration=0.1), tmp_path / str(k)
        )
        msgs = run_sensor(lid, ctx)
        store = MessageStore(Flavor.ROS2)
        outs.append(store.serialize(msgs[0].build(store), msgs[0].msgtype))
        outs.append((tmp_path / str(k) / "lidar" / "velodyne" / "000000.npz").read_bytes())
    assert outs[0] == outs[2]
    assert outs[1] == outs[3]
    ctx = FakeContext(
        scene(plane()), LinearTrajectory((0, 0, H), duration=0.1), tmp_path / "s", seed=7
    )
    msgs = run_sensor(Lidar(_cfg(dropout=0.1)), ctx)
    store = MessageStore(Flavor.ROS2)
    assert store.serialize(msgs[0].build(store), msgs[0].msgtype) != outs[0]


def test_vlp16_and_custom(tmp_path: Path) -> None:
    vlp = Lidar(_cfg(preset="vlp16"))
    assert vlp.spec.n_lasers == 16
    assert vlp.spec.azimuth_steps == math.floor(0.1 / 55.296e-6)
    custom = Lidar(_cfg(preset="custom", elevations_deg=[-10, -20, 5], azimuth_steps=360,
                        rate=4.0, noise_sigma=0.0))  # fmt: skip
    ctx = FakeContext(scene(plane()), LinearTrajectory((0, 0, 2.0)), tmp_path)
    pts = custom.scan(ctx.trajectory, ctx.raycaster(), 0, ctx.rng("c"))
    assert pts.shape[0] == 2 * 360
    assert set(np.unique(pts["ring"]).tolist()) == {0, 1}  # -20 -> ring 0, -10 -> ring 1
    r = np.sqrt(pts["x"] ** 2 + pts["y"] ** 2 + pts["z"] ** 2)
    np.testing.assert_allclose(r[pts["ring"] == 0], 2.0 / math.sin(math.radians(20)), rtol=1e-5)
    assert pts["time"].max() < 0.25


@pytest.mark.parametrize(
    ("data", "key"),
    [
        ({"preset": "hdl64"}, "preset"),
        ({"rate": 25.0}, "rate"),
        ({"rate": 4.0}, "rate"),
        ({"noise_sigma": -0.01}, "noise_sigma"),
        ({"dropout": 1.5}, "dropout"),
        ({"preset": "custom"}, "elevations_deg"),
        ({"elevations_deg": [1.0, 2.0]}, "elevations_deg"),
        ({"preset": "custom", "elevations_deg": [95.0], "azimuth_steps": 10}, "elevations_deg"),
        ({"min_range": 5.0, "max_range": 2.0}, "min_range"),
        ({"azimuth_steps": 4000}, "azimuth_steps"),
        ({"organised": True}, "organised"),
    ],
)
def test_bad_config_names_the_key(data: dict[str, object], key: str) -> None:
    with pytest.raises(ConfigError) as err:
        _cfg(**data)
    text = str(err.value)
    assert "sim.yaml" in text
    assert key in text


_ROS1_SCRIPT = """
import sys, json, rosbag
from sensor_msgs import point_cloud2
out = []
for topic, msg, t in rosbag.Bag(sys.argv[1]).read_messages():
    names = ("x", "y", "z", "intensity", "ring", "time")
    pts = list(point_cloud2.read_points(msg, field_names=names))
    out.append({"stamp": msg.header.stamp.to_nsec(), "t": t.to_nsec(), "n": len(pts),
                "fields": [(f.name, f.offset, f.datatype) for f in msg.fields],
                "first": [float(v) for v in pts[0]], "md5": msg._md5sum})
print(json.dumps(out))
"""


@pytest.mark.ros1
def test_ros1_native_reader_reads_the_cloud(tmp_path: Path) -> None:
    import json
    import shutil
    import subprocess

    from rosbags.rosbag1 import Writer as Writer1

    py = shutil.which("python3", path="/usr/bin")
    if py is None:
        pytest.skip("/usr/bin/python3 not found")
    probe = subprocess.run(
        [py, "-c", "import rosbag, sensor_msgs.point_cloud2"], capture_output=True
    )
    if probe.returncode != 0:
        pytest.skip("Debian's python3-rosbag / sensor_msgs are not installed for /usr/bin/python3")
    lid = Lidar(_cfg(rate=20.0))
    ctx = FakeContext(scene(plane()), LinearTrajectory((0, 0, H), duration=0.1), tmp_path)
    msgs = run_sensor(lid, ctx)
    store = MessageStore(Flavor.ROS1)
    bag = tmp_path / "cloud.bag"
    with Writer1(bag) as w:
        conn = w.add_connection("/velodyne_points", msgs[0].msgtype, typestore=store.typestore)
        for m in msgs:
            w.write(conn, ctx.stamp(m.t_ns), store.serialize(m.build(store), m.msgtype))
    script = tmp_path / "read.py"
    script.write_text(_ROS1_SCRIPT)
    proc = subprocess.run([py, str(script), str(bag)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout)
    assert len(got) == 2
    first = np.load(tmp_path / "lidar" / "velodyne" / "000000.npz")
    assert got[0]["stamp"] == got[0]["t"] == ctx.start_time_ns
    assert got[0]["n"] == first["x"].shape[0]
    assert [tuple(f) for f in got[0]["fields"]] == [
        ("x", 0, 7), ("y", 4, 7), ("z", 8, 7),
        ("intensity", 12, 7), ("ring", 16, 4), ("time", 18, 7),
    ]  # fmt: skip
    expected = [float(first[k][0]) for k in ("x", "y", "z", "intensity", "ring", "time")]
    np.testing.assert_allclose(got[0]["first"], expected, rtol=1e-6)
    assert got[0]["md5"] == "1158d486dd51d683ce2f1be655c3c181"  # sensor_msgs/PointCloud2
