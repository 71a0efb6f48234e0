"""Event recordings read whole into memory: AEDAT 4 (``.aedat4``: events and APS frames,
through the optional ``aedat`` package) and roslan's own ``events.h5`` / ``events.txt``
layouts (:mod:`roslan.events.files`).

Times are integer ns from the first event; polarity 1 ON, 0 OFF; x, y pixel column/row.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from roslan.errors import RecordingError

__all__ = ["AEDAT_INSTALL", "Recording", "read_recording"]

AEDAT_INSTALL = "pip install aedat  (or: pip install 'roslan[realism]')"
"""The install command of the AEDAT 4 reader."""

SUFFIXES = (".aedat4", ".h5", ".txt")


@dataclass(frozen=True)
class Recording:
    """Events ``t_ns`` (N,) int64 ns from the first event, ``x``, ``y`` (N,) int64,
    ``p`` (N,) int8 (1 ON, 0 OFF), sorted by time; APS ``frames`` (K, H, W) uint8 at
    ``frame_t_ns`` (K,) (exposure midpoints, same clock) or None."""

    path: Path
    width: int
    height: int
    t_ns: NDArray[np.int64]
    x: NDArray[np.int64]
    y: NDArray[np.int64]
    p: NDArray[np.int8]
    frames: NDArray[np.uint8] | None = None
    frame_t_ns: NDArray[np.int64] | None = None

    @property
    def duration_s(self) -> float:
        """Span from the first to the last event, s."""
        return float(self.t_ns[-1] - self.t_ns[0]) * 1e-9 if self.t_ns.size else 0.0


def read_recording(path: Path, size: tuple[int, int] | None = None) -> Recording:
    """Read ``path`` (.aedat4, .h5 or .txt); ``size`` (width, height) is needed only for a
    ``.txt`` file whose events do not span the sensor (default: largest x, y + 1).

    Raises :class:`RecordingError` naming the file and what is wrong.
    """
    path = Path(path)
    if path.suffix not in SUFFIXES:
        msg = f"{path}: unknown recording type {path.suffix!r}; allowed: {', '.join(SUFFIXES)}"
        raise RecordingError(msg)
    if not path.is_file():
        msg = f"{path}: no such file"
        raise RecordingError(msg)
    if path.suffix == ".aedat4":
        rec = _read_aedat(path)
    elif path.suffix == ".h5":
        rec = _read_h5(path)
    else:
        rec = _read_txt(path, size)
    if rec.t_ns.size == 0:
        msg = f"{path}: the recording holds no events"
        raise RecordingError(msg)
    bad = (rec.x < 0) | (rec.x >= rec.width) | (rec.y < 0) | (rec.y >= rec.height)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        msg = (
            f"{path}: event {i} at pixel ({rec.x[i]}, {rec.y[i]}) lies outside the "
            f"{rec.width}x{rec.height} sensor"
        )
        raise RecordingError(msg)
    return rec


def _finish(
    path: Path,
    width: int,
    height: int,
    t: NDArray[np.int64],
    x: NDArray[Any],
    y: NDArray[Any],
    p: NDArray[Any],
    frames: NDArray[np.uint8] | None = None,
    frame_t: NDArray[np.int64] | None = None,
) -> Recording:
    """Sorted by time, from the first event's instant."""
    order = np.argsort(t, kind="stable")
    t0 = int(t[order[0]]) if t.size else 0
    ft = None if frame_t is None else frame_t - t0
    return Recording(
        path,
        int(width),
        int(height),
        t[order] - t0,
        x[order].astype(np.int64),
        y[order].astype(np.int64),
        (p[order] > 0).astype(np.int8),
        frames,
        ft,
    )


