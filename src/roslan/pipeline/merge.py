"""The stamp merge: every component's messages, in one total order, into the bag writers.

Each component (ground truth, then the sensors in config order) is a lazy, time-ordered
message generator. :class:`CheckedStream` wraps one and checks its contract (stamps never
decrease, only declared topics); :func:`tagged` gives each message its merge key
``(t_ns, order)``, where ``order`` is the component's stable position (ground truth 0,
sensor ``i`` -> ``i + 1``); :func:`pump` merges all streams with ``heapq.merge`` and writes
every message to every bag. Worker processes merge their own sensors by the same key, so
the total order, and every output byte, is the same whatever runs where.
"""

from __future__ import annotations

import heapq
import time
from collections.abc import Iterable, Iterator, Sequence
from operator import itemgetter
from typing import TYPE_CHECKING, Protocol

from roslan.errors import SensorError
from roslan.sensors.base import WAIT_TOPIC, Message

if TYPE_CHECKING:
    from roslan.io.bag import MultiBagWriter

__all__ = ["MERGE_KEY", "CheckedStream", "MergeItem", "pump", "tagged"]

MergeItem = tuple[int, int, Message]
"""``(t_ns, order, message)``: merge key first; ``order`` = component position."""

MERGE_KEY = itemgetter(0, 1)
"""Key of the stamp merge: ``(t_ns, order)``."""

PROGRESS_EVERY = 2048
"""Messages between two progress updates."""


class ProgressSink(Protocol):
    def update(self, t_s: float) -> None: ...


class CheckedStream:
    """One component's message generator, checked (time order, declared topics) and,
    with ``profile``, timed."""

    def __init__(self, name: str, gen: Iterator[Message], topics: set[str], profile: bool) -> None:
        self.name = name
        self.gen = gen
        self.topics = topics
        self.profile = profile
        self.seconds = 0.0
        self.count = 0
        self.waits = True
        """Pass the sensor's wait markers on (:mod:`roslan.sensors.clock`); False: a
        marker is an error (a fixed clock, where nothing may wait)."""

    def __iter__(self) -> Iterator[Message]:
        last = -1
        it = self.gen
        topics = self.topics
        perf = time.perf_counter
        while True:
            if self.profile:
                t0 = perf()
                msg = next(it, None)
                self.seconds += perf() - t0
            else:
                msg = next(it, None)
            if msg is None:
                return
            if msg.topic not in topics or msg.t_ns < last or msg.t_ns < 0:
                if msg.topic == WAIT_TOPIC and self.waits:  # the engine's business
                    yield msg
                    continue
                self._fail(msg, last)
            last = msg.t_ns
            self.count += 1
            yield msg

    def _fail(self, msg: Message, last: int) -> None:
        if msg.topic == WAIT_TOPIC:
            err = f"sensor {self.name!r} waited for the trajectory past the end of the run"
            raise SensorError(err)
        if msg.t_ns < last or msg.t_ns < 0:
            err = (
                f"sensor {self.name!r} yielded t_ns={msg.t_ns} after {last}: "
                "streams must be time-ordered"
            )
            raise SensorError(err)
        err = (
            f"sensor {self.name!r} yielded topic {msg.topic!r} not declared in "
            f"its topics(): {sorted(self.topics)}"
        )
        raise SensorError(err)

    def close(self) -> None:
        """Close the generator (sensors stop their writer threads in its ``finally``)."""
        close = getattr(self.gen, "close", None)
        if close is not None:
            close()


def tagged(order: int, stream: Iterable[Message]) -> Iterator[MergeItem]:
    """``stream``'s messages with their merge key."""
    for msg in stream:
        yield msg.t_ns, order, msg


def merged(streams: Sequence[Iterable[MergeItem]]) -> Iterator[MergeItem]:
    """All ``streams`` in ``(t_ns, order)`` order."""
    return heapq.merge(*streams, key=MERGE_KEY)


def pump(
    streams: Sequence[Iterable[MergeItem]],
    writers: MultiBagWriter,
    start_ns: int,
    progress: ProgressSink,
    profile: bool,
    owners: dict[str, str],
) -> tuple[float, dict[str, float]]:
    """Merge all streams by ``(t_ns, order)`` and write every message at bag time
    ``start_ns + t_ns``; returns (writer seconds, build seconds per component), both
    measured only with ``profile``."""
    n = 0
    write_s = 0.0
    build_s: dict[str, float] = {}
    if not profile:
        for _, _, msg in merged(streams):
            writers.write(msg.topic, start_ns + msg.t_ns, msg.build)
            n += 1
            if n % PROGRESS_EVERY == 0:
                progress.update(msg.t_ns * 1e-9)
        return write_s, build_s
    perf = time.perf_counter
    for _, _, msg in merged(streams):
        t0 = perf()
        datas = writers.build(msg.topic, msg.build)
        t1 = perf()
        writers.write_data(msg.topic, start_ns + msg.t_ns, datas)
        t2 = perf()
        owner = owners[msg.topic]
        build_s[owner] = build_s.get(owner, 0.0) + (t1 - t0)
        write_s += t2 - t1
        n += 1
        if n % PROGRESS_EVERY == 0:
            progress.update(msg.t_ns * 1e-9)
    return write_s, build_s
