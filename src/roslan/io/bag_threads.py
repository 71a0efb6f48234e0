"""Bag writing off the merging thread: one thread per bag, chunk compression in a pool.

The stamp merge (:mod:`roslan.pipeline.merge`) stays the one place that orders messages;
it hands each bag's wire bytes, in merge order, to that bag's :class:`BagThread`, which
appends them to the bag's chunks. A full chunk is compressed in a shared thread pool
(lz4, zstd and bz2 release the GIL) while the next one fills; :class:`OrderedChunks`
writes the compressed chunks to the file strictly in the order they were closed, so a
bag's bytes are the same as when every chunk is compressed inline, whatever the number
of threads (the writers in :mod:`roslan.io.bag` are byte-identical to rosbags' own): an
:class:`~roslan.io.ordered.OrderedPool` on the run's shared chunk pool.

Memory stays bounded: each bag thread's queue holds at most :data:`QUEUE_BATCHES` batches
and :data:`QUEUE_BYTES` (or one larger message alone), and at most ``depth`` chunks wait
for their compression (one, when a chunk reaches :data:`BIG_CHUNK_BYTES`).
"""

from __future__ import annotations

import contextlib
import os
import queue
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from roslan.io.ordered import OrderedPool, Turn

__all__ = ["BATCH_BYTES", "BagThread", "OrderedChunks", "chunk_pool"]

BATCH_BYTES = 4 << 20
"""Message bytes the merging thread collects before handing a batch to a bag thread."""

BATCH_MESSAGES = 512
"""Messages per batch at most (small messages: fewer hand-overs)."""

QUEUE_BATCHES = 8
"""Batches waiting for one bag thread at most (the merge blocks beyond)."""

QUEUE_BYTES = QUEUE_BATCHES * BATCH_BYTES
"""Message bytes waiting for one bag thread at most, unless its queue is empty (a single
message larger than this, e.g. a 12.8 M-point cloud of 282 MB, waits alone)."""

BIG_CHUNK_BYTES = 64 << 20
"""A chunk at least this large is written before the next one is started (chunks this
size hold one huge message each: several in flight would hold several scans)."""

_STOP = object()