def _read_aedat(path: Path) -> Recording:
    try:
        import aedat
    except ImportError as err:
        msg = f"{path}: reading AEDAT 4 needs the aedat package: {AEDAT_INSTALL}"
        raise RecordingError(msg) from err
    try:
        decoder = aedat.Decoder(str(path))
        streams = decoder.id_to_stream()
        ev = [s for s in streams.values() if s.get("type") == "events"]
        if not ev:
            kinds = sorted(str(s.get("type")) for s in streams.values())
            msg = f"{path}: no event stream (streams: {kinds})"
            raise RecordingError(msg)
        width, height = int(ev[0]["width"]), int(ev[0]["height"])
        events, frames, frame_t = [], [], []
        for packet in decoder:
            if "events" in packet:
                events.append(packet["events"])
            elif "frame" in packet:
                f = packet["frame"]
                px = np.asarray(f["pixels"])
                if px.ndim == 3:  # colour: the luma of the channels' mean
                    px = px.mean(axis=2).astype(np.uint8)
                if px.shape == (height, width):
                    frames.append(px)
                    mid = (int(f["exposure_begin_t"]) + int(f["exposure_end_t"])) // 2
                    frame_t.append(mid * 1000)
    except RecordingError:
        raise
    except Exception as err:  # the decoder's own errors (corrupt file, bad header)
        msg = f"{path}: cannot read as AEDAT 4: {err}"
        raise RecordingError(msg) from err
    e = (
        np.concatenate(events)
        if events
        else np.zeros(0, [("t", "u8"), ("x", "u2"), ("y", "u2"), ("on", "?")])
    )
    return _finish(
        path,
        width,
        height,
        e["t"].astype(np.int64) * 1000,
        e["x"],
        e["y"],
        e["on"],
        np.stack(frames) if frames else None,
        np.asarray(frame_t, np.int64) if frames else None,
    )


def _read_h5(path: Path) -> Recording:
    import h5py

    try:
        with h5py.File(path, "r") as f:
            g = f["events"]
            t = (
                np.asarray(g["t_ns"], np.int64)
                if "t_ns" in g
                else np.asarray(g["t"], np.int64) * 1000
            )
            x, y, p = (np.asarray(g[k]) for k in ("x", "y", "p"))
            width = int(f.attrs.get("width", g.attrs.get("width", 0)))
            height = int(f.attrs.get("height", g.attrs.get("height", 0)))
    except (OSError, KeyError) as err:
        msg = f"{path}: not an events.h5 (needs events/t, events/x, events/y, events/p): {err}"
        raise RecordingError(msg) from err
    if not (t.shape == x.shape == y.shape == p.shape):
        msg = f"{path}: events/t, x, y, p differ in length ({t.size}, {x.size}, {y.size}, {p.size})"
        raise RecordingError(msg)
    if width <= 0 or height <= 0:
        msg = f"{path}: width/height attributes missing (roslan's events.h5 has them)"
        raise RecordingError(msg)
    return _finish(path, width, height, t, x, y, p)


def _read_txt(path: Path, size: tuple[int, int] | None) -> Recording:
    try:
        with warnings.catch_warnings():  # an empty file: reported below
            warnings.simplefilter("ignore", UserWarning)
            a = np.loadtxt(path, ndmin=2, dtype=np.float64, comments="#")
    except ValueError as err:
        msg = f"{path}: not an events.txt ('t x y p' per line, t in s): {err}"
        raise RecordingError(msg) from err
    if a.size == 0:
        a = np.zeros((0, 4))
    if a.shape[1] != 4:
        msg = f"{path}: {a.shape[1]} columns per line; events.txt has 4 ('t x y p', t in s)"
        raise RecordingError(msg)
    t = np.rint(a[:, 0] * 1e9).astype(np.int64)
    x, y = a[:, 1].astype(np.int64), a[:, 2].astype(np.int64)
    if size is None:
        size = (int(x.max()) + 1 if x.size else 1, int(y.max()) + 1 if y.size else 1)
    return _finish(path, size[0], size[1], t, x, y, a[:, 3])
