"""Readers of a run's OUTDIR for the plots and the preview video.

Every reader raises :class:`PlotError` naming the file and the sensor a plot needs
when an input is missing or unreadable. Times are read from the dataset text files
(seconds since the trajectory start, 9 decimals) into int64 nanoseconds.

Large inputs are streamed: :class:`EventSource` answers time windows from
``events.h5`` by binary search, or walks ``events.txt`` forward chunk by chunk
(memory bounded by the window plus one chunk); LiDAR scans and images are loaded one
at a time.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from itertools import islice
from pathlib import Path
from typing import Any, TextIO

import numpy as np
from numpy.typing import NDArray

from roslan.errors import RoslanError
from roslan.rundir.calibration import root_camera_name

__all__ = [
    "EventSource",
    "ImageSequence",
    "ImuData",
    "LidarScan",
    "LidarSequence",
    "PlotError",
    "TrajectoryTable",
    "add_outdir_command",
    "find_images",
    "find_lidar",
    "load_imu",
    "load_run",
    "load_summary",
    "load_trajectory_table",
    "missing_input",
    "open_events",
    "resolved_config",
    "seconds_to_ns",
    "sensor_configs",
]


def add_outdir_command(
    subparsers: Any, name: str, help_text: str, doc: str | None, output_help: str
) -> argparse.ArgumentParser:
    """A subcommand reading one ``roslan simulate`` OUTDIR, with an optional ``-o`` file."""
    p: argparse.ArgumentParser = subparsers.add_parser(
        name,
        help=help_text,
        description=doc,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("outdir", metavar="OUTDIR", help="output folder of a roslan simulate run")
    p.add_argument("-o", "--output", type=Path, default=None, help=output_help)
    return p


F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

TRAJECTORY_HEADER = "t,x,y,z,roll,pitch,yaw,vx,vy,vz,vroll,vpitch,vyaw,ax,ay,az,aroll,apitch,ayaw"


class PlotError(RoslanError):
    """A plot cannot be drawn: an input it needs is missing or unreadable."""


def missing_input(command: str, outdir: Path, what: str, sensor_type: str | None) -> PlotError:
    """The error for an absent input: names the command, OUTDIR, the files and the sensor."""
    msg = f"{command}: {outdir} has no {what}"
    if sensor_type is not None:
        msg += f"; add a sensor of type {sensor_type} to the config and simulate again"
    return PlotError(msg)


def seconds_to_ns(t: NDArray[Any]) -> I64:
    """Seconds (float) -> int64 nanoseconds, rounded (the files carry 9 decimals)."""
    return np.rint(np.asarray(t, dtype=np.float64) * 1e9).astype(np.int64)


def _check_outdir(outdir: Path, command: str) -> None:
    if not outdir.is_dir():
        msg = f"{command}: {outdir} is not a directory (give a roslan simulate OUTDIR)"
        raise PlotError(msg)


def _loadtxt(path: Path, columns: int, what: str, *, delimiter: str | None = None) -> F64:
    """A numeric text table (``#`` comments; a non-numeric header line is skipped)."""
    try:
        with path.open() as fh:
            first = fh.readline()
            skip = 0 if _is_numeric_line(first, delimiter) else 1
        data = np.loadtxt(path, delimiter=delimiter, skiprows=skip, ndmin=2, comments="#")
    except (OSError, ValueError) as err:
        msg = f"{path}: cannot read {what}: {err}"
        raise PlotError(msg) from err
    if data.shape[0] == 0:
        msg = f"{path}: no rows ({what} expected)"
        raise PlotError(msg)
    if data.shape[1] != columns:
        msg = f"{path}: {data.shape[1]} columns; {what} has {columns}"
        raise PlotError(msg)
    if not np.all(np.isfinite(data)):
        msg = f"{path}: non-finite values in {what}"
        raise PlotError(msg)
    return np.asarray(data, dtype=np.float64)


def _is_numeric_line(line: str, delimiter: str | None) -> bool:
    parts = [p for p in line.strip().split(delimiter) if p]
    if not parts or line.lstrip().startswith("#"):
        return True
    try:
        [float(p) for p in parts]
    except ValueError:
        return False
    return True


# ---------------------------------------------------------------- run.json / config
def _load_json(path: Path) -> dict[str, Any] | None:
    """A JSON object file as a dict; None when the file is missing or not an object."""
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError) as err:
        msg = f"{path}: not valid JSON: {err}"
        raise PlotError(msg) from err
    return data if isinstance(data, dict) else None


