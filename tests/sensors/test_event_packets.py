"""The event camera's packet cutter (:class:`Packetizer`): the packets it cuts from
buffered ESIM batches, whatever the batch boundaries, against a straightforward cut of the
whole stream (duration packets: grouped by ``t // d`` once the frame time passes their end;
count packets: consecutive runs of ``count`` events)."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

import roslan.sensors.cameras.event_stream as ev_mod
from roslan.events.model import EventBatch
from roslan.io.messages import Flavor
from roslan.sensors.cameras.event_stream import Packetizer

START_NS = 1_700_000_000_000_000_000
D_NS = 1_000_000  # 1 ms packets


def _stream(rng: np.random.Generator) -> tuple[list[int], list[EventBatch]]:
    """Frame instants and, per instant, the batch of the events since the previous one
    (times in ``(t_prev, t]``, sorted; some empty, some of one event, ties and events on
    packet boundaries included)."""
    steps = rng.choice([1, 7, 999, 1000, 1001, 250_000, 1_000_000, 3_300_000], 60)
    times = np.cumsum(steps).tolist()
    batches, prev = [], 0
    for t in times:
        n = int(rng.choice([0, 1, 2, 5, 40, 300]))
        ts = np.sort(rng.integers(prev + 1, t + 1, n))
        if n > 3:  # a tie and an event exactly on a packet boundary (when in range)
            ts[1] = ts[0]
            b = (t // D_NS) * D_NS
            if b > prev:
                ts[-1] = b
                ts.sort()
        batches.append(
            EventBatch(
                ts.astype(np.int64),
                rng.integers(0, 346, n).astype(np.uint16),
                rng.integers(0, 260, n).astype(np.uint16),
                rng.integers(0, 2, n).astype(np.int8),
            )
        )
        prev = t
    return times, batches


def _expected(times: list[int], batches: list[EventBatch], count: int | None) -> list[list[int]]:
    """Per split call (each instant, then the final one): the packets it emits, as lists of
    event positions in the whole stream; by direct grouping of the events one by one."""
    t_all = np.concatenate([b.t for b in batches]).tolist()
    out: list[list[list[int]]] = []
    done = 0  # events emitted so far
    seen = 0  # events buffered so far
    for k, t in enumerate([*times, None]):
        if t is not None:
            seen += batches[k].size
        packets: list[list[int]] = []
        if count is not None:
            while seen - done >= count or (t is None and seen > done):
                m = min(count, seen - done)
                packets.append(list(range(done, done + m)))
                done += m
        else:
            groups: dict[int, list[int]] = {}
            for i in range(done, seen):
                if t is None or t_all[i] < (t // D_NS) * D_NS:
                    groups.setdefault(t_all[i] // D_NS, []).append(i)
            for j in sorted(groups):
                packets.append(groups[j])
                done += len(groups[j])
        out.append(packets)
    return out


@pytest.mark.parametrize("count", [None, 1, 7, 64], ids=["duration", "count1", "count7", "count64"])
@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("prebuild", [False, True])
def test_packets_equal_a_direct_cut_for_any_batch_boundaries(
    monkeypatch: pytest.MonkeyPatch, count: int | None, seed: int, prebuild: bool
) -> None:
    rng = np.random.default_rng(seed)
    times, batches = _stream(rng)
    packed: list[tuple[Any, ...]] = []
    pack = ev_mod.pack_event_array

    def spy(flavor: Flavor, *args: Any) -> bytes:
        packed.append((flavor, *args))
        return pack(flavor, *args)

    monkeypatch.setattr(ev_mod, "pack_event_array", spy)
    cfg = SimpleNamespace(packet_duration=D_NS * 1e-9, packet_events=count, topic="/dvs")
    sensor = SimpleNamespace(
        config=cfg, camera=SimpleNamespace(height=260, width=346), optical_frame="dvs_optical"
    )
    ctx = SimpleNamespace(start_time_ns=START_NS, stamp=lambda t: START_NS + t)
    pk = Packetizer(sensor, ctx, prebuild=prebuild)  # type: ignore[arg-type]
    if prebuild:
        pk.flavors = {Flavor.ROS1}
    ev_all = EventBatch.concatenate(batches)
    want = _expected(times, batches, count)
    buf: list[EventBatch] = []
    seq = 0
    for k, t in enumerate([*times, times[-1]]):
        final = k == len(times)
        if not final and batches[k].size:
            buf.append(batches[k])
        packed.clear()
        buf, msgs = pk.split(buf, t, final=final)
        at_cut = list(packed)  # prebuild: packed when cut, one per packet
        assert len(at_cut) == (len(msgs) if prebuild else 0)
        assert len(msgs) == len(want[k]), (k, t)
        for i, (msg, idx) in enumerate(zip(msgs, want[k], strict=True)):
            packed.clear()
            data = msg.build(SimpleNamespace(flavor=Flavor.ROS1))
            assert len(packed) == (0 if prebuild else 1)
            _, stamp, frame, _, _, t_ev, x_ev, y_ev, p_ev, s, offset = (
                at_cut[i] if prebuild else packed[0]
            )
            assert t_ev.tolist() == ev_all.t[idx].tolist()
            assert (x_ev.tolist(), y_ev.tolist()) == (
                ev_all.x[idx].tolist(),
                ev_all.y[idx].tolist(),
            )
            assert p_ev.tolist() == ev_all.p[idx].tolist()
            assert offset == START_NS
            assert msg.t_ns == int(ev_all.t[idx[-1]])
            assert stamp == START_NS + msg.t_ns
            assert s == seq
            # the bytes: those of the absolute stamps packed directly
            e = ev_all.slice(0, ev_all.size)
            assert data == pack(
                Flavor.ROS1, stamp, frame, 260, 346, e.t[idx] + START_NS, e.x[idx], e.y[idx],
                e.p[idx], seq,
            )  # fmt: skip
            seq += 1
        # what stays buffered: the events not yet in a packet, in order
        rest = np.concatenate([b.t for b in buf]) if buf else np.zeros(0, np.int64)
        n_done = sum(len(p) for w in want[: k + 1] for p in w)
        n_seen = sum(b.size for b in batches[: k + 1])
        assert rest.tolist() == ev_all.t[n_done:n_seen].tolist()
    assert not buf
