"""Bag writing off the merging thread: a thread per bag and a chunk-compression pool give the
same bytes as writing inline; a writer's error reaches the caller; abort stops cleanly."""

from __future__ import annotations

import hashlib
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from roslan.io import bag_threads
from roslan.io.bag import BagTopic, MultiBagWriter
from roslan.io.bag_threads import BagThread, OrderedChunks

TOPICS = [
    BagTopic("/img", "sensor_msgs/msg/Image"),
    BagTopic("/s", "std_msgs/msg/String"),
    BagTopic("/tf_static", "tf2_msgs/msg/TFMessage", latched=True),
]


def _digests(root: Path) -> dict[str, str]:
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }


def _write_bags(out: Path, threads: bool, pool_threads: int | None) -> dict[str, str]:
    out.mkdir()
    rng = np.random.default_rng(5)
    w = MultiBagWriter(out, ["ros1", "ros2"], TOPICS, threads=threads)
    if pool_threads is not None:  # a wider pool than this machine's CPUs would give
        pool = ThreadPoolExecutor(pool_threads)
        for writer in w.writers:
            inner = writer._writer  # type: ignore[attr-defined]
            storage = getattr(inner, "storage", inner)
            storage._ordered.pool = pool
    for i in range(400):  # ~12 MB of images: a dozen chunks per bag
        stamp = 10**18 + i * 10**6
        img = rng.integers(0, 40, size=(120, 250), dtype=np.uint8)
        w.write("/img", stamp, lambda s, a=img, t=stamp: s.image("cam", t, a, "mono8"))
        text = "x" * int(rng.integers(0, 300))
        w.write("/s", stamp, lambda s, t=text: s.new("std_msgs/msg/String", data=t))
    w.close()
    assert w.counts == {"/img": 400, "/s": 400, "/tf_static": 0}
    return _digests(out)


def test_threads_and_pool_give_the_inline_bytes(tmp_path: Path) -> None:
    inline = _write_bags(tmp_path / "inline", threads=False, pool_threads=None)
    threaded = _write_bags(tmp_path / "threads", threads=True, pool_threads=None)
    wide = _write_bags(tmp_path / "wide", threads=True, pool_threads=6)
    assert len(inline) == 3  # landing.bag, the .mcap and metadata.yaml
    assert inline == threaded == wide


def test_ordered_chunks_write_in_submission_order() -> None:
    """Chunks finishing out of order (later ones compress faster) are written in order."""
    written: list[tuple[int, bytes]] = []

    def compress(data: bytes) -> bytes:
        time.sleep(0.02 * (5 - data[0]))  # chunk 0 slowest
        return data[::-1]

    with ThreadPoolExecutor(4) as pool:
        oc = OrderedChunks(pool, compress, lambda k, c: written.append((k, c)), depth=3)
        for k in range(5):
            oc.submit(k, bytes([k, 9]))
            assert oc.waiting <= 3
        oc.drain()
    assert written == [(k, bytes([9, k])) for k in range(5)]


def test_writer_error_reaches_the_caller_and_abort_stops(tmp_path: Path) -> None:
    calls: list[int] = []

    def write(topic: str, stamp: int, data: bytes) -> None:
        calls.append(stamp)
        if stamp == 3:
            raise OSError(28, "No space left on device")

    closed = threading.Event()
    t = BagThread("test", write, closed.set)

    def feed() -> None:
        for i in range(10_000):
            t.put("/s", i, b"abc")
            if i % bag_threads.BATCH_MESSAGES == 0:
                t.flush()
        t.close()

    with pytest.raises(OSError, match="No space left"):
        feed()
    assert not closed.is_set()  # a failed bag is not closed (the run aborts it)
    assert calls[-1] == 3  # nothing written after the failure
    t.abort()  # after a failure: no error, the thread is gone
    assert not t._thread.is_alive()


def test_failing_bag_in_a_multibag_writer(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    w = MultiBagWriter(tmp_path, ["ros1", "ros2"], TOPICS)
    ros2 = w.writers[1]

    def broken(conn: object, stamp: int, data: bytes) -> None:
        raise OSError(5, "Input/output error")

    monkeypatch.setattr(ros2._writer, "write", broken)  # type: ignore[attr-defined]

    def feed() -> None:
        for i in range(2000):
            w.write("/s", 10**18 + i, lambda s: s.new("std_msgs/msg/String", data="abc"))
        w.close()

    with pytest.raises(OSError, match="Input/output error"):
        feed()
    w.abort()
    assert all(not t._thread.is_alive() for t in w._threads)