def load_run(outdir: Path) -> dict[str, Any] | None:
    """``run.json`` as a dict, or None when the run has none."""
    return _load_json(outdir / "run.json")


def load_summary(outdir: Path) -> dict[str, Any] | None:
    """``summary.json`` (trajectory summary: touchdown_time, tau0, k...) or None."""
    return _load_json(outdir / "summary.json")


def resolved_config(run: dict[str, Any] | None) -> dict[str, Any] | None:
    """The resolved simulation config inside run.json (``config`` key, or run.json itself)."""
    if run is None:
        return None
    for key in ("config", "resolved_config", "sim_config"):
        value = run.get(key)
        if isinstance(value, dict):
            return value
    if isinstance(run.get("trajectory"), dict) and "sensors" in run:
        return run
    return None


def sensor_configs(outdir: Path, sensor_type: str | Sequence[str]) -> list[dict[str, Any]]:
    """The run.json sensor config mappings of the given type(s), in config order."""
    cfg = resolved_config(load_run(outdir))
    if cfg is None:
        return []
    types = {sensor_type} if isinstance(sensor_type, str) else set(sensor_type)
    sensors = cfg.get("sensors") or []
    return [s for s in sensors if isinstance(s, dict) and s.get("type") in types]


# ---------------------------------------------------------------- trajectory
@dataclass(frozen=True, slots=True)
class TrajectoryTable:
    """The 18 gap components in the goal frame F at N instants.

    Attributes:
        t: (N,) trajectory time, s.
        gaps, rates, accels: (N, 6) x y z (m) roll pitch yaw (rad), their rates
            (m/s, rad/s) and accelerations (m/s^2, rad/s^2), frame F.
    """

    t: F64
    gaps: F64
    rates: F64
    accels: F64


def load_trajectory_table(outdir: Path, command: str) -> TrajectoryTable:
    """``trajectory.csv`` (written by every run)."""
    _check_outdir(outdir, command)
    path = outdir / "trajectory.csv"
    if not path.is_file():
        raise missing_input(command, outdir, "trajectory.csv (the trajectory table)", None)
    data = _loadtxt(path, 19, f"the trajectory table ({TRAJECTORY_HEADER})", delimiter=",")
    return TrajectoryTable(
        t=data[:, 0], gaps=data[:, 1:7], rates=data[:, 7:13], accels=data[:, 13:19]
    )


def load_groundtruth(outdir: Path) -> tuple[F64, F64, F64] | None:
    """``groundtruth.txt`` (TUM, world): (t (N,) s, position (N, 3) m, quat_xyzw (N, 4))."""
    path = outdir / "groundtruth.txt"
    if not path.is_file():
        return None
    data = _loadtxt(path, 8, "TUM ground truth (t tx ty tz qx qy qz qw)")
    return data[:, 0], data[:, 1:4], data[:, 4:8]


# ---------------------------------------------------------------- IMU
@dataclass(frozen=True, slots=True)
class ImuData:
    """Measured IMU samples: t (N,) s; acc (N, 3) m/s^2 and gyro (N, 3) rad/s in the IMU frame."""

    t: F64
    acc: F64
    gyro: F64
    path: Path


def find_imu_files(outdir: Path) -> list[Path]:
    """``imu.txt`` and, for runs with several IMUs, ``imu_<name>.txt`` / ``imu/<name>.txt``."""
    out = [p for p in (outdir / "imu.txt",) if p.is_file()]
    out += sorted(outdir.glob("imu_*.txt"))
    if (outdir / "imu").is_dir():
        out += sorted((outdir / "imu").glob("*.txt"))
    return out


