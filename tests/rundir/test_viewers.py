"""What a run offers the viewers: the latched /scene in both bags (judged by ROS 1's own
rosbag and the independent mcap reader), landing.rviz / landing.foxglove.json naming the
bag's topics, and ``roslan view --save`` (Rerun) with an entity for every sensor."""

from __future__ import annotations

import json
import shutil
import struct
import subprocess
import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from pipeline_helpers import short_config
from roslan.io.messages import Flavor, MessageStore
from roslan.scene.loader import load_scene
from roslan.scene.markers import SCENE_MSGTYPE, scene_marker_bytes, scene_mesh

SENSORS: list[dict[str, Any]] = [
    {"type": "imu", "name": "imu", "rate": 100.0, "topic": "/imu"},
    {
        "type": "event_camera",
        "name": "dvs",
        "rate": 10.0,
        "topic": "/dvs",
        "resolution": [48, 36],
        "max_rate": 60.0,
        "min_rate": 30.0,
        "pose": {"position": [0.1, 0.0, 0.0], "rpy": [0.0, 0.5, 0.0]},
    },
    {
        "type": "camera",
        "name": "camera",
        "rate": 5.0,
        "topic": "/camera",
        "resolution": [64, 48],
        "fx": 40.0,
        "pose": {"position": [0.1, 0.0, 0.0], "rpy": [0.0, 0.5, 0.0]},
    },
    {
        "type": "lidar",
        "name": "velodyne",
        "preset": "vlp16",
        "rate": 5.0,
        "topic": "/velodyne_points",
    },
    {"type": "sonar", "name": "sonar", "rate": 10.0, "topic": "/sonar", "axis": [0, 0, -1]},
]


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    pytest.importorskip("roslan.render.gl")
    from roslan.pipeline.run import run_simulation

    out = tmp_path_factory.mktemp("viewers") / "out"
    run_simulation(
        short_config(scene="warehouse", sensors=SENSORS), out, quiet=True, overview=False
    )
    return out


def _exported_triangles(out: Path) -> int:
    poses = yaml.safe_load((out / "scene" / "poses.yaml").read_text())
    return int(sum(o["triangles"] for o in poses["objects"]))


ROS1_SCRIPT = """
import sys, rosbag
bag = rosbag.Bag(sys.argv[1])
conns = [c for c in bag._get_connections(topics=["/scene"])]
print("latching", conns[0].header.get("latching").decode())
n = 0
for topic, msg, t in bag.read_messages(topics=["/scene"]):
    n += 1
    m = msg.markers[0]
    print("type", msg._type, m.type, m.header.frame_id, len(m.points), len(m.colors))
    print("first", m.points[0].x, m.points[0].y, m.points[0].z)
print("count", n)
"""


