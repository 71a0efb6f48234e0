"""The event camera's stream after each render: ESIM, EventArray packets, messages.

:class:`AfterRender` takes one rendered instant at a time (luminance, depth, flow), in
time order, on the sensor's helper thread (or the calling one): the events of the
interval, their dataset-file writes (submitted to the sensor's file writer), the
instant's messages, and the packets cut by :class:`Packetizer`. The messages come out in
stream order through :meth:`AfterRender.take`.
"""

from __future__ import annotations

import bisect
import collections
import heapq
import itertools
from collections.abc import Iterator, Sized
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray

from roslan.events.model import EventBatch, EventGenerator, EventModelParams
from roslan.events.ros import EVENT_ARRAY, pack_event_array
from roslan.io.messages import Flavor, MessageStore
from roslan.sensors.base import Message, SimContext
from roslan.sensors.cameras.encoding import srgb_curve
from roslan.sensors.cameras.event_image import RecentEvents
from roslan.sensors.measurements import EventSamples

if TYPE_CHECKING:
    from roslan.io.background import BackgroundSink
    from roslan.sensors.cameras.event_config import EventCameraConfig
    from roslan.sensors.cameras.flow_truth import FlowTruth

__all__ = ["AfterRender", "Packetizer", "StreamSensor"]

F32 = NDArray[np.float32]


class _Size(Protocol):
    @property
    def width(self) -> int: ...

    @property
    def height(self) -> int: ...


class StreamSensor(Protocol):
    """What the stream needs of the event camera
    (:class:`~roslan.sensors.cameras.event.EventCamera`, which imports this module): its
    config, pixel model, size and frame, its file writers and message builders."""

    @property
    def config(self) -> EventCameraConfig: ...

    @property
    def params(self) -> EventModelParams: ...

    @property
    def camera(self) -> _Size: ...

    @property
    def optical_frame(self) -> str: ...

    @property
    def _sink(self) -> BackgroundSink | None: ...

    @property
    def flow_truth(self) -> FlowTruth | None: ...

    @property
    def _writers(self) -> Sized: ...

    def _write_events(self, batch: EventBatch, labels: Any = None) -> None: ...

    def _write_image(
        self, ctx: SimContext, t_ns: int, aps: NDArray[np.uint8], index: int
    ) -> None: ...

    def _camera_info_msg(self, ctx: SimContext, t_ns: int) -> Message: ...

    def _image_msg(
        self, ctx: SimContext, t_ns: int, data: NDArray[Any], encoding: str
    ) -> Message: ...

    def _truth_msgs(
        self,
        ctx: SimContext,
        t: int,
        flow: F32 | None,
        depth: F32 | None,
        gt_times: NDArray[np.int64],
        gt_rate: float,
    ) -> list[Message]: ...


def _srgb8(lin: NDArray[np.floating]) -> NDArray[np.uint8]:
    s = srgb_curve(np.clip(np.asarray(lin, dtype=np.float32), 0.0, 1.0))
    out: NDArray[np.uint8] = np.rint(s * 255.0).astype(np.uint8)
    return out


