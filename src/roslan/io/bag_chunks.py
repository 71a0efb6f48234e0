"""The records of one finished chunk, written once its compression is done.

rosbags writes a chunk's records as soon as the chunk is full, compressing it inline;
:mod:`roslan.io.bag` compresses chunks in a pool (:mod:`roslan.io.bag_threads`) and writes
each chunk's records here, in the order the chunks closed, with the same bytes rosbags
writes: ROS 1 bag v2.0 ``CHUNK`` + ``IDXDATA`` records, MCAP ``Chunk`` + ``MessageIndex``
records and the ``ChunkIndex`` record kept for the summary.
"""

from __future__ import annotations

import struct
from io import BytesIO
from typing import BinaryIO

from rosbags.rosbag1.reader import RecordType
from rosbags.rosbag1.writer import Header, WriteChunk, serialize_time
from rosbags.rosbag2.storage_mcap import (
    PendingChunk,
    write_record,
    write_string,
    write_uint16,
    write_uint32,
    write_uint64,
)

__all__ = ["write_mcap_chunk", "write_ros1_chunk"]

_U32 = struct.Struct("<L").pack
_U64X2 = struct.Struct("<QQ").pack


def write_ros1_chunk(bio: BinaryIO, compression: str, chunk: WriteChunk, data: bytes) -> None:
    """The ``CHUNK`` record of ``chunk`` (``data``: its compressed bytes) and one
    ``IDXDATA`` record per connection; sets ``chunk.pos`` and closes ``chunk.data``."""
    chunk.pos = bio.tell()
    header = Header()
    header.set_string("compression", compression)
    header.set_uint32("size", chunk.data.tell())
    header.write(bio, RecordType.CHUNK)
    bio.write(_U32(len(data)))
    bio.write(data)
    for cid, items in chunk.connections.items():
        header = Header()
        header.set_uint32("ver", 1)
        header.set_uint32("conn", cid)
        header.set_uint32("count", len(items))
        header.write(bio, RecordType.IDXDATA)
        bio.write(_U32(len(items) * 12))
        bio.write(b"".join(serialize_time(t) + _U32(off) for t, off in items))
    chunk.data.close()


def write_mcap_chunk(
    bio: BinaryIO, compression: str, chunk: PendingChunk, compressed: bytes
) -> BytesIO:
    """The ``Chunk`` record of ``chunk`` and its ``MessageIndex`` records; returns the
    body of its ``ChunkIndex`` record (written in the summary at close)."""
    rec = BytesIO()
    write_uint64(rec, chunk.message_start_time)
    write_uint64(rec, chunk.message_end_time)
    write_uint64(rec, chunk.bio.tell())
    write_uint32(rec, 0)
    write_string(rec, compression)
    write_uint64(rec, len(compressed))
    rec.write(compressed)
    chunk_start = bio.tell()
    write_record(bio, 0x06, rec)
    chunk_end = bio.tell()
    offsets: list[tuple[int, int]] = []
    for cid, msgs in chunk.msgs.items():
        offsets.append((cid, bio.tell()))
        rec = BytesIO()
        write_uint16(rec, cid)
        write_uint32(rec, len(msgs) * 16)
        rec.write(b"".join(_U64X2(ts, off) for ts, off in msgs))
        write_record(bio, 0x07, rec)
    rec = BytesIO()
    write_uint64(rec, chunk.message_start_time)
    write_uint64(rec, chunk.message_end_time)
    write_uint64(rec, chunk_start)
    write_uint64(rec, chunk_end - chunk_start)
    write_uint32(rec, len(offsets) * 10)
    for cid, offset in offsets:
        write_uint16(rec, cid)
        write_uint64(rec, offset)
    write_uint64(rec, bio.tell() - chunk_end)
    write_string(rec, compression)
    write_uint64(rec, len(compressed))
    write_uint64(rec, chunk.bio.tell())
    return rec
