"""The event stream of a run, read by time window (``events.h5`` or ``events.txt``)."""

from __future__ import annotations

from itertools import islice
from pathlib import Path
from typing import Any, TextIO

import numpy as np
from numpy.typing import NDArray

from roslan.errors import PlotError
from roslan.rundir.readers import (
    I64,
    missing_input,
    require_run_folder,
    seconds_to_ns,
    sensor_configs,
)

__all__ = ["EventSource", "count_events", "open_events"]


class EventSource:
    """Events of one event camera, read by time window.

    ``window(t0_ns, t1_ns)`` returns ``(x, y, p)`` of the events with
    ``t0_ns <= t < t1_ns``: x, y (M,) int64 pixel coordinates, p (M,) int8 polarity
    in {-1, +1}. From ``events.h5`` any window is a binary search; from ``events.txt``
    windows must come in non-decreasing order (the file is walked forward once).
    """

    CHUNK = 1 << 20  # events.txt lines read per step

    def __init__(self, path: Path, width: int | None, height: int | None) -> None:
        self.path = path
        self.width = width
        self.height = height
        self._h5: Any = None
        self._t_scale = 1
        self._fh: TextIO | None = None
        self._buf_t: I64 = np.empty(0, np.int64)
        self._buf_xyp: NDArray[np.int64] = np.empty((0, 3), np.int64)
        self._eof = False
        self._last_t1 = -(1 << 62)
        if path.suffix == ".h5":
            import h5py

            try:
                self._h5 = h5py.File(path, "r")
                g = self._h5["events"]
                self._t, self._x, self._y, self._p = g["t"], g["x"], g["y"], g["p"]
                # exact ns when present, else DSEC's microseconds
                self._t_scale = 1 if "t_ns" in g else 1000
                if "t_ns" in g:
                    self._t = g["t_ns"]
            except (OSError, KeyError) as err:
                msg = f"{path}: cannot read events/t, events/x, events/y, events/p: {err}"
                raise PlotError(msg) from err
            for key in ("width", "height"):
                for holder in (self._h5.attrs, g.attrs):
                    if key in holder and getattr(self, key) is None:
                        setattr(self, key, int(holder[key]))

    def close(self) -> None:
        if self._h5 is not None:
            self._h5.close()
            self._h5 = None
        if self._fh is not None:
            self._fh.close()
            self._fh = None

    def __enter__(self) -> EventSource:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- HDF5
    def _h5_time_ns(self, i: int) -> int:
        """Time of event ``i`` in ns (``events/t_ns``, or DSEC's ``events/t`` in us)."""
        return int(self._t[i]) * self._t_scale

    def _h5_search(self, t_ns: int) -> int:
        """First index with t >= t_ns (bisection reading single elements: O(log N) reads)."""
        lo, hi = 0, int(self._t.shape[0])
        while lo < hi:
            mid = (lo + hi) // 2
            if self._h5_time_ns(mid) < t_ns:
                lo = mid + 1
            else:
                hi = mid
        return lo

    def window(
        self, t0_ns: int, t1_ns: int
    ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int8]]:
        if self._h5 is not None:
            i0, i1 = self._h5_search(t0_ns), self._h5_search(t1_ns)
            x = np.asarray(self._x[i0:i1], dtype=np.int64)
            y = np.asarray(self._y[i0:i1], dtype=np.int64)
            p = np.where(np.asarray(self._p[i0:i1]) > 0, 1, -1).astype(np.int8)
            return x, y, p
        return self._txt_window(t0_ns, t1_ns)

    # -- text
    def _txt_window(
        self, t0_ns: int, t1_ns: int
    ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int8]]:
        if t1_ns < self._last_t1:
            # going back in time: restart the forward walk
            self.close()
            self._buf_t = np.empty(0, np.int64)
            self._buf_xyp = np.empty((0, 3), np.int64)
            self._eof = False
        self._last_t1 = t1_ns
        if self._fh is None and not self._eof:
            self._fh = self.path.open()
        keep = self._buf_t >= t0_ns
        self._buf_t, self._buf_xyp = self._buf_t[keep], self._buf_xyp[keep]
        while not self._eof and (self._buf_t.size == 0 or self._buf_t[-1] < t1_ns):
            t, xyp = self._read_chunk()
            keep = t >= t0_ns
            self._buf_t = np.concatenate([self._buf_t, t[keep]])
            self._buf_xyp = np.concatenate([self._buf_xyp, xyp[keep]])
        sel = (self._buf_t >= t0_ns) & (self._buf_t < t1_ns)
        xyp = self._buf_xyp[sel]
        return xyp[:, 0], xyp[:, 1], np.where(xyp[:, 2] > 0, 1, -1).astype(np.int8)

    def _read_chunk(self) -> tuple[I64, NDArray[np.int64]]:
        assert self._fh is not None
        lines = [ln for ln in islice(self._fh, self.CHUNK) if ln.strip() and ln[0] != "#"]
        if not lines:
            self._eof = True
            self._fh.close()
            self._fh = None
            return np.empty(0, np.int64), np.empty((0, 3), np.int64)
        try:
            data = np.loadtxt(lines, ndmin=2)
        except ValueError as err:
            msg = f"{self.path}: expected lines 't x y p': {err}"
            raise PlotError(msg) from err
        if data.shape[1] != 4:
            msg = f"{self.path}: {data.shape[1]} columns; expected 't x y p'"
            raise PlotError(msg)
        return seconds_to_ns(data[:, 0]), data[:, 1:4].astype(np.int64)

    def time_range_ns(self) -> tuple[int, int] | None:
        """(first, last) event time, or None without events. Reads the text file fully."""
        if self._h5 is not None:
            n = int(self._t.shape[0])
            return None if n == 0 else (self._h5_time_ns(0), self._h5_time_ns(n - 1))
        first = last = None
        with self.path.open() as fh:
            for line in fh:
                if line.strip() and line[0] != "#":
                    t = line.split(None, 1)[0]
                    if first is None:
                        first = t
                    last = t
        if first is None or last is None:
            return None
        return int(seconds_to_ns(np.asarray([float(first)]))[0]), int(
            seconds_to_ns(np.asarray([float(last)]))[0]
        )


