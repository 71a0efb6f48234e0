"""ROS 1 and ROS 2 bag writers behind one small interface.

Both write through :mod:`rosbags`: ROS 1 bags v2.0 (chunked, optional lz4/bz2 chunk
compression) and ROS 2 bags in MCAP storage. One connection per topic; the record
time of every message is its header stamp; latched topics (``/tf_static``) get
``latching=1`` in ROS 1 and a ``transient_local`` QoS profile in ROS 2, so players
re-deliver them to late subscribers.

Messages come as :class:`~roslan.sensors.base.Message`: ``build(store)`` returns a
message object of the flavour's typestore (serialized here) or the finished wire bytes.
"""

from __future__ import annotations

import contextlib
import struct
from collections import defaultdict
from collections.abc import Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from io import BytesIO
from pathlib import Path
from typing import Any, Literal, NamedTuple, Protocol

import lz4.frame
from rosbags.interfaces import (
    Connection,
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag1 import Writer as _Ros1Writer
from rosbags.rosbag1.writer import MAXSIZE, WriteChunk
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as _Ros2Writer
from rosbags.rosbag2.storage_mcap import McapWriter as _McapWriter
from rosbags.rosbag2.storage_mcap import PendingChunk

from roslan.errors import OutputError
from roslan.io.bag_chunks import write_mcap_chunk, write_ros1_chunk
from roslan.io.bag_threads import BagThread, OrderedChunks, chunk_pool
from roslan.io.messages import Flavor, MessageStore
from roslan.io.ros1_msgdefs import ros1_full_text

__all__ = [
    "BAG_NAMES",
    "BagTopic",
    "BagWriter",
    "MultiBagWriter",
    "Ros1BagWriter",
    "Ros2BagWriter",
]

BAG_NAMES = {Flavor.ROS1: "landing.bag", Flavor.ROS2: "landing_ros2"}
"""File (ROS 1) / folder (ROS 2) name of each flavour's bag inside OUTDIR."""

ROS2_BAG_VERSION: Literal[8, 9] = 8
"""rosbag2 metadata version written (8 = Humble/Iron; readable by every later distro)."""

ROS2_DISTRO = "humble"
"""The ROS 2 distribution whose message definitions the ROS 2 bag carries (rosbags'
Humble typestore); written as ``ros_distro`` in metadata.yaml and the MCAP metadata."""

ROS2_COMPRESSIONS = ("zstd", "lz4", "none")
"""MCAP chunk compressions of the ROS 2 bag (``output.ros2_compression``)."""

ZSTD_LEVEL = 1
"""zstd level of the MCAP chunks (1: about half the CPU of level 3, a 7 % larger bag)."""


class BagTopic(NamedTuple):
    """One connection: topic name, message type, and whether it is latched."""

    topic: str
    msgtype: str
    latched: bool = False


def _ros2_qos(latched: bool) -> list[Qos]:
    # rosbag2 (Humble+) records "infinite" (default) durations as these maxima.
    infinite = QosTime(2147483647, 4294967295)
    return [
        Qos(
            history=QosHistory.KEEP_LAST,
            depth=1 if latched else 10,
            reliability=QosReliability.RELIABLE,
            durability=QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE,
            deadline=infinite,
            lifespan=infinite,
            liveliness=QosLiveliness.AUTOMATIC,
            liveliness_lease_duration=infinite,
            avoid_ros_namespace_conventions=False,
        )
    ]


_U32 = struct.Struct("<L").pack
_SEC_NSEC_LEN = struct.Struct("<LLL").pack
_MCAP_MSG = struct.Struct("<BQHLQQ").pack
_NS = 1_000_000_000


_ROS1_LZ4_LEVEL = 0
"""lz4 level of the ROS 1 chunks: 0 = lz4's fast mode. HC level 3 made the default job's
bag 12 % smaller (146 vs 165 MB) for about 2.5 CPU-s more (7x the compression time); the
fast mode keeps the default OUTDIR within its budget (docs/performance.md). roslz4
decodes any level."""


def roslz4_compress(data: bytes, level: int = _ROS1_LZ4_LEVEL) -> bytes:
    """An lz4 frame roslz4 decodes (1 MiB independent blocks, content checksum, no size)."""
    out: bytes = lz4.frame.compress(
        data,
        compression_level=level,
        block_size=lz4.frame.BLOCKSIZE_MAX1MB,
        block_linked=False,
        content_checksum=True,
        store_size=False,
    )
    return out


class _FastRos1Writer(_Ros1Writer):
    """rosbags' ROS 1 writer; apart from the lz4 frame parameters its output is byte-identical:

    * lz4 chunks use the frame parameters ROS 1's roslz4 can decode;
    * ``write`` assembles the message-data record header from per-connection bytes
      prepared once (rosbags builds a dict and encodes it per message);
    * once a chunk is on disk its per-message (time, offset) index entries are replaced
      by their counts, the only thing ``close()`` still needs, so memory stays flat
      however long the bag is.
    """

    _prefix: dict[int, bytes]

    def set_compression(self, fmt: _Ros1Writer.CompressionFormat) -> None:
        super().set_compression(fmt)
        if self.compression_format == "lz4":
            # lz4.frame's defaults (content-size field, 64 KiB linked blocks) are rejected by
            # ROS 1's own roslz4 ("malformed data to decompress"); write the frame layout
            # roslz4 itself produces: independent 1 MiB blocks, content checksum, no size.
            self.compressor = roslz4_compress

    def write(self, connection: Connection, timestamp: int, data: bytes | memoryview) -> None:
        try:
            prefix = self._prefix[connection.id]
        except (AttributeError, KeyError):
            if connection not in self.connections:
                super().write(connection, timestamp, data)  # raises the library's error
                return
            if not hasattr(self, "_prefix"):
                self._prefix = {}
            # record header: op=0x02, conn=<u32>, time=<u32 sec, u32 nsec>  (38 bytes)
            prefix = self._prefix[connection.id] = (
                _U32(38)
                + _U32(4)
                + b"op=\x02"
                + _U32(9)
                + b"conn="
                + _U32(connection.id)
                + _U32(13)
                + b"time="
            )
        chunk = self.chunks[-1]
        bio = chunk.data
        chunk.connections[connection.id].append((timestamp, bio.tell()))
        if timestamp < chunk.start:
            chunk.start = timestamp
        if timestamp > chunk.end:
            chunk.end = timestamp
        sec, nsec = divmod(timestamp, _NS)
        bio.write(prefix + _SEC_NSEC_LEN(sec, nsec, len(data)))
        bio.write(data)
        if bio.tell() > self.chunk_threshold:
            self.write_chunk(chunk)

    _ordered: OrderedChunks | None = None
    _closing = False

    def set_pool(self, pool: ThreadPoolExecutor | None) -> None:
        """Compress chunks in ``pool`` (written in order: the same bytes as inline)."""
        self._ordered = OrderedChunks(pool, self.compressor, self._write_out)

    def write_chunk(self, chunk: WriteChunk) -> None:
        if self._ordered is None:
            self._ordered = OrderedChunks(None, self.compressor, self._write_out)
        if chunk.data.tell() == 0:
            return
        # the next chunk fills while this one is compressed (as rosbags: appended after it)
        self.chunks.append(WriteChunk(BytesIO(), -1, MAXSIZE, 0, defaultdict(list)))
        self._ordered.submit(chunk, chunk.data.getvalue(), now=self._closing)

    def _write_out(self, chunk: WriteChunk, data: bytes) -> None:
        assert self.bio is not None
        write_ros1_chunk(self.bio, self.compression_format, chunk, data)
        # close() only takes len() of each entry; range(n) is len-able and tiny.
        counts = {cid: range(len(items)) for cid, items in chunk.connections.items()}
        chunk.connections = counts  # type: ignore[assignment]

    def close(self) -> None:
        self._closing = True
        if self._ordered is not None:
            self._ordered.drain()
        super().close()

    def abort(self) -> None:
        if self._ordered is not None:
            self._ordered.cancel()
        super().abort()


def _mcap_compressor(name: str) -> Any:
    if name == "zstd":
        try:  # the standard library's from Python 3.14; before, rosbags' own dependency
            from compression import zstd  # type: ignore[import-not-found, unused-ignore]
        except ImportError:
            from backports import zstd

        # level 1: half the CPU of level 3 for a 7 % larger bag (docs/performance.md)
        return lambda data: zstd.compress(data, level=ZSTD_LEVEL)
    if name == "lz4":
        # MCAP's lz4: one lz4 frame per chunk (what the mcap libraries write and read)
        return lambda data: lz4.frame.compress(data, store_size=True)
    return lambda data: data


class _FastMcapWriter(_McapWriter):
    """rosbags' MCAP storage with a one-``struct.pack`` message record (same bytes), chunk
    compression ``zstd``/``lz4``/none (:data:`chunk_compression`, set before the first chunk
    closes) and ``ros_distro`` = :data:`ROS2_DISTRO` in the metadata record."""

    _ordered: OrderedChunks | None = None
    _closing = False

    def set_chunk_compression(self, name: str, pool: ThreadPoolExecutor | None = None) -> None:
        """Chunk compression ``name``, chunks compressed in ``pool`` (None: inline)."""
        if name not in ROS2_COMPRESSIONS:
            msg = f"ROS 2 chunk compression {name!r}: use one of {', '.join(ROS2_COMPRESSIONS)}"
            raise ValueError(msg)
        self.compression = "" if name == "none" else name
        self.compressor = _mcap_compressor(name)
        self._ordered = OrderedChunks(pool, self.compressor, self._write_out)

    def close_chunk(self) -> None:
        if self._ordered is None:
            self._ordered = OrderedChunks(None, self.compressor, self._write_out)
        chunk = self.chunk
        self.chunk = PendingChunk(2**63 - 1, 0, BytesIO(), defaultdict(list))
        self._ordered.submit(chunk, chunk.bio.getvalue(), now=self._closing)

    def _write_out(self, chunk: PendingChunk, compressed: bytes) -> None:
        self.chunks.append(write_mcap_chunk(self.bio, self.compression, chunk, compressed))

    def close(self, version: int, metadata: str) -> None:
        self._closing = True
        if self._ordered is not None:
            self._ordered.drain()
        super().close(version, _with_distro(metadata))

    def abort(self) -> None:
        if self._ordered is not None:
            self._ordered.cancel()
        super().abort()

    def write(self, connection: Connection, timestamp: int, data: bytes | memoryview) -> None:
        if timestamp < self.message_start_time:
            self.message_start_time = timestamp
        if timestamp > self.message_end_time:
            self.message_end_time = timestamp
        self.channel_stats[connection.id] += 1
        chunk = self.chunk
        if timestamp < chunk.message_start_time:
            chunk.message_start_time = timestamp
        if timestamp > chunk.message_end_time:
            chunk.message_end_time = timestamp
        bio = chunk.bio
        chunk.msgs[connection.id].append((timestamp, bio.tell()))
        # record: op 0x05, u64 length, u16 channel, u32 sequence (0), u64 log/publish time
        bio.write(_MCAP_MSG(0x05, 22 + len(data), connection.id, 0, timestamp, timestamp))
        bio.write(data)
        if bio.tell() > 2**20:
            self.close_chunk()


def _with_distro(metadata_yaml: str) -> str:
    """rosbags writes ``ros_distro: rosbags``; name the distro of the definitions instead."""
    return metadata_yaml.replace("ros_distro: rosbags", f"ros_distro: {ROS2_DISTRO}")


class _FastRos2Writer(_Ros2Writer):
    STORAGE_PLUGINS = {**_Ros2Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: _FastMcapWriter}  # noqa: RUF012

    def close(self) -> None:
        super().close()
        text = self.metapath.read_text(encoding="utf-8")
        tmp = self.metapath.with_suffix(".yaml.tmp")
        tmp.write_text(_with_distro(text), encoding="utf-8")
        tmp.replace(self.metapath)

    def write(self, connection: Connection, timestamp: int, data: bytes | memoryview) -> None:
        if (
            self.storage is None
            or self.compression_mode.name == "MESSAGE"
            or connection.owner is not self
        ):
            super().write(connection, timestamp, data)
            return
        self.storage.write(connection, timestamp, data)
        self.counts[connection.id] += 1
        if timestamp < self.min_timestamp:
            self.min_timestamp = timestamp
        if timestamp > self.max_timestamp:
            self.max_timestamp = timestamp


class BagWriter(Protocol):
    """A bag being written: one flavour, one file or folder."""

    store: MessageStore
    path: Path

    def add_topics(self, topics: Sequence[BagTopic]) -> None: ...

    def write(self, topic: str, stamp_ns: int, data: bytes | bytearray | memoryview) -> None: ...

    def connection(self, topic: str) -> Connection: ...

    @property
    def raw_write(self) -> Any: ...

    @property
    def compress_cpu_s(self) -> float: ...

    def close(self) -> None: ...

    def abort(self) -> None: ...


class _BagWriter:
    """What both bag flavours share once open: one rosbags writer, one connection per topic."""

    _writer: Any
    _conns: dict[str, Connection]

    def write(self, topic: str, stamp_ns: int, data: bytes | bytearray | memoryview) -> None:
        self._writer.write(self._conns[topic], stamp_ns, data)

    def connection(self, topic: str) -> Connection:
        return self._conns[topic]

    @property
    def raw_write(self) -> Any:
        """rosbags' ``write(connection, timestamp, data)`` of this bag."""
        return self._writer.write

    @property
    def compress_cpu_s(self) -> float:
        """CPU seconds spent compressing this bag's chunks."""
        inner = getattr(self._writer, "storage", self._writer)
        ordered: OrderedChunks | None = getattr(inner, "_ordered", None)
        return ordered.cpu_s if ordered is not None else 0.0

    def close(self) -> None:
        self._writer.close()

    def abort(self) -> None:
        self._writer.abort()


class Ros1BagWriter(_BagWriter):
    """ROS 1 bag v2.0 at ``path`` (must not exist), chunked, ``compression`` none/lz4/bz2."""

    def __init__(
        self,
        path: Path,
        compression: str = "lz4",
        store: MessageStore | None = None,
        pool: ThreadPoolExecutor | None = None,
    ) -> None:
        self.path = path
        self.store = store or MessageStore(Flavor.ROS1)
        self._writer = _FastRos1Writer(path)
        if compression != "none":
            fmt = _Ros1Writer.CompressionFormat[compression.upper()]
            self._writer.set_compression(fmt)
        self._writer.set_pool(pool)
        self._writer.open()
        self._conns: dict[str, Connection] = {}

    def add_topics(self, topics: Sequence[BagTopic]) -> None:
        for t in topics:
            # rosbags' definition drops comments; store ROS 1's full text (same md5 sum)
            stripped, md5sum = self.store.typestore.generate_msgdef(t.msgtype)
            self._conns[t.topic] = self._writer.add_connection(
                t.topic,
                t.msgtype,
                msgdef=ros1_full_text(t.msgtype) or stripped,
                md5sum=md5sum,
                callerid="/roslan",
                latching=1 if t.latched else None,
            )


class Ros2BagWriter(_BagWriter):
    """ROS 2 bag folder at ``path`` (must not exist) with MCAP storage and CDR messages.

    ``compression`` (``zstd``, ``lz4``, ``none``) compresses each MCAP chunk, as
    ``ros2 bag record --storage-preset-profile zstd_fast`` does: the compression lives in
    the MCAP file, so metadata.yaml keeps ``compression_format: ''`` and
    ``compression_mode: ''`` (rosbag2's file/message compression is not used, and
    ``ros2 bag play`` reads the bag without a decompression plugin).
    """

    def __init__(
        self,
        path: Path,
        store: MessageStore | None = None,
        compression: str = "zstd",
        pool: ThreadPoolExecutor | None = None,
    ) -> None:
        self.path = path
        self.store = store or MessageStore(Flavor.ROS2)
        self._writer = _FastRos2Writer(
            path, version=ROS2_BAG_VERSION, storage_plugin=StoragePlugin.MCAP
        )
        self._writer.open()
        storage = self._writer.storage
        assert isinstance(storage, _FastMcapWriter)
        storage.set_chunk_compression(compression, pool)
        self._conns: dict[str, Connection] = {}

    def add_topics(self, topics: Sequence[BagTopic]) -> None:
        for t in topics:
            self._conns[t.topic] = self._writer.add_connection(
                t.topic,
                t.msgtype,
                typestore=self.store.typestore,
                offered_qos_profiles=_ros2_qos(t.latched),
            )


class MultiBagWriter:
    """All bags of one run: every message goes to each flavour, built for that flavour.

    The caller (the stamp merge) builds each message's wire bytes per flavour; each bag
    is written by its own :class:`~roslan.io.bag_threads.BagThread` in the order of the
    calls, its chunks compressed in a shared pool (``threads=False``: everything inline
    in the caller; the bytes are the same).

    Args:
        outdir: folder receiving ``landing.bag`` / ``landing_ros2/``.
        formats: flavours to write (``'ros1'``, ``'ros2'``).
        topics: every connection, in a fixed (deterministic) order.
        compression: ROS 1 chunk compression (``none``, ``lz4``, ``bz2``).
        ros2_compression: ROS 2 MCAP chunk compression (``zstd``, ``lz4``, ``none``).
        threads: a writer thread per bag and a chunk-compression pool.
    """

    def __init__(
        self,
        outdir: Path,
        formats: Iterable[str],
        topics: Sequence[BagTopic],
        compression: str = "lz4",
        ros2_compression: str = "zstd",
        *,
        threads: bool = True,
    ) -> None:
        self.writers: list[BagWriter] = []
        self.msgtypes = {t.topic: t.msgtype for t in topics}
        self.counts: dict[str, int] = {t.topic: 0 for t in topics}
        fmts = [Flavor(f) for f in formats]
        self._pool = chunk_pool(len(fmts)) if threads else None
        self._threads: list[BagThread] = []
        try:
            for flavor in fmts:
                path = outdir / BAG_NAMES[flavor]
                writer: BagWriter = (
                    Ros1BagWriter(path, compression, pool=self._pool)
                    if flavor is Flavor.ROS1
                    else Ros2BagWriter(path, compression=ros2_compression, pool=self._pool)
                )
                self.writers.append(writer)
                writer.add_topics(topics)
        except OSError as err:
            self.abort()
            msg = f"cannot write bag in {outdir}: {err}"
            raise OutputError(msg) from err
        if threads:
            self._threads = [
                BagThread(f"roslan-bag-{w.store.flavor}", w.write, w.close) for w in self.writers
            ]
        self._prepare()

    @property
    def thread_cpu_s(self) -> float:
        """CPU seconds of the bag threads (known after close; 0 without threads)."""
        return sum(t.cpu_s for t in self._threads)

    @property
    def compress_cpu_s(self) -> float:
        """CPU seconds of the chunk compression (pool or inline)."""
        return sum(w.compress_cpu_s for w in self.writers)

    def _prepare(self) -> None:
        # per topic: (store, msgtype, sink) for every bag: its thread, or its writer
        sinks = [t.put for t in self._threads] or [w.write for w in self.writers]
        self._targets = {
            topic: [(w.store, msgtype, sink) for w, sink in zip(self.writers, sinks, strict=True)]
            for topic, msgtype in self.msgtypes.items()
        }

    def write(self, topic: str, stamp_ns: int, build: Any) -> None:
        """Write one message (``build`` as in ``Message.build``) at record time ``stamp_ns``."""
        for store, msgtype, sink in self._targets[topic]:
            sink(topic, stamp_ns, store.encode(build, msgtype))
        self.counts[topic] += 1

    def build(self, topic: str, build: Any) -> list[bytes | bytearray | memoryview]:
        """The wire bytes of one message for each writer (``write_data`` writes them)."""
        msgtype = self.msgtypes[topic]
        return [w.store.encode(build, msgtype) for w in self.writers]

    def write_data(
        self, topic: str, stamp_ns: int, datas: Sequence[bytes | bytearray | memoryview]
    ) -> None:
        """Write bytes from :meth:`build` (one entry per writer)."""
        for (_, _, sink), data in zip(self._targets[topic], datas, strict=True):
            sink(topic, stamp_ns, data)
        self.counts[topic] += 1

    def close(self) -> None:
        """Write what waits and close every bag (raises the first writer error)."""
        try:
            if self._threads:
                for t in self._threads:
                    t.close()
            else:
                for w in self.writers:
                    w.close()
        finally:
            if self._pool is not None:
                self._pool.shutdown(wait=True)

    def abort(self) -> None:
        for t in self._threads:
            t.abort()
        for w in self.writers:
            with contextlib.suppress(Exception):  # best effort while already failing
                w.abort()
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