def chunk_pool(n_bags: int) -> ThreadPoolExecutor | None:
    """The chunk-compression pool of one run: up to two threads per bag, at most the usable
    CPUs less one (the merge), none on a single CPU (chunks are then compressed inline)."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - non-Linux
        cpus = os.cpu_count() or 1
    n = min(2 * n_bags, cpus - 1)
    return ThreadPoolExecutor(n, thread_name_prefix="roslan-chunk") if n >= 1 else None


class OrderedChunks:
    """Chunks compressed in ``pool`` and written by ``write_out(payload, compressed)`` in
    the order :meth:`submit` received them (an :class:`OrderedPool` on ``pool``); without
    a pool, inline.

    At most ``depth`` chunks wait (compressing, or compressed behind an earlier one);
    :meth:`drain` writes every one that waits.
    """

    def __init__(
        self,
        pool: ThreadPoolExecutor | None,
        compress: Callable[[bytes], bytes],
        write_out: Callable[[Any, bytes], None],
        depth: int = 4,
    ) -> None:
        self.compress = compress
        self.write_out = write_out
        self.depth = max(1, depth)
        # (the pool's depth counts the chunk being submitted too)
        self._ordered: OrderedPool[tuple[Any, bytes]] = OrderedPool(
            1, "roslan-chunk", self.depth + 1, executor=pool
        )
        self._cpu: list[float] = []  # CPU seconds of each compression (list.append is atomic)

    @property
    def cpu_s(self) -> float:
        """CPU seconds spent compressing chunks so far (on whichever thread)."""
        return sum(self._cpu)

    @property
    def waiting(self) -> int:
        """Chunks submitted and not yet written."""
        return self._ordered.in_flight

    def _compress(self, turn: Turn, payload: Any, data: bytes) -> tuple[Any, bytes]:
        c0 = time.thread_time()
        out = self.compress(data)
        self._cpu.append(time.thread_time() - c0)
        return payload, out

    def _write(self, done: list[tuple[Any, bytes]]) -> None:
        for payload, compressed in done:
            self.write_out(payload, compressed)

    def submit(self, payload: Any, data: bytes, *, now: bool = False) -> None:
        """Compress ``data`` (the chunk's uncompressed bytes) and write ``payload`` out once
        every earlier chunk is written; ``now``: before returning."""
        self._write(self._ordered.submit(self._compress, payload, data))
        if now or len(data) >= BIG_CHUNK_BYTES:
            self.drain()

    def drain(self) -> None:
        """Write out every waiting chunk (waiting for their compression)."""
        self._write(self._ordered.finish())

    def cancel(self) -> None:
        """Forget the waiting chunks (a failed run): those not started are dropped, the
        running ones finish unwritten."""
        self._ordered.close()


class BagThread:
    """One thread appending batches of ``(topic, stamp_ns, data)`` to one bag through
    ``write(topic, stamp_ns, data)``; ``close_bag()`` runs on the thread at :meth:`close`.

    The first error of the thread is raised again in the caller by the next :meth:`put`
    or by :meth:`close`; :meth:`abort` stops the thread without closing the bag.
    """

    def __init__(
        self,
        name: str,
        write: Callable[[str, int, Any], None],
        close_bag: Callable[[], None],
    ) -> None:
        self._write = write
        self._close_bag = close_bag
        self._q: queue.Queue[Any] = queue.Queue(maxsize=QUEUE_BATCHES)
        self._batch: list[tuple[str, int, Any]] = []
        self._bytes = 0
        self._queued = 0  # bytes of the batches handed over and not yet written
        self._room = threading.Condition()
        self.error: BaseException | None = None
        self.cpu_s = 0.0
        """CPU time of this thread (its share of writing, compression excluded)."""
        self._aborted = False
        self._closed = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        c0 = time.thread_time()
        write = self._write
        while True:
            item = self._q.get()
            if self.error is not None or self._aborted:
                if item is _STOP:
                    break
                self._release(item)
                continue  # drain without writing: the first error is reported
            try:
                if item is _STOP:
                    self._close_bag()
                    break
                for topic, stamp, data in item:
                    write(topic, stamp, data)
            except BaseException as err:  # handed to the merging thread
                self.error = err
                if item is _STOP:
                    break
            finally:
                if item is not _STOP:
                    self._release(item)
        self.cpu_s = time.thread_time() - c0

    def _release(self, batch: list[tuple[str, int, Any]]) -> None:
        with self._room:
            self._queued -= sum(len(d) for _, _, d in batch)
            self._room.notify_all()

    def put(self, topic: str, stamp_ns: int, data: Any) -> None:
        """Queue one message (in merge order)."""
        self._batch.append((topic, stamp_ns, data))
        self._bytes += len(data)
        if self._bytes >= BATCH_BYTES or len(self._batch) >= BATCH_MESSAGES:
            self.flush()

    def flush(self) -> None:
        """Hand the collected messages to the thread (raises its first error)."""
        self._raise()
        if self._batch:
            batch, self._batch, size, self._bytes = self._batch, [], self._bytes, 0
            while True:  # at most QUEUE_BYTES waiting (or this batch alone)
                with self._room:
                    if not self._queued or self._queued + size <= QUEUE_BYTES:
                        self._queued += size
                        break
                    self._room.wait(0.5)
                self._raise()
                if not self._thread.is_alive():  # pragma: no cover - defensive
                    msg = "a bag writer thread stopped"
                    raise RuntimeError(msg) from None
            while True:
                try:
                    self._q.put(batch, timeout=0.5)
                    return
                except queue.Full:
                    self._raise()
                    if not self._thread.is_alive():  # pragma: no cover - defensive
                        msg = "a bag writer thread stopped"
                        raise RuntimeError(msg) from None

    def _raise(self) -> None:
        if self.error is not None:
            self._stop()
            err, self.error = self.error, None
            raise err

    def _stop(self) -> None:
        if not self._closed:
            self._closed = True
            self._q.put(_STOP)
            self._thread.join()

    def close(self) -> None:
        """Write everything queued, close the bag on the thread, raise the first error."""
        self.flush()
        self._stop()
        self._raise()

    def abort(self) -> None:
        """Drop what waits, stop the thread (the bag is not closed); no error."""
        self._aborted = True
        self._batch = []
        with contextlib.suppress(queue.Empty):
            while True:
                self._q.get_nowait()
        self._stop()
        self.error = None
