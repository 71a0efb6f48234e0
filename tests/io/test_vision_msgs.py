"""vision_msgs in both bags: Detection2DArray and Detection3DArray written by roslan's bag
writer, read back by rosbags and by ROS 1's own rosbag (decoding from the definition the
bag stores: Debian has no vision_msgs package); md5 sums equal the published ones."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from roslan.frames import matrix_to_rpy, quat_xyzw_to_matrix
from roslan.io.bag import BagTopic, MultiBagWriter
from roslan.io.messages import Flavor, MessageStore
from roslan.io.ros1_msgdefs import ros1_full_text
from roslan.io.vision import (
    DETECTION2D_ARRAY,
    DETECTION3D_ARRAY,
    detection2d_array,
    detection3d_array,
)
from roslan.scene import load_scene
from roslan.scene.instances import scene_labels

STAMP = 1_700_000_000_123_456_789
BOXES = np.array([[10.0, 20.0, 30.5, 40.25], [0.0, 0.0, 1.0, 2.0], [100.5, 7.0, 3.0, 3.0]])
CLASSES = np.array([9, 10, 29])
INSTANCES = np.array([17, 300, 799])


def _objects() -> tuple[Any, ...]:
    """A few warehouse instances (rotated racks, boxes, the forklift) as 3-D boxes."""
    labels = scene_labels(load_scene("warehouse"))
    picks = [i for i in labels.instances if i.class_name in ("rack", "forklift", "pallet")][:12]
    return tuple(picks)


def _write(tmp_path: Path, flavor: Flavor) -> Path:
    objs = _objects()
    topics = [
        BagTopic("/camera/detections", DETECTION2D_ARRAY),
        BagTopic("/objects", DETECTION3D_ARRAY, True),
    ]
    w = MultiBagWriter(tmp_path, [flavor.value], topics)
    w.write(
        "/camera/detections",
        STAMP,
        lambda s: detection2d_array(s, STAMP, "camera_optical", BOXES, CLASSES, INSTANCES),
    )
    w.write(
        "/objects",
        STAMP,
        lambda s: detection3d_array(
            s,
            STAMP,
            "world",
            [o.center for o in objs],
            [o.size for o in objs],
            [o.rpy for o in objs],
            [o.class_id for o in objs],
            [o.id for o in objs],
        ),
    )
    w.close()
    return tmp_path / ("landing.bag" if flavor is Flavor.ROS1 else "landing_ros2")


@pytest.mark.parametrize("flavor", list(Flavor))
def test_detections_round_trip_through_rosbags(tmp_path: Path, flavor: Flavor) -> None:
    bag = _write(tmp_path, flavor)
    objs = _objects()
    with AnyReader([bag]) as reader:
        got = {c.topic: reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()}
        types = {c.topic: c.msgtype for c in reader.connections}
    assert types == {"/camera/detections": DETECTION2D_ARRAY, "/objects": DETECTION3D_ARRAY}
    d2: Any = got["/camera/detections"]
    assert d2.header.frame_id == "camera_optical"
    assert d2.header.stamp.sec * 10**9 + d2.header.stamp.nanosec == STAMP
    assert len(d2.detections) == len(BOXES)
    for det, b, c, inst in zip(d2.detections, BOXES, CLASSES, INSTANCES, strict=True):
        centre = det.bbox.center if flavor is Flavor.ROS1 else det.bbox.center.position
        assert (centre.x, centre.y) == (b[0] + b[2] / 2, b[1] + b[3] / 2)
        assert (det.bbox.size_x, det.bbox.size_y) == (b[2], b[3])
        (hyp,) = det.results
        if flavor is Flavor.ROS1:
            assert (hyp.id, hyp.score) == (c, 1.0)
            assert det.source_img.data.size == 0
        else:
            assert (hyp.hypothesis.class_id, hyp.hypothesis.score) == (str(c), 1.0)
            assert det.id == str(inst)
    d3: Any = got["/objects"]
    assert d3.header.frame_id == "world"
    assert len(d3.detections) == len(objs)
    for det, o in zip(d3.detections, objs, strict=True):
        p, q = det.bbox.center.position, det.bbox.center.orientation
        np.testing.assert_allclose([p.x, p.y, p.z], o.center, rtol=0, atol=1e-12)
        np.testing.assert_allclose([det.bbox.size.x, det.bbox.size.y, det.bbox.size.z], o.size)
        R = quat_xyzw_to_matrix(np.array([q.x, q.y, q.z, q.w]))
        np.testing.assert_allclose(matrix_to_rpy(R), o.rpy, atol=1e-12)
        (hyp,) = det.results
        assert (hyp.id if flavor is Flavor.ROS1 else int(hyp.hypothesis.class_id)) == o.class_id
        if flavor is Flavor.ROS2:
            assert det.id == str(o.id)


def test_ros1_md5_sums_are_the_published_ones() -> None:
    """The md5 sums rosbags computes from the Noetic fields equal those ROS 1's own
    generators publish for vision_msgs (as in generated client libraries)."""
    ts = MessageStore(Flavor.ROS1).typestore
    assert ts.generate_msgdef(DETECTION2D_ARRAY)[1] == "402071f61477de256df9f1aa45e6e4c8"
    assert ts.generate_msgdef(DETECTION3D_ARRAY)[1] == "05c51d9aea1fb4cfdc8effb94f197b6f"
    text = ros1_full_text(DETECTION2D_ARRAY) or ""
    for dep in (
        "vision_msgs/ObjectHypothesisWithPose",
        "geometry_msgs/Pose2D",
        "sensor_msgs/Image",
    ):
        assert f"\nMSG: {dep}\n" in text
    assert ros1_full_text(DETECTION3D_ARRAY) is not None


def test_ros2_definitions_differ_from_ros1_where_vision_msgs_do() -> None:
    fields = {
        f.value: dict(MessageStore(f).typestore.fielddefs["vision_msgs/msg/Detection2D"][1])
        for f in Flavor
    }
    assert set(fields["ros1"]) == {"header", "results", "bbox", "source_img"}
    assert set(fields["ros2"]) == {"header", "results", "bbox", "id"}
    hyp2 = dict(
        MessageStore(Flavor.ROS2).typestore.fielddefs["vision_msgs/msg/ObjectHypothesis"][1]
    )
    assert set(hyp2) == {"class_id", "score"}


def _debian_python() -> str:
    py = shutil.which("python3", path="/usr/bin")
    probe = subprocess.run([py or "/usr/bin/python3", "-c", "import rosbag"], capture_output=True)
    if py is None or probe.returncode != 0:
        pytest.skip("Debian's python3-rosbag is not installed for /usr/bin/python3")
    return py


_READ = """
import json, sys, rosbag, genpy
out = {}
with rosbag.Bag(sys.argv[1]) as bag:
    conns = {c.topic: c for c in bag._get_connections()}
    for topic, msg, t in bag.read_messages():
        assert isinstance(msg, genpy.Message), type(msg)
        msg._check_types()
        c = conns[topic]
        row = {"type": msg._type, "md5": msg._md5sum, "conn_md5": c.md5sum,
               "stamp": msg.header.stamp.to_nsec(), "frame": msg.header.frame_id}
        if msg._type == "vision_msgs/Detection2DArray":
            row["boxes"] = [[d.bbox.center.x, d.bbox.center.y, d.bbox.center.theta,
                             d.bbox.size_x, d.bbox.size_y, d.results[0].id, d.results[0].score]
                            for d in msg.detections]
        else:
            row["boxes"] = [[d.bbox.center.position.x, d.bbox.center.position.y,
                             d.bbox.center.position.z, d.bbox.size.x, d.bbox.size.y,
                             d.bbox.size.z, d.results[0].id] for d in msg.detections]
        out[topic] = row
