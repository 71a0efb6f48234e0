"""Streaming event files: ``events.txt`` (Event Camera Dataset) and ``events.h5``.

Both are appended to chunk by chunk while the simulation streams, so memory stays
bounded by one chunk however long the trajectory is.

* ``events.txt``: ``t x y p`` per line, t seconds since the trajectory start with
  nine decimals (exact, from integer ns), p in {0, 1}. Formatted by a numba kernel
  into a byte buffer (no per-event Python objects).
* ``events.h5``: the DSEC layout (``events/t`` microseconds, ``t_offset``, ``ms_to_idx``,
  see :class:`EventH5Writer`) plus ``events/t_ns`` (exact nanoseconds, for event times
  finer than 1 us); chunked,
  gzip+shuffle compressed (or lzf); ``width``/``height`` attributes.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from roslan.events.model import EventBatch

__all__ = ["EventH5Writer", "EventTextWriter", "format_events_txt"]

_NS = 1_000_000_000


_LUT3 = np.array([[ord(c) for c in f"{i:03d}"] for i in range(1000)], dtype=np.uint8)
"""(1000, 3) ASCII digits of 000..999."""


def _put(
    buf: NDArray[np.uint8],
    keep: NDArray[np.bool_] | None,
    col: int,
    v: NDArray[np.int64],
    width: int,
) -> None:
    """Write ``v`` (N,) right-aligned in ``width`` columns from ``col``; mark leading zeros
    (all but the last digit) as dropped in ``keep``."""
    groups = -(-width // 3)
    pad = groups * 3 - width
    rest = v
    digits = np.empty((v.shape[0], groups * 3), np.uint8)
    for g in range(groups - 1, -1, -1):  # a few 3-digit groups, not a loop over events
        digits[:, 3 * g : 3 * g + 3] = _LUT3[rest % 1000]
        rest = rest // 1000
    buf[:, col : col + width] = digits[:, pad:]
    if keep is not None and width > 1:
        pw = 10 ** np.arange(width - 1, 0, -1, dtype=np.int64)
        keep[:, col : col + width - 1] = v[:, None] >= pw


def format_events_txt(
    t_ns: NDArray[np.int64], x: NDArray[Any], y: NDArray[Any], p: NDArray[Any]
) -> bytes:
    """Lines ``'%d.%09d %d %d %d\\n'`` of (N,) events as bytes (t non-negative ns; x, y
    non-negative integers)."""
    return _format_txt(t_ns, x, y, p).tobytes()


def _format_txt(
    t_ns: NDArray[np.int64],
    x: NDArray[Any],
    y: NDArray[Any],
    p: NDArray[Any],
    buf: NDArray[np.uint8] | None = None,
) -> NDArray[np.uint8]:
    """As :func:`format_events_txt`, the bytes as a uint8 array (no copy to ``bytes``):
    a view of ``buf`` when it is long enough (a buffer reused from call to call: no fresh
    pages to fault in each time)."""
    n = int(t_ns.shape[0])
    if n == 0:
        return np.zeros(0, np.uint8)
    t = np.ascontiguousarray(t_ns, dtype=np.int64)
    xs, ys = _coord(x), _coord(y)
    lo = min(int(t.min()), int(xs.min()), int(ys.min()))
    if lo < 0:
        msg = f"events.txt needs non-negative times and pixel coordinates, got {lo}"
        raise ValueError(msg)
    from roslan.events import _kernels

    # bytes a line at most: seconds '.' 9 digits, ' x', ' y', ' p\n'
    width = len(str(int(t.max()) // _NS)) + 10 + 2 + len(str(int(xs.max())))
    width += len(str(int(ys.max()))) + 3
    out = buf if buf is not None and buf.shape[0] >= n * width else np.empty(n * width, np.uint8)
    k = _kernels.format_txt(t, xs, ys, np.ascontiguousarray(p), out)
    return out[:k]


def _coord(v: NDArray[Any]) -> NDArray[Any]:
    """Pixel coordinates as a contiguous integer array (uint16 kept, others int64)."""
    a = np.ascontiguousarray(v)
    return a if a.dtype == np.uint16 else a.astype(np.int64)


def _format_events_txt_numpy(
    t_ns: NDArray[np.int64], x: NDArray[Any], y: NDArray[Any], p: NDArray[Any]
) -> bytes:
    """NumPy digit-arithmetic reference of :func:`format_events_txt` (benchmark baseline)."""
    n = int(t_ns.shape[0])
    if n == 0:
        return b""
    t = np.asarray(t_ns, dtype=np.int64)
    sec, frac = t // _NS, t % _NS
    xs = np.asarray(x, dtype=np.int64)
    ys = np.asarray(y, dtype=np.int64)
    ws = len(str(int(sec.max())))
    wx = len(str(int(xs.max())))
    wy = len(str(int(ys.max())))
    width = ws + 1 + 9 + 1 + wx + 1 + wy + 1 + 1 + 1
    buf = np.empty((n, width), np.uint8)
    keep = np.ones((n, width), bool)
    _put(buf, keep, 0, sec, ws)
    c = ws
    buf[:, c] = ord(".")
    _put(buf, None, c + 1, frac, 9)  # fraction: all nine digits kept
    c += 10
    for v, w in ((xs, wx), (ys, wy)):
        buf[:, c] = ord(" ")
        _put(buf, keep, c + 1, v, w)
        c += 1 + w
    buf[:, c] = ord(" ")
    buf[:, c + 1] = np.where(np.asarray(p) > 0, ord("1"), ord("0"))
    buf[:, c + 2] = ord("\n")
    if keep.all():
        return buf.tobytes()
    return buf[keep].tobytes()


class EventTextWriter:
    """Appends events to ``events.txt``."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._fh = path.open("wb")
        self.count = 0
        self._buf = np.empty(0, np.uint8)  # the text of a batch, reused

    def write(self, batch: EventBatch) -> None:
        step = 1 << 18  # bounds the text buffer
        for a in range(0, batch.size, step):
            b = batch.slice(a, a + step)
            text = _format_txt(b.t, b.x, b.y, b.p, self._buf)
            self._fh.write(text.data)  # (copied by the write: the buffer is free again)
            base = text.base
            if isinstance(base, np.ndarray) and base.shape[0] > self._buf.shape[0]:
                self._buf = base  # a larger buffer was needed: keep it
        self.count += batch.size

    def close(self) -> None:
        if not self._fh.closed:
            self._fh.close()