def open_events(outdir: Path, command: str) -> EventSource:
    """The event stream of the run's event camera (``events.h5`` preferred over ``events.txt``)."""
    require_run_folder(outdir, command)
    candidates = [outdir / "events.h5", outdir / "events.txt"]
    candidates += sorted(outdir.glob("*/events.h5")) + sorted(outdir.glob("*/events.txt"))
    path = next((p for p in candidates if p.is_file()), None)
    if path is None:
        raise missing_input(command, outdir, "events (events.h5 or events.txt)", "event_camera")
    width = height = None
    for cfg in sensor_configs(outdir, "event_camera"):
        w, h = _config_resolution(cfg)
        if w is not None:
            width, height = w, h
            break
    return EventSource(path, width, height)


def _config_resolution(cfg: dict[str, Any]) -> tuple[int | None, int | None]:
    """(width, height) of a camera-like sensor config (its ``resolution`` key)."""
    res = cfg.get("resolution")
    if isinstance(res, list | tuple) and len(res) == 2:
        return int(res[0]), int(res[1])
    return None, None


def count_events(folder: Path) -> int:
    """Events a run wrote: rows of the first ``events.h5`` under ``folder``, else lines of
    the first ``events.txt``, else 0 (run.json does not count events)."""
    h5 = sorted(folder.rglob("events.h5"))
    if h5:
        import h5py

        with h5py.File(h5[0], "r") as f:
            return int(f["events/t"].shape[0])
    txt = sorted(folder.rglob("events.txt"))
    if txt:
        count = 0
        with txt[0].open("rb") as fh:
            for block in iter(lambda: fh.read(1 << 22), b""):
                count += block.count(b"\n")
        return count
    return 0
