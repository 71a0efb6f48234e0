"""``dvs_msgs/EventArray`` (rpg_dvs_ros) wire bytes packed straight from NumPy arrays.

One structured-dtype assignment per packet, never one Python object per event; the
bytes equal what ``rosbags`` serializes for the same message (tests compare them).

ROS 1: header (seq, stamp, frame_id), height, width, uint32 count, then 13 packed bytes
per event (x, y: uint16; ts: uint32 sec, uint32 nsec; polarity: uint8).

ROS 2 (CDR, little endian): alignment counts from the byte after the 4-byte
encapsulation header. The event sequence starts 4-aligned, so event 0 is 13 packed
bytes; every later event starts 2 mod 4 and is laid out as
``pad, x, y, pad2, sec, nsec, polarity`` = 16 bytes (its ``ts.sec`` realigned to 4);
no padding follows the last one.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from roslan.io.messages import Flavor

__all__ = ["EVENT_ARRAY", "pack_event_array"]

EVENT_ARRAY = "dvs_msgs/msg/EventArray"

_ROS1_EVENT = np.dtype([("x", "<u2"), ("y", "<u2"), ("sec", "<u4"), ("nsec", "<u4"), ("p", "u1")])
_CDR_EVENT = np.dtype(
    {
        "names": ["x", "y", "sec", "nsec", "p"],
        "formats": ["<u2", "<u2", "<i4", "<u4", "u1"],
        "offsets": [1, 3, 7, 11, 15],
        "itemsize": 16,
    }
)
_NS = 1_000_000_000


def _sec_nsec(t: NDArray[np.int64]) -> tuple[int | NDArray[np.int64], NDArray[np.int64]]:
    """``t // 1e9, t % 1e9`` of sorted stamps: a packet within one second (nearly every
    one) takes one subtraction instead of two integer divisions (the same values)."""
    s0 = int(t[0]) // _NS
    if int(t[-1]) // _NS == s0:
        return s0, t - s0 * _NS
    return t // _NS, t % _NS


def _fill(
    rec: NDArray[np.void],
    x: NDArray[np.integer],
    y: NDArray[np.integer],
    sec: int | NDArray[np.int64],
    nsec: NDArray[np.int64],
    p: NDArray[np.integer],
) -> None:
    rec["x"] = x
    rec["y"] = y
    rec["sec"] = sec
    rec["nsec"] = nsec
    rec["p"] = np.asarray(p) > 0


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
) -> bytes:
    """Serialize one EventArray.

    Args:
        flavor: ROS 1 or ROS 2 (CDR).
        stamp_ns: absolute header stamp, ns.
        frame_id: header frame.
        height, width: sensor size, px.
        t_ns: (N,) absolute event stamps, ns, sorted.
        x, y: (N,) pixel column / row; p: (N,) polarity (> 0: ON).
        seq: ROS 1 header sequence number.
    """
    n = int(t_ns.shape[0])
    t = np.asarray(t_ns, dtype=np.int64)
    sec, nsec = _sec_nsec(t) if n else (t, t)
    fid = frame_id.encode()
    s_sec, s_nsec = divmod(int(stamp_ns), _NS)
    if flavor is Flavor.ROS1:
        head = np.array([seq, s_sec, s_nsec, len(fid)], dtype="<u4").tobytes() + fid
        head += np.array([height, width, n], dtype="<u4").tobytes()
        rec = np.empty(n, dtype=_ROS1_EVENT)
        _fill(rec, x, y, sec, nsec, p)
        return head + rec.tobytes()
    # CDR: positions relative to the byte after the encapsulation header
    head = (
        b"\x00\x01\x00\x00"
        + np.array([s_sec], "<i4").tobytes()
        + np.array([s_nsec, len(fid) + 1], "<u4").tobytes()
    )
    head += fid + b"\x00"
    pos = 12 + len(fid) + 1
    head += b"\x00" * (-pos % 4)
    head += np.array([height, width, n], dtype="<u4").tobytes()
    if n == 0:
        return head
    first = np.empty(1, dtype=_ROS1_EVENT)
    sec0, sec1 = (sec, sec) if isinstance(sec, int) else (sec[:1], sec[1:])
    _fill(first, x[:1], y[:1], sec0, nsec[:1], p[:1])
    rest = np.zeros(n - 1, dtype=_CDR_EVENT)
    _fill(rest, x[1:], y[1:], sec1, nsec[1:], p[1:])
    return head + first.tobytes() + rest.tobytes()