class EventH5Writer:
    """Appends events to ``events.h5`` in the DSEC layout, in whole chunks (bounded memory).

    Layout (DSEC, Gehrig et al. 2021, what DSEC loaders read):

    * ``events/t`` int64 microseconds since the trajectory start (floor of the exact ns
      time), ``events/x``, ``events/y`` uint16, ``events/p`` uint8 in {0 OFF, 1 ON};
    * ``t_offset`` int64 scalar: microseconds to add to ``events/t`` for the absolute (bag)
      stamp, i.e. ``output.start_time`` in microseconds;
    * ``ms_to_idx`` uint64: ``ms_to_idx[m]`` is the index of the first event with
      ``t >= 1000 m`` microseconds, for every millisecond up to one past the last event;
    * ``events/t_ns`` int64: the exact nanosecond times, only when they are not whole
      microseconds (``exact_ns``; an extra dataset: DSEC loaders ignore it, roslan's own
      readers prefer it). A sensor with 1 us timestamps needs none: ``t`` is exact.

    Args:
        path: the file to create.
        width, height: sensor resolution (``width``/``height`` attributes).
        chunk: events per HDF5 chunk.
        compression: ``"gzip"`` (level 1, any HDF5 reader), ``"lzf"`` (h5py's own filter,
            faster, larger) or None.
        t_offset_ns: absolute stamp of trajectory time 0 (written as ``t_offset`` in us).
        exact_ns: also write ``events/t_ns`` (event times with sub-microsecond digits).
    """

    FIELDS = (
        ("t", np.int64),
        ("x", np.uint16),
        ("y", np.uint16),
        ("p", np.uint8),
        ("t_ns", np.int64),
    )

    def __init__(
        self,
        path: Path,
        width: int,
        height: int,
        chunk: int = 1 << 16,
        compression: Literal["gzip", "lzf"] | None = "gzip",
        t_offset_ns: int = 0,
        exact_ns: bool = True,
    ) -> None:
        import h5py

        if compression not in ("gzip", "lzf", None):
            msg = f"events.h5 compression {compression!r}: use 'gzip', 'lzf' or None"
            raise ValueError(msg)

        self.path = path
        self.chunk = int(chunk)
        self._f = h5py.File(path, "w", libver="earliest", track_order=False)
        g = self._f.create_group("events")
        self._ds: dict[str, Any] = {}
        opts: dict[str, Any] = {
            "compression": compression,
            "compression_opts": 1 if compression == "gzip" else None,
            "shuffle": compression is not None,
            "track_times": False,
        }
        self._fields = [(n, dt) for n, dt in self.FIELDS if exact_ns or n != "t_ns"]
        for name, dt in self._fields:
            self._ds[name] = g.create_dataset(
                name, shape=(0,), maxshape=(None,), dtype=dt, chunks=(self.chunk,), **opts
            )
        self._ms = self._f.create_dataset(
            "ms_to_idx", shape=(0,), maxshape=(None,), dtype=np.uint64, chunks=(4096,), **opts
        )
        self._f.create_dataset("t_offset", data=np.int64(int(t_offset_ns) // 1000))
        for holder in (self._f.attrs, g.attrs):
            holder["width"] = int(width)
            holder["height"] = int(height)
        g["t"].attrs["unit"] = "us since the trajectory start; absolute = t + t_offset"
        if exact_ns:
            g["t_ns"].attrs["unit"] = "ns since the trajectory start (exact)"
        g["p"].attrs["values"] = "1 ON (brighter), 0 OFF"
        self._pending: list[EventBatch] = []
        self._labels: list[NDArray[np.uint32]] | None = None  # events/label, when given
        self._opts = opts
        self._n_pending = 0
        self._next_ms = 0  # first millisecond whose ms_to_idx entry is not yet written
        self.count = 0

    def write(self, batch: EventBatch, labels: NDArray[np.uint32] | None = None) -> None:
        """Append ``batch`` (and its ``events/label`` values: give them with every batch
        or never)."""
        if labels is not None and self._labels is None:
            ds = self._f["events"].create_dataset(
                "label", shape=(0,), maxshape=(None,), dtype=np.uint32,
                chunks=(self.chunk,), **self._opts,
            )  # fmt: skip
            ds.attrs["encoding"] = "SemanticKITTI: class | instance << 16 (docs/guide/labels.md)"
            self._ds["label"] = ds
            self._labels = []
        if batch.size == 0:
            return
        if self._labels is not None:
            if labels is None or labels.shape[0] != batch.size:
                msg = f"{self.path}: give events/label values with every batch, one per event"
                raise ValueError(msg)
            self._labels.append(labels)
        self._pending.append(batch)
        self._n_pending += batch.size
        if self._n_pending >= self.chunk:
            self._flush(final=False)

    def _append_ms(self, values: NDArray[np.int64]) -> None:
        if values.size:
            n = self._ms.shape[0]
            self._ms.resize((n + values.size,))
            self._ms[n:] = values.astype(np.uint64)
            self._next_ms += int(values.size)

    def _flush(self, *, final: bool) -> None:
        if self._n_pending == 0:
            return
        allb = EventBatch.concatenate(self._pending)
        m = allb.size if final else (allb.size // self.chunk) * self.chunk
        if m == 0:
            return
        n0 = self.count
        t_ns = np.asarray(allb.t[:m], dtype=np.int64)
        t_us = t_ns // 1000
        cols = {"t": t_us, "x": allb.x[:m], "y": allb.y[:m], "p": np.asarray(allb.p[:m]) > 0}
        cols["t_ns"] = t_ns
        for name, dt in self._fields:
            ds = self._ds[name]
            ds.resize((n0 + m,))
            ds[n0 : n0 + m] = np.asarray(cols[name], dtype=dt)
        # every millisecond whose first event is decided: 1000 ms <= the last time written
        last_ms = int(t_us[-1]) // 1000
        ms = np.arange(self._next_ms, last_ms + 1, dtype=np.int64)
        self._append_ms(n0 + np.searchsorted(t_us, ms * 1000, side="left"))
        if self._labels is not None:
            lab = np.concatenate(self._labels)
            ds = self._ds["label"]
            ds.resize((n0 + m,))
            ds[n0 : n0 + m] = lab[:m]
            self._labels = [lab[m:]] if lab.size > m else []
        self.count += m
        rest = allb.slice(m, allb.size)
        self._pending = [rest] if rest.size else []
        self._n_pending = rest.size

    def close(self) -> None:
        if self._f.id.valid:
            self._flush(final=True)
            # one entry past the last event's millisecond: the end of the last window
            self._append_ms(np.full(1, self.count, np.int64))
            self._f.attrs["count"] = self.count
            self._f.close()
