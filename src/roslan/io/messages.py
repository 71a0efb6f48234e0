"""ROS message construction for both bag flavours.

ROS 1 and ROS 2 share message *names* but not all definitions (ROS 1's Header has
``seq``; time types differ), so every message is built against the typestore of
the flavour being written. Sensors describe a message once, as a function of a
:class:`MessageStore`; the pipeline calls it for each flavour it writes.

Extra types roslan publishes that are not in the stock stores (``dvs_msgs`` of
rpg_dvs_ros; ``vision_msgs``, whose ROS 1 and ROS 2 definitions differ, from
:mod:`roslan.io.vision_msgdefs`) are registered here, with definitions identical to the originals so
their ROS 1 md5sums match and every ROS tool decodes them.
"""

from __future__ import annotations

import struct
from enum import StrEnum
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

__all__ = ["EXTRA_MSGDEFS", "Flavor", "MessageStore"]


class Flavor(StrEnum):
    """Which ROS generation a bag is written for."""

    ROS1 = "ros1"
    ROS2 = "ros2"


# rpg_dvs_ros/dvs_msgs, verbatim field lists (comments dropped).
EXTRA_MSGDEFS: dict[str, str] = {
    "dvs_msgs/msg/Event": "uint16 x\nuint16 y\ntime ts\nbool polarity\n",
    "dvs_msgs/msg/EventArray": (
        "Header header\nuint32 height\nuint32 width\ndvs_msgs/Event[] events\n"
    ),
    # tf2_msgs is missing from rosbags' ROS 1 Noetic store (ROS 2 stores have it).
    "tf2_msgs/msg/TFMessage": "geometry_msgs/TransformStamped[] transforms\n",
}

_UINT8_SEQUENCE = (Nodetype.SEQUENCE, ((Nodetype.BASE, ("uint8", 0)), 0))
_NO_BYTES = np.zeros(0, dtype=np.uint8)

_STORES = {Flavor.ROS1: Stores.ROS1_NOETIC, Flavor.ROS2: Stores.ROS2_HUMBLE}


def _vision_types(flavor: Flavor, have: Any) -> dict[str, Any]:
    """The flavour's vision_msgs types (:mod:`roslan.io.vision_msgdefs`) not in ``have``."""
    from roslan.io.vision_msgdefs import ROS1_VISION_MSG_TEXTS, ROS2_VISION_MSGDEFS

    out: dict[str, Any] = {}
    if flavor is Flavor.ROS1:
        for short, text in ROS1_VISION_MSG_TEXTS.items():
            pkg, typ = short.split("/")
            name = f"{pkg}/msg/{typ}"
            if name not in have:
                out.update(get_types_from_msg(text, name))
    else:
        for name, text in ROS2_VISION_MSGDEFS.items():
            if name not in have:
                out.update(get_types_from_msg(text, name))
    return out


class MessageStore:
    """Typestore of one flavour plus small constructors for common pieces."""

    def __init__(self, flavor: Flavor) -> None:
        self.flavor = flavor
        ts = get_typestore(_STORES[flavor])
        extra: dict[str, Any] = {}
        for name, text in EXTRA_MSGDEFS.items():
            if name in ts.types:  # the stock store already has it
                continue
            if flavor is Flavor.ROS2:
                text = text.replace("Header header", "std_msgs/Header header").replace(
                    "time ts", "builtin_interfaces/Time ts"
                )
            extra.update(get_types_from_msg(text, name))
        extra.update(_vision_types(flavor, ts.types))
        ts.register(extra)
        self.typestore: Typestore = ts
        self.types = ts.types
        self._Time = ts.types["builtin_interfaces/msg/Time"]
        self._Header = ts.types["std_msgs/msg/Header"]

    @property
    def is_ros1(self) -> bool:
        return self.flavor is Flavor.ROS1

    def time(self, ns: int) -> Any:
        """builtin_interfaces/Time from absolute integer nanoseconds."""
        sec, nsec = divmod(int(ns), 1_000_000_000)
        return self._Time(sec=sec, nanosec=nsec)

    def header(self, stamp_ns: int, frame_id: str, seq: int = 0) -> Any:
        """std_msgs/Header stamped at absolute ``stamp_ns``."""
        if self.is_ros1:
            return self._Header(seq=seq, stamp=self.time(stamp_ns), frame_id=frame_id)
        return self._Header(stamp=self.time(stamp_ns), frame_id=frame_id)

    def new(self, msgtype: str, **fields: Any) -> Any:
        """Instantiate message ``msgtype`` (e.g. ``'sensor_msgs/msg/Imu'``)."""
        return self.types[msgtype](**fields)

    def serialize(self, msg: Any, msgtype: str) -> bytes:
        """Wire bytes for this flavour (ROS 1 serialization or CDR)."""
        if self.is_ros1:
            return bytes(self.typestore.serialize_ros1(msg, msgtype))
        return bytes(self.typestore.serialize_cdr(msg, msgtype))

    def encode(self, build: Any, msgtype: str) -> bytes | bytearray | memoryview:
        """Wire bytes of one message described by ``build`` (``Message.build``: a callable
        of the store returning a message object or ready wire bytes)."""
        data = build(self)
        if isinstance(data, bytes | bytearray | memoryview):
            return data
        return self.serialize(data, msgtype)

    def image(
        self, frame_id: str, stamp_ns: int, data: NDArray[Any], encoding: str, seq: int = 0
    ) -> bytes:
        """Wire bytes of a sensor_msgs/Image of ``data`` (H, W[, C]), any dtype, row-major,
        little-endian; ``step`` = bytes per row; the pixels are appended once."""
        h = int(data.shape[0])
        flat = np.ascontiguousarray(data).view(np.uint8).reshape(-1)
        return self.serialize_with_blob(
            "sensor_msgs/msg/Image",
            flat,
            header=self.header(stamp_ns, frame_id, seq),
            height=h,
            width=int(data.shape[1]),
            encoding=encoding,
            is_bigendian=0,
            step=flat.size // h,
        )

    def serialize_with_blob(self, msgtype: str, blob: NDArray[np.uint8], **fields: Any) -> bytes:
        """Wire bytes of ``msgtype`` whose *last* field is the ``uint8[]`` ``blob`` (Image,
        CompressedImage data): the other fields go through the serializer, the blob is
        appended once (rosbags would copy it through its serializer and ``bytes()``;
        the bytes are the same: length prefix, then the data, in both flavours).

        Args:
            msgtype: e.g. ``'sensor_msgs/msg/Image'``.
            blob: the last field's bytes, any shape, C-contiguous uint8.
            fields: every other field of the message.
        """
        name, desc = self.typestore.fielddefs[msgtype][1][-1]
        if desc != _UINT8_SEQUENCE:
            msg = f"{msgtype}: last field {name!r} is not uint8[]"
            raise TypeError(msg)
        empty = self.serialize(self.new(msgtype, **{name: _NO_BYTES}, **fields), msgtype)
        data = np.ascontiguousarray(blob, dtype=np.uint8).reshape(-1)
        # the empty sequence serializes as its u32 length 0, last (CDR: 4-aligned, no tail)
        return b"".join((empty[:-4], struct.pack("<I", data.size), data.data))