print(json.dumps(out))
"""


def ros1_detections(bag: Path, topic: str) -> dict[str, Any]:
    """The last Detection2DArray/3DArray of ``topic`` in ``bag`` as ROS 1's own reader
    (Debian's python3-rosbag) decodes it: type, md5 sums and boxes (:data:`_READ`)."""
    script = _READ.replace("read_messages()", f"read_messages(topics=[{topic!r}])")
    proc = subprocess.run(
        [_debian_python(), "-c", script, str(bag)], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    row: dict[str, Any] = json.loads(proc.stdout)[topic]
    assert row["md5"] == row["conn_md5"]
    return row


@pytest.mark.ros1
def test_ros1_own_reader_decodes_the_detections(tmp_path: Path) -> None:
    py = _debian_python()
    has = subprocess.run([py, "-c", "import vision_msgs.msg"], capture_output=True)
    bag = _write(tmp_path, Flavor.ROS1)
    proc = subprocess.run([py, "-c", _READ, str(bag)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    rows = json.loads(proc.stdout)
    d2, d3 = rows["/camera/detections"], rows["/objects"]
    assert d2["type"] == "vision_msgs/Detection2DArray"
    assert d3["type"] == "vision_msgs/Detection3DArray"
    # the class ROS 1 built from the bag's stored definition has the md5 of the connection
    for row in (d2, d3):
        assert row["md5"] == row["conn_md5"]
        assert row["stamp"] == STAMP
    if has.returncode != 0:  # decoded from the bag's own definition, not an installed one
        assert d2["md5"] == "402071f61477de256df9f1aa45e6e4c8"
    expected2 = [
        [b[0] + b[2] / 2, b[1] + b[3] / 2, 0.0, b[2], b[3], int(c), 1.0]
        for b, c in zip(BOXES, CLASSES, strict=True)
    ]
    assert d2["boxes"] == expected2
    objs = _objects()
    expected3 = [[*o.center, *o.size, o.class_id] for o in objs]
    np.testing.assert_array_equal(np.array(d3["boxes"]), np.array(expected3))


@pytest.mark.ros1
def test_pose2d_text_is_the_installed_ros_text() -> None:
    py = _debian_python()
    proc = subprocess.run(
        [py, "-c", "import sys, geometry_msgs.msg as g; sys.stdout.write(g.Pose2D._full_text)"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    assert ros1_full_text("geometry_msgs/msg/Pose2D") == proc.stdout
