"""``dvs_msgs/EventArray`` (rpg_dvs_ros) wire bytes packed straight from NumPy arrays.

One numba pass per packet writes the events' bytes into the message buffer, never one
Python object per event; the bytes equal what ``rosbags`` serializes for the same
message (tests compare them).

ROS 1: header (seq, stamp, frame_id), height, width, uint32 count, then 13 packed bytes
per event (x, y: uint16; ts: uint32 sec, uint32 nsec; polarity: uint8).

ROS 2 (CDR, little endian): alignment counts from the byte after the 4-byte
encapsulation header. The event sequence starts 4-aligned, so event 0 is 13 packed
bytes; every later event starts 2 mod 4 and is laid out as
``pad, x, y, pad2, sec, nsec, polarity`` = 16 bytes (its ``ts.sec`` realigned to 4);
no padding follows the last one.
"""

from __future__ import annotations

import functools
import struct
from typing import Any

import numpy as np
from numpy.typing import NDArray

from roslan.io.messages import Flavor

__all__ = ["EVENT_ARRAY", "pack_event_array"]

EVENT_ARRAY = "dvs_msgs/msg/EventArray"

_ROS1_EVENT = np.dtype([("x", "<u2"), ("y", "<u2"), ("sec", "<u4"), ("nsec", "<u4"), ("p", "u1")])
_CDR_EVENT = np.dtype(
    {
        "names": ["x", "y", "sec", "nsec", "p"],
        "formats": ["<u2", "<u2", "<u4", "<u4", "u1"],
        "offsets": [1, 3, 7, 11, 15],
        "itemsize": 16,
    }
)
"""A CDR event after the first (``ts.sec`` is int32 on the wire: the same bytes)."""
_NS = 1_000_000_000


@functools.cache
def _pack_events() -> Any:
    """The numba packing kernel (imported, i.e. compiled or loaded from numba's cache, on
    first use)."""
    from roslan.events._kernels import pack_events

    return pack_events


def pack_event_array(
    flavor: Flavor,
    stamp_ns: int,
    frame_id: str,
    height: int,
    width: int,
    t_ns: NDArray[np.int64],
    x: NDArray[np.integer],
    y: NDArray[np.integer],
    p: NDArray[np.integer],
    seq: int = 0,
    t_offset: int = 0,
) -> bytes:
    """Serialize one EventArray.

    Args:
        flavor: ROS 1 or ROS 2 (CDR).
        stamp_ns: absolute header stamp, ns.
        frame_id: header frame.
        height, width: sensor size, px.
        t_ns: (N,) event stamps, ns (absolute once ``t_offset`` is added).
        x, y: (N,) pixel column / row; p: (N,) polarity (> 0: ON).
        seq: ROS 1 header sequence number.
        t_offset: ns added to every ``t_ns`` (e.g. trajectory times to absolute stamps).
    """
    n = int(t_ns.shape[0])
    fid = frame_id.encode()
    s_sec, s_nsec = divmod(int(stamp_ns), _NS)
    if flavor is Flavor.ROS1:
        head = struct.pack("<4I", seq, s_sec, s_nsec, len(fid)) + fid
        body = 13 * n
    else:
        # CDR: positions relative to the byte after the encapsulation header
        head = b"\x00\x01\x00\x00" + struct.pack("<i2I", s_sec, s_nsec, len(fid) + 1) + fid
        head += b"\x00" * (1 + (-(13 + len(fid)) % 4))  # the string's NUL, then alignment
        body = 13 + 16 * (n - 1) if n else 0
    head += struct.pack("<3I", height, width, n)
    if n == 0:
        return head
    h = len(head)
    if flavor is Flavor.ROS1:
        out = np.empty(h + body, np.uint8)
        rec = _ROS1_EVENT
    else:
        out = np.zeros(h + body, np.uint8)  # CDR's padding bytes
        rec = _CDR_EVENT
    out[:h] = np.frombuffer(head, np.uint8)
    first, rest = out[h : h + 13].view(_ROS1_EVENT), out[h + 13 :].view(rec)
    t = np.asarray(t_ns, dtype=np.int64)
    _pack_events()(t, t_offset, np.asarray(x), np.asarray(y), np.asarray(p), first, rest)
    return out.tobytes()