def load_imu(outdir: Path, command: str, path: Path | None = None) -> ImuData:
    """The IMU text file ``t ax ay az gx gy gz`` (Event Camera Dataset layout)."""
    _check_outdir(outdir, command)
    if path is None:
        files = find_imu_files(outdir)
        if not files:
            raise missing_input(command, outdir, "IMU samples (imu.txt)", "imu")
        path = files[0]
    data = _loadtxt(path, 7, "IMU samples (t ax ay az gx gy gz)")
    return ImuData(t=data[:, 0], acc=data[:, 1:4], gyro=data[:, 4:7], path=path)


# ---------------------------------------------------------------- images
def _read_image(path: Path) -> NDArray[np.uint8]:
    """An image file as (H, W, 3) uint8 RGB (grayscale replicated; 16-bit scaled)."""
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        msg = f"{path}: cannot read image"
        raise PlotError(msg)
    if img.dtype == np.uint16:
        img = (np.asarray(img, dtype=np.uint16) // 257).astype(np.uint8)
    elif img.dtype != np.uint8:
        img = np.clip(np.nan_to_num(img.astype(np.float32)) * 255.0, 0, 255).astype(np.uint8)
    if img.ndim == 2:
        return np.repeat(img[:, :, None], 3, axis=2)
    if img.shape[2] == 4:
        img = img[:, :, :3]
    return np.ascontiguousarray(img[:, :, ::-1])


@dataclass(frozen=True, slots=True)
class ImageSequence:
    """Timestamped frames of one image listing (``images.txt``: ``t images/NNNNNNNN.png``).

    Attributes:
        name: label of the stream (the listing's folder or file stem).
        t_ns: (N,) int64 trajectory time of each frame, increasing.
        paths: the N image files.
    """

    name: str
    t_ns: I64
    paths: tuple[Path, ...]

    def __len__(self) -> int:
        return len(self.paths)

    def index_at(self, t_ns: int) -> int:
        """Index of the latest frame at or before ``t_ns`` (the first frame before it)."""
        i = int(np.searchsorted(self.t_ns, t_ns, side="right")) - 1
        return max(i, 0)

    def read(self, i: int) -> NDArray[np.uint8]:
        """Frame ``i`` as (H, W, 3) uint8 RGB."""
        return _read_image(self.paths[i])


def _read_listing(listing: Path, outdir: Path) -> ImageSequence:
    base = listing.parent
    times: list[float] = []
    paths: list[Path] = []
    try:
        lines = listing.read_text().splitlines()
    except OSError as err:
        msg = f"{listing}: cannot read: {err}"
        raise PlotError(msg) from err
    for n, line in enumerate(lines, 1):
        parts = line.split()
        if not parts or parts[0].startswith("#"):
            continue
        try:
            times.append(float(parts[0]))
        except ValueError:
            if n == 1:
                continue  # a header line
            msg = f"{listing}:{n}: expected 't path', got {line!r}"
            raise PlotError(msg) from None
        if len(parts) < 2:
            msg = f"{listing}:{n}: expected 't path', got {line!r}"
            raise PlotError(msg)
        paths.append(base / parts[1])
    t_ns = seconds_to_ns(np.asarray(times))
    order = np.argsort(t_ns, kind="stable")
    if listing.name == "images.txt":
        # <sensor>/images.txt names its sensor; the top-level one is the root camera's
        # (first event camera, else first camera), "images" without run.json
        name = (_root_camera_name(outdir) or "images") if listing.parent == outdir else base.name
    else:
        name = listing.stem.removeprefix("images_")
    return ImageSequence(name=name, t_ns=t_ns[order], paths=tuple(paths[i] for i in order))


def _root_camera_name(outdir: Path) -> str | None:
    """The camera whose images.txt is at the OUTDIR root (run.json's first event camera,
    else its first camera; a stereo camera's left eye)."""
    cfgs = sensor_configs(outdir, ("event_camera", "camera", "stereo_camera"))
    return root_camera_name((str(c.get("type")), str(c.get("name"))) for c in cfgs)


def find_images(outdir: Path, prefer: Sequence[str] = ()) -> list[ImageSequence]:
    """All non-empty image listings: ``images.txt`` at the top, then one per sub-folder
    (``<sensor>/images.txt``) and ``images_<name>.txt`` files. Streams whose name contains
    one of ``prefer`` come first."""
    listings: list[Path] = []
    top = outdir / "images.txt"
    if top.is_file():
        listings.append(top)
    listings += sorted(outdir.glob("images_*.txt"))
    listings += sorted(p for p in outdir.glob("*/images.txt") if p.is_file())
    seqs = [s for s in (_read_listing(p, outdir) for p in listings) if len(s)]

    def rank(s: ImageSequence) -> int:
        for i, key in enumerate(prefer):
            if key in s.name:
                return i
        return len(prefer)

    return sorted(seqs, key=rank)


# ---------------------------------------------------------------- events
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
    def _h5_search(self, t_ns: int) -> int:
        """First index with t >= t_ns (bisection reading single elements: O(log N) reads)."""
        lo, hi = 0, int(self._t.shape[0])
        while lo < hi:
            mid = (lo + hi) // 2
            if int(self._t[mid]) * self._t_scale < t_ns:
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
            return None if n == 0 else (int(self._t[0]), int(self._t[n - 1]))
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
    _check_outdir(outdir, command)
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
    """(width, height) of a camera-like sensor config, whatever the key layout."""
    for holder in (cfg, cfg.get("intrinsics") or {}, cfg.get("camera") or {}):
        if not isinstance(holder, dict):
            continue
        if "width" in holder and "height" in holder:
            return int(holder["width"]), int(holder["height"])
        if "resolution" in holder:
            res = holder["resolution"]
            if isinstance(res, list | tuple) and len(res) == 2:
                return int(res[0]), int(res[1])
    return None, None


# ---------------------------------------------------------------- LiDAR
@dataclass(frozen=True, slots=True)
class LidarScan:
    """One LiDAR scan in the sensor frame.

    Attributes:
        xyz: (M, 3) float64 points, m (only finite returns).
        intensity: (M,) float64 or None.
        ring: (M,) int64 laser index or None.
        time: (M,) float64 s from the scan stamp, or None.
        t_ns: trajectory time of the scan, ns.
    """

    xyz: F64
    intensity: F64 | None
    ring: NDArray[np.int64] | None
    time: F64 | None
    t_ns: int


@dataclass(frozen=True, slots=True)
class LidarSequence:
    """The scans of one LiDAR: ``lidar/<name>/NNNNNN.npz``, ordered by index.

    Attributes:
        name: the sensor name (folder).
        paths: scan files.
        t_ns: (N,) int64 scan stamp (trajectory time) of each file.
    """

    name: str
    paths: tuple[Path, ...]
    t_ns: I64

    def __len__(self) -> int:
        return len(self.paths)

    def index_at(self, t_ns: int) -> int:
        """Index of the latest scan stamped at or before ``t_ns``."""
        return max(int(np.searchsorted(self.t_ns, t_ns, side="right")) - 1, 0)

    def read(self, i: int) -> LidarScan:
        return _read_scan(self.paths[i], int(self.t_ns[i]))


def _npz_stamp(path: Path) -> int | None:
    try:
        with np.load(path) as z:
            for key in ("t_ns", "stamp_ns", "stamp"):
                if key in z.files:
                    v = np.asarray(z[key]).reshape(-1)
                    if v.size:
                        return int(v[0]) if v.dtype.kind in "iu" else round(float(v[0]) * 1e9)
            if "t" in z.files:
                v = np.asarray(z["t"]).reshape(-1)
                if v.size == 1:
                    return round(float(v[0]) * 1e9)
    except (OSError, ValueError) as err:
        msg = f"{path}: cannot read LiDAR scan: {err}"
        raise PlotError(msg) from err
    return None


def _read_scan(path: Path, t_ns: int) -> LidarScan:
    try:
        with np.load(path) as z:
            arrays = {k: np.asarray(z[k]) for k in z.files}
    except (OSError, ValueError) as err:
        msg = f"{path}: cannot read LiDAR scan: {err}"
        raise PlotError(msg) from err
    if all(k in arrays for k in "xyz"):
        xyz = np.stack([arrays[k].reshape(-1) for k in "xyz"], axis=1)
    elif "points" in arrays and arrays["points"].ndim == 2 and arrays["points"].shape[1] >= 3:
        xyz = arrays["points"][:, :3]
    else:
        msg = f"{path}: a LiDAR scan needs arrays x, y, z (or points (M, 3)); has {sorted(arrays)}"
        raise PlotError(msg)
    xyz = xyz.astype(np.float64)
    ok = np.all(np.isfinite(xyz), axis=1) & (np.abs(xyz).sum(axis=1) > 0)

    def col(key: str) -> NDArray[Any] | None:
        a = arrays.get(key)
        if a is None or a.reshape(-1).shape[0] != ok.shape[0]:
            return None
        return np.asarray(a.reshape(-1)[ok])

    ring = col("ring")
    intensity = col("intensity")
    time = col("time")
    return LidarScan(
        xyz=xyz[ok],
        intensity=None if intensity is None else intensity.astype(np.float64),
        ring=None if ring is None else ring.astype(np.int64),
        time=None if time is None else time.astype(np.float64),
        t_ns=t_ns,
    )


def _scan_times(folder: Path, paths: list[Path], rate: float | None) -> I64:
    """Scan stamps: a ``timestamps.txt``/``scans.txt`` listing, a stamp in each file,
    or index / rate."""
    for listing in ("timestamps.txt", "scans.txt", "times.txt"):
        f = folder / listing
        if f.is_file():
            rows = [ln.split() for ln in f.read_text().splitlines() if ln.strip()]
            rows = [r for r in rows if not r[0].startswith("#")]
            try:
                times = {
                    (Path(r[1]).name if len(r) > 1 else str(i)): float(r[0])
                    for i, r in enumerate(rows)
                }
            except ValueError:
                continue
            if all(p.name in times for p in paths):
                return seconds_to_ns(np.asarray([times[p.name] for p in paths]))
            if len(times) == len(paths):
                return seconds_to_ns(np.asarray([float(r[0]) for r in rows]))
    stamps = [_npz_stamp(p) for p in paths[:1]]
    if stamps[0] is not None:
        return np.asarray([_npz_stamp(p) for p in paths], dtype=np.int64)
    hz = rate if rate and rate > 0 else 10.0
    idx = np.asarray([int(p.stem) if p.stem.isdigit() else i for i, p in enumerate(paths)])
    return np.rint(idx * (1e9 / hz)).astype(np.int64)


def find_lidar(outdir: Path, command: str) -> list[LidarSequence]:
    """All LiDAR scan folders ``lidar/<name>/*.npz`` (raises the "add a lidar" error if none)."""
    _check_outdir(outdir, command)
    root = outdir / "lidar"
    seqs: list[LidarSequence] = []
    if root.is_dir():
        rates = {
            str(c.get("name")): float(c.get("rate") or 0.0)
            for c in sensor_configs(outdir, ("lidar", "solid_state_lidar"))
        }
        folders = sorted(p for p in root.iterdir() if p.is_dir())
        if any(root.glob("*.npz")):
            folders.insert(0, root)
        for folder in folders:
            paths = sorted(folder.glob("*.npz"))
            if paths:
                t_ns = _scan_times(folder, paths, rates.get(folder.name))
                order = np.argsort(t_ns, kind="stable")
                seqs.append(
                    LidarSequence(
                        name=folder.name,
                        paths=tuple(paths[i] for i in order),
                        t_ns=t_ns[order],
                    )
                )
    if not seqs:
        raise missing_input(command, outdir, "LiDAR scans (lidar/<name>/NNNNNN.npz)", "lidar")
    return seqs


def chunks(n: int, size: int) -> Iterator[tuple[int, int]]:
    """(start, stop) pairs covering range(n) in steps of ``size``."""
    for i in range(0, n, size):
        yield i, min(i + size, n)


def nice_time_step(span: float, target: int = 6) -> float:
    """A 1/2/5 x 10^k step giving about ``target`` ticks over ``span``."""
    raw = max(span, 1e-9) / target
    mag = 10 ** math.floor(math.log10(raw))
    for m in (1, 2, 5, 10):
        if m * mag >= raw:
            return float(m * mag)
    return float(10 * mag)
