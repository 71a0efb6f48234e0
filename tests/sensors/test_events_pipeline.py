"""The event camera's helper thread (ESIM, packets, messages beside the next render):
the same stream and files as on one thread, and its errors reach the caller."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import roslan.sensors.cameras.event_stream as ev_mod
from event_helpers import run_event_camera
from roslan.events.model import EventBatch, EventGenerator
from roslan.io.messages import Flavor, MessageStore

STORES = [MessageStore(f) for f in Flavor]


def _wire(m: Any) -> tuple[Any, ...]:
    """A message's time, topic and wire bytes in both flavours."""
    return (m.t_ns, m.topic, *(bytes(s.encode(m.build, m.msgtype)) for s in STORES))


def _files(root: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()
    }


@pytest.mark.parametrize(
    "over",
    [{}, {"optic_flow": True, "depthmap": True, "aps": True, "packet_events": 50}],
    ids=["default", "truth-aps-count-packets"],
)
def test_pipelined_stream_equals_sequential(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, over: dict[str, Any]
) -> None:
    pytest.importorskip("roslan.render.gl")
    threads: list[str] = []
    update = EventGenerator.update

    def spy(self: EventGenerator, intensity: Any, t_ns: int) -> EventBatch:
        threads.append(threading.current_thread().name)
        return update(self, intensity, t_ns)

    monkeypatch.setattr(EventGenerator, "update", spy)
    packers: list[str] = []
    pack = ev_mod.pack_event_array

    def pack_spy(*args: Any, **kw: Any) -> bytes:
        packers.append(threading.current_thread().name)
        return pack(*args, **kw)

    monkeypatch.setattr(ev_mod, "pack_event_array", pack_spy)
    main = threading.current_thread().name
    runs = {}
    for pipelined in (False, True):
        threads.clear()
        packers.clear()
        out = tmp_path / f"p{int(pipelined)}"
        out.mkdir()
        wire: list[tuple[Any, ...]] = []  # built as each message comes, as the pipeline does
        sensor, _ = run_event_camera(
            out, 5, pipelined=pipelined, on_message=lambda m, w=wire: w.append(_wire(m)), **over
        )
        # ESIM ran on the helper thread only when pipelined (else on this one); there the
        # helper packed the later packets ahead, for both flavours
        assert threads
        assert all((name != main) == pipelined for name in threads)
        helper_packs = sum(name != main for name in packers)
        assert helper_packs > len(packers) // 2 if pipelined else helper_packs == 0
        assert sensor.stats["events"] > 100
        runs[pipelined] = (wire, _files(out), sensor.stats)
    seq, pipe = runs[False], runs[True]
    assert [m[:2] for m in pipe[0]] == [m[:2] for m in seq[0]]
    assert pipe[0] == seq[0]  # every message, both flavours, byte for byte
    assert pipe[1] == seq[1]  # events.txt, events.h5, images, flow PNGs, depth.h5
    assert pipe[2] == seq[2]
    times = [m[0] for m in pipe[0]]
    assert times == sorted(times)
    # and the HDF5 datasets, value for value
    h5py = pytest.importorskip("h5py")
    with (
        h5py.File(tmp_path / "p0" / "events.h5") as a,
        h5py.File(tmp_path / "p1" / "events.h5") as b,
    ):
        for key in ("events/t", "events/x", "events/y", "events/p"):
            assert np.array_equal(a[key][:], b[key][:])


def test_error_on_the_helper_thread_reaches_the_caller(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("roslan.render.gl")
    update = EventGenerator.update
    where: list[str] = []

    def failing(self: EventGenerator, intensity: Any, t_ns: int) -> EventBatch:
        if t_ns > 100_000_000:
            where.append(threading.current_thread().name)
            msg = f"ESIM broke at {t_ns} ns"
            raise RuntimeError(msg)
        return update(self, intensity, t_ns)

    monkeypatch.setattr(EventGenerator, "update", failing)
    with pytest.raises(RuntimeError, match=r"^ESIM broke at \d+ ns$"):
        run_event_camera(tmp_path, 5)
    assert where
    assert where[0] != threading.current_thread().name
    # the helper and the file writer are gone: nothing writes into the folder any more
    assert not [t for t in threading.enumerate() if t.name.startswith("dvs-")]
