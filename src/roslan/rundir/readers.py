"""Readers of a run's OUTDIR: the files the plots, the preview video and batch read.

Every reader raises :class:`PlotError` naming the file and the sensor a plot needs
when an input is missing or unreadable. Times are read from the dataset text files
(seconds since the trajectory start, 9 decimals) into int64 nanoseconds.

Large inputs are streamed: :class:`EventSource` answers time windows from
``events.h5`` by binary search, or walks ``events.txt`` forward chunk by chunk
(memory bounded by the window plus one chunk); LiDAR scans and images are loaded one
at a time.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from roslan.errors import PlotError
from roslan.rundir.calibration import root_camera_name

__all__ = [
    "LIDAR_TYPES",
    "ImageSequence",
    "ImuData",
    "LidarScan",
    "LidarSequence",
    "PlotError",
    "TrajectoryTable",
    "configured_names",
    "find_images",
    "find_lidar",
    "load_imu",
    "load_run",
    "load_summary",
    "load_trajectory_table",
    "missing_input",
    "require_run_folder",
    "resolved_config",
    "seconds_to_ns",
    "sensor_configs",
]


F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

TRAJECTORY_HEADER = "t,x,y,z,roll,pitch,yaw,vx,vy,vz,vroll,vpitch,vyaw,ax,ay,az,aroll,apitch,ayaw"


def missing_input(command: str, outdir: Path, what: str, sensor_type: str | None) -> PlotError:
    """The error for an absent input: names the command, OUTDIR, the files and the sensor."""
    msg = f"{command}: {outdir} has no {what}"
    if sensor_type is not None:
        msg += f"; add a sensor of type {sensor_type} to the config and simulate again"
    return PlotError(msg)


def seconds_to_ns(t: NDArray[Any]) -> I64:
    """Seconds (float) -> int64 nanoseconds, rounded (the files carry 9 decimals)."""
    return np.rint(np.asarray(t, dtype=np.float64) * 1e9).astype(np.int64)


def require_run_folder(outdir: Path, command: str) -> None:
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


LIDAR_TYPES = ("lidar", "solid_state_lidar")


def configured_names(outdir: Path, sensor_type: str | Sequence[str]) -> list[str]:
    """Names of the run's sensors of the given type(s) in config order: from run.json,
    else from ``calib/extrinsics.yaml`` (written in config order before run.json, which
    ``roslan simulate`` writes last)."""
    types = {sensor_type} if isinstance(sensor_type, str) else set(sensor_type)
    names = [str(c.get("name")) for c in sensor_configs(outdir, tuple(types))]
    if names:
        return names
    import yaml

    try:
        with (outdir / "calib" / "extrinsics.yaml").open(encoding="utf-8") as fh:
            data = yaml.safe_load(fh)
    except (OSError, yaml.YAMLError):
        return []
    sensors = data.get("sensors") if isinstance(data, dict) else None
    if not isinstance(sensors, dict):
        return []
    return [str(n) for n, c in sensors.items() if isinstance(c, dict) and c.get("type") in types]


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
    require_run_folder(outdir, command)
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
    require_run_folder(outdir, command)
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

    def read(self, i: int, max_points: int | None = None) -> LidarScan:
        """Scan ``i``; with ``max_points``, every k-th point of a denser scan (k the
        smallest stride that leaves at most that many), thinned before any conversion."""
        return _read_scan(self.paths[i], int(self.t_ns[i]), max_points)


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


def _read_scan(path: Path, t_ns: int, max_points: int | None = None) -> LidarScan:
    try:
        with np.load(path) as z:
            arrays = {k: np.asarray(z[k]) for k in z.files}
    except (OSError, ValueError) as err:
        msg = f"{path}: cannot read LiDAR scan: {err}"
        raise PlotError(msg) from err
    n = arrays["x"].size if "x" in arrays else 0
    if max_points is not None and n > max_points > 0:
        step = -(-n // max_points)
        arrays = {k: a.reshape(-1)[::step] if a.size == n else a for k, a in arrays.items()}
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
    require_run_folder(outdir, command)
    root = outdir / "lidar"
    seqs: list[LidarSequence] = []
    if root.is_dir():
        rates = {
            str(c.get("name")): float(c.get("rate") or 0.0)
            for c in sensor_configs(outdir, LIDAR_TYPES)
        }
        # in config order (the first configured LiDAR first), unknown folders after
        rank = {n: i for i, n in enumerate(configured_names(outdir, LIDAR_TYPES))}
        folders = sorted(
            (p for p in root.iterdir() if p.is_dir()),
            key=lambda p: (rank.get(p.name, len(rank)), p.name),
        )
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
