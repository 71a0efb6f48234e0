"""MessageStore.serialize_with_blob: the same bytes as rosbags' serializer, both flavours."""

from __future__ import annotations

import numpy as np
import pytest

from roslan.io.messages import Flavor, MessageStore


@pytest.mark.parametrize("flavor", list(Flavor))
@pytest.mark.parametrize("n", [0, 1, 3, 7, 640 * 480 * 3])
def test_image_with_blob_equals_serializer(flavor: Flavor, n: int) -> None:
    store = MessageStore(flavor)
    rng = np.random.default_rng(n)
    data = rng.integers(0, 256, n, dtype=np.uint8)
    fields = {
        "header": store.header(1_700_000_000_123_456_789, "cam_optical", 7),
        "height": 1,
        "width": n,
        "encoding": "mono8",
        "is_bigendian": 0,
        "step": n,
    }
    ref = store.serialize(
        store.new("sensor_msgs/msg/Image", data=data, **fields), "sensor_msgs/msg/Image"
    )
    assert store.serialize_with_blob("sensor_msgs/msg/Image", data, **fields) == ref


@pytest.mark.parametrize("flavor", list(Flavor))
@pytest.mark.parametrize("fmt", ["png", "jpeg", "x"])  # string lengths: CDR pads before data
def test_compressed_image_with_blob_equals_serializer(flavor: Flavor, fmt: str) -> None:
    store = MessageStore(flavor)
    data = np.arange(11, dtype=np.uint8).reshape(1, 11)  # any shape: its bytes
    fields = {"header": store.header(5, "f"), "format": fmt}
    msgtype = "sensor_msgs/msg/CompressedImage"
    ref = store.serialize(store.new(msgtype, data=data.ravel(), **fields), msgtype)
    assert store.serialize_with_blob(msgtype, data, **fields) == ref
    back = (
        store.typestore.deserialize_ros1(ref, msgtype)
        if store.is_ros1
        else (store.typestore.deserialize_cdr(ref, msgtype))
    )
    assert back.format == fmt
    assert bytes(back.data) == data.tobytes()


def test_blob_must_be_the_last_uint8_field() -> None:
    store = MessageStore(Flavor.ROS1)
    with pytest.raises(TypeError, match="last field 'pose' is not uint8"):
        store.serialize_with_blob("geometry_msgs/msg/PoseStamped", np.zeros(3, np.uint8))


@pytest.mark.parametrize("flavor", list(Flavor))
def test_image_message_decodes_to_the_array(flavor: Flavor) -> None:
    store = MessageStore(flavor)
    flow = np.random.default_rng(1).normal(size=(5, 7, 2)).astype(np.float32)  # 32FC2
    raw = store.image("dvs_optical", 1_700_000_000_000_000_042, flow, "32FC2", seq=3)
    de = store.typestore.deserialize_ros1 if store.is_ros1 else store.typestore.deserialize_cdr
    msg = de(raw, "sensor_msgs/msg/Image")
    assert (msg.height, msg.width, msg.step, msg.encoding) == (5, 7, 7 * 8, "32FC2")
    assert msg.header.frame_id == "dvs_optical"
    assert msg.header.stamp.sec == 1_700_000_000
    assert msg.header.stamp.nanosec == 42
    np.testing.assert_array_equal(np.frombuffer(msg.data, np.float32).reshape(5, 7, 2), flow)