@pytest.mark.ros1
def test_ros1_rosbag_decodes_the_latched_scene(run: Path, tmp_path: Path) -> None:
    py = shutil.which("python3", path="/usr/bin")
    if py is None:
        pytest.skip("/usr/bin/python3 not found")
    probe = subprocess.run([py, "-c", "import rosbag, visualization_msgs.msg"], capture_output=True)
    if probe.returncode != 0:
        pytest.skip("Debian's python3-rosbag / python3-visualization-msgs are not installed")
    script = tmp_path / "scene.py"
    script.write_text(ROS1_SCRIPT)
    proc = subprocess.run(
        [py, str(script), str(run / "landing.bag")], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    rows = {ln.split()[0]: ln.split()[1:] for ln in proc.stdout.splitlines()}
    assert rows["latching"] == ["1"]
    assert rows["count"] == ["1"]
    msgtype, marker_type, frame, n_points, n_colors = rows["type"]
    assert msgtype == "visualization_msgs/MarkerArray"
    assert (marker_type, frame) == ("11", "world")  # TRIANGLE_LIST in the world frame
    assert int(n_points) == int(n_colors)
    assert int(n_points) % 3 == 0
    assert int(n_points) // 3 >= 0.9 * _exported_triangles(run)
    # the first triangle is the scene's first triangle (world coordinates)
    scene = load_scene(run / "scene" / "scene.yaml")
    v, f, _ = scene.triangles
    np.testing.assert_allclose([float(x) for x in rows["first"]], v[f[0, 0]], atol=1e-6)


def test_mcap_scene_is_transient_local(run: Path) -> None:
    from mcap.reader import make_reader

    mcap = next((run / "landing_ros2").glob("*.mcap"))
    with mcap.open("rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        assert summary is not None
        chans = [c for c in summary.channels.values() if c.topic == "/scene"]
        assert len(chans) == 1
        qos = yaml.safe_load(chans[0].metadata["offered_qos_profiles"])
        assert qos[0]["durability"] == 1  # rmw: 1 TRANSIENT_LOCAL (2 volatile)
        assert summary.schemas[chans[0].schema_id].name == "visualization_msgs/msg/MarkerArray"
        msgs = list(reader.iter_messages(topics=["/scene"]))
    assert len(msgs) == 1
    from rosbags.typesys import Stores, get_typestore

    msg = get_typestore(Stores.ROS2_HUMBLE).deserialize_cdr(msgs[0][2].data, SCENE_MSGTYPE)
    assert len(msg.markers[0].points) // 3 >= 0.9 * _exported_triangles(run)
    meta = yaml.safe_load((run / "landing_ros2" / "metadata.yaml").read_text())
    topics = meta["rosbag2_bagfile_information"]["topics_with_message_count"]
    scene = next(t for t in topics if t["topic_metadata"]["name"] == "/scene")
    assert "durability: 1" in scene["topic_metadata"]["offered_qos_profiles"]


@pytest.mark.parametrize("flavor", list(Flavor))
def test_marker_bytes_equal_rosbags_serialization(flavor: Flavor) -> None:
    """The spliced points/colours give the bytes rosbags' own serializer writes."""
    from roslan.scene.mesh import box, place
    from roslan.scene.model import Material, Scene

    store = MessageStore(flavor)
    scene = Scene("s", (place("b", box((1.0, 2.0, 3.0)), Material(color=(0.2, 0.5, 0.9))),))
    mesh = scene_mesh(scene)
    data = scene_marker_bytes(store, 1_700_000_000_123_456_789, mesh)
    ts = store.typestore
    msg = (
        ts.deserialize_ros1(data, SCENE_MSGTYPE)
        if store.is_ros1
        else ts.deserialize_cdr(data, SCENE_MSGTYPE)
    )
    pts = np.array([[p.x, p.y, p.z] for p in msg.markers[0].points])
    np.testing.assert_array_equal(pts, mesh.corners.reshape(-1, 3))
    again = store.serialize(msg, SCENE_MSGTYPE)
    assert again == data


def test_large_scene_is_simplified_to_the_budget() -> None:
    scene = load_scene("warehouse")
    whole = scene_mesh(scene)
    assert whole.n_triangles == scene.n_triangles  # default scenes go in whole
    small = scene_mesh(scene, budget=5000)
    assert 2500 < small.n_triangles <= 5000
    # clustered vertices stay inside the scene's bounds
    c = small.corners.reshape(-1, 3)
    assert np.all(c >= scene.bounds[0] - 1e-6)
    assert np.all(c <= scene.bounds[1] + 1e-6)


def _strings(node: Any) -> list[str]:
    if isinstance(node, dict):
        return [s for v in node.values() for s in _strings(v)]
    if isinstance(node, list):
        return [s for v in node for s in _strings(v)]
    return [node] if isinstance(node, str) else []


def test_layouts_name_only_the_bag_topics(run: Path) -> None:
    from rosbags.highlevel import AnyReader

    with AnyReader([run / "landing.bag"]) as reader:
        bag_topics = {c.topic for c in reader.connections}
    rviz = yaml.safe_load((run / "landing.rviz").read_text())
    manager = rviz["Visualization Manager"]
    assert manager["Global Options"]["Fixed Frame"] == "world"
    named = {v for d in manager["Displays"] for k, v in d.items() if k.endswith("Topic")}
    assert named <= bag_topics
    assert {"/scene", "/ground_truth/odometry", "/velodyne_points", "/camera/image_raw"} <= named
    assert {"/dvs/image_raw", "/dvs/event_image"} <= named  # APS frames, events as an image
    classes = {d["Class"] for d in manager["Displays"]}
    assert {"rviz/MarkerArray", "rviz/Odometry", "rviz/PointCloud2", "rviz/Camera"} <= classes
    fox = json.loads((run / "landing.foxglove.json").read_text())
    mentioned = {s.split(".")[0] for s in _strings(fox) if s.startswith("/")}
    mentioned |= {t for panel in fox["configById"].values() for t in panel.get("topics", {})}
    assert mentioned <= bag_topics
    assert {"/scene", "/velodyne_points", "/camera/image_raw", "/imu", "/sonar"} <= mentioned


def test_view_save_writes_a_verified_recording(run: Path, tmp_path: Path) -> None:
    pytest.importorskip("rerun")
    from roslan.cli import main

    out = tmp_path / "landing.rrd"
    assert main(["view", str(run), "--save", str(out)]) == 0
    assert out.stat().st_size > 0
    assert not (tmp_path / "landing.rrd.tmp").exists()
    # the CLI the rerun-sdk wheel installs beside this interpreter
    cli = Path(sys.executable).parent / "rerun"
    exe = str(cli) if cli.is_file() else shutil.which("rerun")
    assert exe is not None, "the rerun CLI of rerun-sdk is not installed"
    proc = subprocess.run(
        [exe, "rrd", "verify", str(out)], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    assert "verified without error" in proc.stdout + proc.stderr
    from rerun.chunk import RrdReader

    schema = str(RrdReader(str(out)).store().schema())
    # one timeline, the trajectory's: no wall-clock log_time (the data depends on OUTDIR alone)
    assert "Index(timeline:trajectory_time)" in schema
    assert "log_time" not in schema
    assert "log_tick" not in schema
    entities = {ln.split(":", 1)[1].strip() for ln in schema.splitlines() if "Entity path:" in ln}
    for sensor in SENSORS:
        assert any(e.startswith(f"/world/base_link/{sensor['name']}/") for e in entities), sensor
    assert "/world/scene" in entities
    assert "/world/base_link" in entities
    assert "/world/trajectory" in entities
    assert any(e.endswith("/events") for e in entities)
    assert any(e.endswith("/scan") for e in entities)
    assert any(e.endswith("/accel") for e in entities)
    assert any(e.endswith("/range") for e in entities)


def _rerun_cli() -> str:
    cli = Path(sys.executable).parent / "rerun"
    exe = str(cli) if cli.is_file() else shutil.which("rerun")
    assert exe is not None, "the rerun CLI of rerun-sdk is not installed"
    return exe


def test_view_save_twice_gives_the_same_recording(run: Path, tmp_path: Path) -> None:
    """Same OUTDIR, same recording: the same file, byte for byte, with every row id
    stamped from the run (its start time and the row's rank), not the wall clock. The two
    saves run in one process, the second after the first; no warning says the file could
    not be made canonical."""
    pytest.importorskip("rerun")
    from rerun.chunk import RrdReader

    from roslan.cli import main

    a, b = tmp_path / "a.rrd", tmp_path / "b.rrd"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["view", str(run), "--save", str(a)]) == 0
        assert main(["view", str(run), "--save", str(b)]) == 0
    assert not list(tmp_path.glob("*.raw"))
    ba, bb = a.read_bytes(), b.read_bytes()
    assert len(ba) > 10_000
    assert ba == bb
    chunks = [c.to_record_batch() for c in RrdReader(str(a)).stream().to_chunks()]
    assert len(chunks) > 10
    start = json.loads((run / "run.json").read_text())["start_time_ns"]
    ids = np.concatenate(
        [np.frombuffer(x.column("rerun.controls.RowId").buffers()[1], ">u8") for x in chunks]
    ).reshape(-1, 2)
    assert (ids[:, 0] == start).all()  # stamped with the run's start, not the wall clock
    assert sorted(ids[:, 1].tolist()) == list(range(1, len(ids) + 1))
    # the store-info message's row id: (start, 0), after 12 + 16 + 2 bytes of headers
    assert struct.unpack_from("<BQBQ", ba, 30) == (0x09, start, 0x11, 0)


def test_view_without_display_or_extra_is_clear(
    run: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import builtins

    from roslan.cli import main

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["view", str(run)]) == 2
    assert "--save FILE.rrd" in capsys.readouterr().err
    real_import = builtins.__import__

    def no_rerun(name: str, *args: Any, **kwargs: Any) -> Any:
        if name == "rerun" or name.startswith("rerun."):
            raise ImportError(name)
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_rerun)
    assert main(["view", str(run), "--save", str(run.parent / "x.rrd")]) == 2
    assert "pip install 'roslan[view]'" in capsys.readouterr().err
