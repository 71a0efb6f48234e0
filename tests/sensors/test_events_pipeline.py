"""The event camera's helper thread (ESIM, packets, messages beside the next render):
the same stream and files as on one thread, and its errors reach the caller."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from event_helpers import run_event_camera
from roslan.events.model import EventBatch, EventGenerator
from roslan.io.messages import Flavor, MessageStore


def _wire(msgs: list[Any]) -> list[tuple[int, str, bytes, bytes]]:
    stores = [MessageStore(f) for f in Flavor]
    return [(m.t_ns, m.topic, *(bytes(s.encode(m.build, m.msgtype)) for s in stores)) for m in msgs]


def _files(root: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(root)): p.read_bytes()
        for p in sorted(root.rglob("*"))
        if p.is_file() and p.suffix != ".h5"  # HDF5 stamps its own creation time
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
    runs = {}
    for pipelined in (False, True):
        threads.clear()
        out = tmp_path / f"p{int(pipelined)}"
        out.mkdir()
        sensor, msgs = run_event_camera(out, 5, pipelined=pipelined, **over)
        # ESIM ran on the helper thread only when pipelined (else on this one)
        main = threading.current_thread().name
        assert threads
        assert all((name != main) == pipelined for name in threads)
        assert sensor.stats["events"] > 100
        runs[pipelined] = (_wire(msgs), _files(out), sensor.stats)
    seq, pipe = runs[False], runs[True]
    assert [m[:2] for m in pipe[0]] == [m[:2] for m in seq[0]]
    assert pipe[0] == seq[0]  # every message, both flavours, byte for byte
    assert pipe[1] == seq[1]  # events.txt, images, flow PNGs
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