class AfterRender:
    """What follows an instant's render and flow: ESIM, event packets, the instant's
    messages and its dataset-file writes, in time order (one thread at a time).

    :meth:`step` queues the instant's messages; :meth:`take` hands over, in stream order,
    those whose time no later message can precede."""

    def __init__(
        self,
        sensor: StreamSensor,
        ctx: SimContext,
        info_times: NDArray[np.int64],
        gt_times: NDArray[np.int64],
        gt_rate: float,
        *,
        pipelined: bool,
    ) -> None:
        c = sensor.config
        self.sensor, self.ctx = sensor, ctx
        W, H = sensor.camera.width, sensor.camera.height
        self.gen = EventGenerator(W, H, sensor.params, ctx.rng(f"{c.name}/pixels"))
        self.tick = c.timestamp_resolution_ns
        self.recent = (
            RecentEvents(W, H, round(c.event_image_window * 1e9)) if c.event_image else None
        )
        self.info_set = set(info_times.tolist())
        self.gt_set = set(gt_times.tolist())
        self.gt_times, self.gt_rate = gt_times, gt_rate
        self.pending: list[tuple[int, int, Message]] = []
        self.counter = itertools.count()
        self.buf: list[EventBatch] = []
        self.packets = Packetizer(sensor, ctx, prebuild=pipelined)
        self.image_index = 0
        self.n_events = 0
        self.ready: collections.deque[Message] = collections.deque()
        self.labels: Any = None  # the labels' side (output.labels: event_labels.py)
        if getattr(c, "writes_labels", False):
            from roslan.sensors.base import sample_times_ns
            from roslan.sensors.cameras.event_labels import EventLabels

            end = int(ctx.trajectory.duration_ns)
            times = sample_times_ns(c.label_rate, end) if c.label_rate else info_times
            self.gen.flag_noise = True
            self.labels = EventLabels(sensor, ctx, times)

    def step(
        self,
        t: int,
        lum: F32,
        depth: F32 | None,
        flow: F32 | None,
        ids: NDArray[np.int32] | None = None,
    ) -> None:
        s, c, ctx, sink = self.sensor, self.sensor.config, self.ctx, self.sensor._sink
        assert sink is not None
        batch = self.gen.update(lum, t)
        if batch.size and self.tick > 1:
            # the sensor's timestamp counter (order kept): floor to the tick, in place
            np.floor_divide(batch.t, self.tick, out=batch.t)
            batch.t[:] *= self.tick
        labels = None
        if self.labels is not None:
            labels = self.labels.events(batch, self.gen.last_noise, t)
        if batch.size:
            self.n_events += batch.size
            ctx.clock.tap(c.name, EventSamples(batch.x, batch.y, batch.t, batch.p))
            if s._writers:
                sink.submit(s._write_events, batch, labels)
            self.buf.append(batch)
        recent = self.recent
        if recent is not None:
            recent.add(batch, t)
        out: list[Message] = []
        if t in self.info_set:
            out.append(s._camera_info_msg(ctx, t))
            if recent is not None:
                out.append(s._image_msg(ctx, t, recent.frame(t), "rgb8"))
            if c.has_aps:
                aps = _srgb8(lum)
                out.append(s._image_msg(ctx, t, aps, "mono8"))
                if ctx.files is not None:  # (None: a run that records no files)
                    sink.submit(s._write_image, ctx, t, aps, self.image_index)
                self.image_index += 1
        if self.labels is not None:
            out += self.labels.instant(t, aps=c.has_aps and t in self.info_set)
        if t in self.gt_set:
            out += s._truth_msgs(ctx, t, flow, depth, self.gt_times, self.gt_rate)
        if s.flow_truth is not None:  # (a map starts after the first event)
            start = t in self.gt_set and self.n_events > 0
            s.flow_truth.step(t, depth, start=start, submit=sink.submit, ids=ids)
        self.buf, ready = self.packets.split(self.buf, t, final=False)
        self._push(*ready, *out)
        horizon = t if not self.buf else min(t, int(self.buf[0].t[0]))
        self._release(horizon)

    def follow(self, forced: Any) -> None:
        """Take the forced instants known so far (closed loop: they grow with the horizon,
        :class:`~roslan.sensors.cameras.event_causal.ForcedInstants`)."""
        self.info_set, self.gt_set, self.gt_times = forced.info_set, forced.gt_set, forced.gt

    def floor(self, t: int) -> int:
        """The smallest stamp a message may still have after instant ``t`` (every message
        released so far taken): a queued message's, a buffered event's, or an event
        after ``t`` (floored to the timestamp tick)."""
        f = t + 1
        if self.tick > 1:
            f = (f // self.tick) * self.tick
        if self.pending:
            f = min(f, self.pending[0][0])
        if self.buf:
            f = min(f, int(self.buf[0].t[0]))
        return f

    def finish(self, t: int) -> None:
        """After the last instant ``t``: the last packet, then everything queued."""
        self.buf, ready = self.packets.split(self.buf, t, final=True)
        self._push(*ready)
        self._release(None)
        if self.labels is not None:
            self.labels.close()

    def _push(self, *msgs: Message) -> None:
        for m in msgs:
            heapq.heappush(self.pending, (m.t_ns, next(self.counter), m))

    def _release(self, horizon: int | None) -> None:
        pending, ready = self.pending, self.ready
        while pending and (horizon is None or pending[0][0] <= horizon):
            ready.append(heapq.heappop(pending)[2])

    def take(self) -> Iterator[Message]:
        """The messages released so far (safe while :meth:`step` runs on another thread:
        one appends, the other pops, each deque operation atomic)."""
        ready = self.ready
        while ready:
            yield ready.popleft()


class Packetizer:
    """Cuts the event stream into EventArray messages (by duration or by count)."""

    def __init__(self, sensor: StreamSensor, ctx: SimContext, *, prebuild: bool = False) -> None:
        self.sensor = sensor
        self.ctx = ctx
        c = sensor.config
        self.d_ns = max(1, round(c.packet_duration * 1e9))
        self.count = c.packet_events
        self.seq = 0
        self.prebuild = prebuild
        """Pack each packet for the flavours asked so far when it is cut (on the helper
        thread), so that its consumer finds the bytes ready."""
        self.flavors: set[Flavor] = set()

    def split(
        self, buf: list[EventBatch], t_ns: int, *, final: bool
    ) -> tuple[list[EventBatch], list[Message]]:
        """Messages for every complete packet (all of them when ``final``) and the rest.

        ``buf`` holds the buffered events, in time order, as batches that are never
        joined as a whole: a packet is a view of its batch, or the join of its pieces when
        it spans batches, and the rest stays views of the batches it is in."""
        if not buf:
            return buf, []
        starts = list(itertools.accumulate((b.size for b in buf), initial=0))
        total = starts[-1]
        cuts: list[int]
        if self.count is not None:
            n_full = total // self.count
            cuts = [i * self.count for i in range(n_full + 1)]
            if final and total > cuts[-1]:
                cuts.append(total)
        else:
            # packet j = [j d, (j+1) d) is complete once the frame time reaches its end
            d = self.d_ns
            end = np.array([(t_ns // d) * d], np.int64)
            limit = total if final else int(_count_before(buf, end)[0])
            if limit == 0:
                return buf, []
            # the first event of each later packet: a few binary searches, not a pass
            j0 = int(buf[0].t[0]) // d
            j1 = int(_take(buf, starts, limit - 1, limit).t[0]) // d
            bounds = np.arange(j0 + 1, j1 + 1, dtype=np.int64) * d
            cuts = [0, *_count_before(buf, bounds).tolist(), limit]
        msgs = [
            self._message(_take(buf, starts, a, b)) for a, b in itertools.pairwise(cuts) if b > a
        ]
        return _pieces(buf, starts, cuts[-1], total), msgs

    def _message(self, ev: EventBatch) -> Message:
        s = self.sensor
        ctx = self.ctx
        t_last = int(ev.t[-1])
        seq = self.seq
        self.seq += 1
        cam = s.camera
        frame = s.optical_frame
        t0 = ctx.start_time_ns
        stamp = ctx.stamp(t_last)

        def pack(flavor: Flavor) -> bytes:
            return pack_event_array(
                flavor, stamp, frame, cam.height, cam.width, ev.t, ev.x, ev.y, ev.p, seq, t0
            )

        ready = {f: pack(f) for f in tuple(self.flavors)} if self.prebuild else {}
        flavors = self.flavors

        def build(store: MessageStore) -> bytes:
            data = ready.pop(store.flavor, None)
            if data is None:
                flavors.add(store.flavor)  # (set.add is atomic: the helper reads it)
                data = pack(store.flavor)
            return data

        return Message(t_last, f"{s.config.topic}/events", EVENT_ARRAY, build)


def _count_before(buf: list[EventBatch], bounds: NDArray[np.int64]) -> NDArray[np.int64]:
    """The number of buffered events (``buf``: batches in time order) earlier than each of
    ``bounds``: the sum of the batches' binary searches."""
    n = np.zeros(bounds.shape, np.int64)
    for b in buf:
        n += np.searchsorted(b.t, bounds, side="left")
    return n


def _pieces(buf: list[EventBatch], starts: list[int], a: int, b: int) -> list[EventBatch]:
    """Events ``a:b`` of the batches ``buf`` (``starts``: their first indices, and the
    total) as views of the batches they are in."""
    out = []
    for k in range(max(bisect.bisect_right(starts, a) - 1, 0), len(buf)):
        s = starts[k]
        if s >= b:
            break
        piece = buf[k].slice(max(a - s, 0), min(b - s, buf[k].size))
        if piece.size:
            out.append(piece)
    return out


def _take(buf: list[EventBatch], starts: list[int], a: int, b: int) -> EventBatch:
    """Events ``a:b`` of the batches ``buf`` as one batch (a view when they lie in one)."""
    return EventBatch.concatenate(_pieces(buf, starts, a, b))
