"""``roslan export semantickitti OUTDIR``: a labelled LiDAR's scans in the SemanticKITTI layout.

A run with ``output.labels: true`` writes a ``label`` array in each LiDAR scan
(``lidar/<name>/NNNNNN.npz``). This turns one LiDAR's scans into the layout SemanticKITTI
(and the KITTI odometry benchmark it extends) uses, which its tools and most LiDAR
segmentation code read::

    DEST/sequences/00/velodyne/000000.bin   float32 x, y, z, remission per point (N x 4,
                                            little-endian, no header), sensor frame
    DEST/sequences/00/labels/000000.label   uint32 per point, the same order: class id in
                                            the low 16 bits, instance id in the high 16
    DEST/sequences/00/poses.txt             per scan: the first 3 rows of the 4 x 4 pose
                                            of the scan relative to the first, row-major
                                            (12 numbers; the first line is the identity)
    DEST/sequences/00/times.txt             per scan: its stamp, s since the trajectory
                                            start (``%e``, KITTI's own format)
    DEST/sequences/00/calib.txt             ``P0:`` .. ``P3:`` and ``Tr:``, 12 numbers each
    DEST/roslan_export.json                 which run, which LiDAR, how many scans/points

Facts of the layout: KITTI's poses are those of its camera 0 and ``Tr`` maps the Velodyne
frame into that camera's; SemanticKITTI's tools read the LiDAR pose as ``Tr^-1 P Tr``.
roslan has no KITTI camera, so ``Tr`` is the identity (camera 0 is the LiDAR frame) and
``P0`` .. ``P3`` are ``[I | 0]``: the poses are the LiDAR's own. A pose is the sensor's at
its scan stamp (the turn's first firing): the base_link pose of ``groundtruth.txt``
(interpolated between its rows when the stamp falls between them: slerp and linear) times
the LiDAR's ``T_base_link_sensor`` of ``calib/extrinsics.yaml``. The points are the scan's
own (each in the sensor frame at its firing instant, not de-skewed). ``remission`` is the
scan's ``intensity`` divided by the LiDAR's ``intensity_scale`` (run.json; default 255), in
[0, 1] as KITTI's.

The export is written into a hidden sibling folder and moved to DEST when complete; an
existing DEST is replaced only with ``overwrite`` and only if it is an earlier roslan
export (it holds ``roslan_export.json``). Scans are read and written one at a time.
"""

from __future__ import annotations

import json
import shutil
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from roslan.errors import OutputError, PlotError
from roslan.frames import quat_xyzw_to_matrix
from roslan.io.files import atomic_write_text, current_umask
from roslan.rundir.folder import note_derived
from roslan.rundir.readers import (
    LIDAR_TYPES,
    LidarSequence,
    find_lidar,
    load_groundtruth,
    sensor_configs,
)

__all__ = ["MARKER", "export_semantickitti", "sensor_poses"]

MARKER = "roslan_export.json"
"""The file that marks a folder as a roslan SemanticKITTI export (what ``--overwrite``
may replace)."""

COMMAND = "roslan export semantickitti"

F64 = NDArray[np.float64]


def _has_labels(seq: LidarSequence) -> bool:
    try:
        with np.load(seq.paths[0]) as z:
            return "label" in z.files
    except (OSError, ValueError) as err:
        msg = f"{COMMAND}: {seq.paths[0]}: cannot read LiDAR scan: {err}"
        raise PlotError(msg) from err


def _pick(outdir: Path, lidar: str | None) -> LidarSequence:
    """The LiDAR to export: ``lidar`` by name, or the only labelled one."""
    seqs = find_lidar(outdir, COMMAND)
    labelled = [s for s in seqs if _has_labels(s)]
    names = [s.name for s in seqs]
    if lidar is not None:
        match = [s for s in seqs if s.name == lidar]
        if not match:
            msg = f"{COMMAND}: --lidar {lidar!r}: {outdir} has no such LiDAR; it has {names}"
            raise PlotError(msg)
        if match[0] not in labelled:
            msg = (
                f"{COMMAND}: --lidar {lidar!r}: its scans in {outdir / 'lidar' / lidar} have no "
                "'label' array; simulate with output.labels: true (and that LiDAR's own "
                "labels not false)"
            )
            raise PlotError(msg)
        return match[0]
    if not labelled:
        msg = (
            f"{COMMAND}: {outdir} has no labelled LiDAR: the scans of {names} have no "
            "'label' array; simulate with output.labels: true to write them"
        )
        raise PlotError(msg)
    if len(labelled) > 1:
        msg = (
            f"{COMMAND}: {outdir} has {len(labelled)} labelled LiDARs "
            f"{[s.name for s in labelled]}; choose one with --lidar NAME"
        )
        raise PlotError(msg)
    return labelled[0]


def _sensor_config(outdir: Path, name: str) -> dict[str, Any]:
    for cfg in sensor_configs(outdir, LIDAR_TYPES):
        if cfg.get("name") == name:
            return cfg
    return {}


def _extrinsics(outdir: Path, name: str) -> F64:
    """``T_base_link_sensor`` of LiDAR ``name`` from ``calib/extrinsics.yaml``."""
    import yaml

    path = outdir / "calib" / "extrinsics.yaml"
    try:
        with path.open(encoding="utf-8") as fh:
            data = yaml.safe_load(fh)
        T = np.asarray(data["sensors"][name]["T_base_link_sensor"], dtype=np.float64)
    except (OSError, yaml.YAMLError, KeyError, TypeError, ValueError) as err:
        msg = f"{COMMAND}: {path}: no T_base_link_sensor of LiDAR {name!r} ({err})"
        raise PlotError(msg) from err
    if T.shape != (4, 4) or not np.isfinite(T).all():
        msg = f"{COMMAND}: {path}: T_base_link_sensor of {name!r} is not a finite 4 x 4 matrix"
        raise PlotError(msg)
    return T


def sensor_poses(outdir: Path, name: str, t_ns: NDArray[np.int64]) -> NDArray[np.float64]:
    """(N, 4, 4) world pose of LiDAR ``name`` at trajectory times ``t_ns`` (see the module
    docstring: ``groundtruth.txt`` slerped, times the extrinsics)."""
    from scipy.spatial.transform import Rotation, Slerp

    gt = load_groundtruth(outdir)
    if gt is None or gt[0].shape[0] < 2:
        msg = f"{COMMAND}: {outdir / 'groundtruth.txt'} is missing or has under 2 rows"
        raise PlotError(msg)
    t, pos, quat = gt
    ts = np.asarray(t_ns, dtype=np.float64) * 1e-9
    if ts.size and (ts.min() < t[0] - 1e-9 or ts.max() > t[-1] + 1e-9):
        msg = (
            f"{COMMAND}: scan stamps {ts.min():.9f}-{ts.max():.9f} s lie outside "
            f"groundtruth.txt ({t[0]:.9f}-{t[-1]:.9f} s)"
        )
        raise PlotError(msg)
    ts = np.clip(ts, t[0], t[-1])
    # a stamp on a ground-truth row takes that row as it is; others are interpolated
    rows = np.searchsorted(t, ts)
    rows = np.minimum(rows, t.shape[0] - 1)
    exact = np.abs(t[rows] - ts) < 5e-10
    T = np.zeros((ts.shape[0], 4, 4))
    T[:, 3, 3] = 1.0
    T[:, :3, :3] = Slerp(t, Rotation.from_quat(quat))(ts).as_matrix()
    T[:, :3, 3] = np.stack([np.interp(ts, t, pos[:, k]) for k in range(3)], axis=1)
    T[exact, :3, :3] = quat_xyzw_to_matrix(quat[rows[exact]])
    T[exact, :3, 3] = pos[rows[exact]]
    out: NDArray[np.float64] = T @ _extrinsics(outdir, name)
    return out


def _rows12(T: F64) -> str:
    """Lines of the first 3 rows of each (4, 4) matrix, row-major, KITTI's ``%e``."""
    flat = np.asarray(T)[:, :3, :4].reshape(-1, 12)
    return "".join(" ".join(f"{v:.12e}" for v in row) + "\n" for row in flat)


def _calib_text() -> str:
    eye = " ".join(f"{v:.12e}" for v in np.eye(4)[:3].reshape(-1))
    return "".join(f"{key}: {eye}\n" for key in ("P0", "P1", "P2", "P3", "Tr"))


def _write_scans(seq: LidarSequence, folder: Path, scale: float) -> int:
    """Every scan's ``.bin`` and ``.label``; returns the number of points."""
    (folder / "velodyne").mkdir(parents=True)
    (folder / "labels").mkdir()
    total = 0
    for i, path in enumerate(seq.paths):
        try:
            with np.load(path) as z:
                cols = {k: np.asarray(z[k]).reshape(-1) for k in ("x", "y", "z", "intensity")}
                label = np.asarray(z["label"]).reshape(-1)
        except (OSError, ValueError, KeyError) as err:
            msg = f"{COMMAND}: {path}: cannot read a labelled LiDAR scan ({err})"
            raise PlotError(msg) from err
        n = cols["x"].shape[0]
        if any(a.shape[0] != n for a in (*cols.values(), label)):
            msg = f"{COMMAND}: {path}: x, y, z, intensity and label differ in length"
            raise PlotError(msg)
        pts = np.empty((n, 4), "<f4")
        pts[:, 0], pts[:, 1], pts[:, 2] = cols["x"], cols["y"], cols["z"]
        pts[:, 3] = cols["intensity"] / np.float32(scale) if scale > 0 else cols["intensity"]
        pts.tofile(folder / "velodyne" / f"{i:06d}.bin")
        label.astype("<u4").tofile(folder / "labels" / f"{i:06d}.label")
        total += n
    return total


def _replace(tmp: Path, dest: Path, overwrite: bool) -> None:
    """Move the finished export ``tmp`` to ``dest`` (an old export only with ``overwrite``)."""
    old: Path | None = None
    if dest.exists() or dest.is_symlink():
        if not overwrite:
            msg = f"{COMMAND}: {dest} appeared while exporting; pass --overwrite to replace it"
            raise OutputError(msg)
        old = Path(tempfile.mkdtemp(prefix=f".{dest.name}.old-", dir=dest.parent))
        old.rmdir()
        dest.rename(old)
    tmp.rename(dest)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def _check_dest(dest: Path, overwrite: bool) -> None:
    if not (dest.exists() or dest.is_symlink()):
        return
    if not overwrite:
        msg = f"{COMMAND}: {dest} exists; pass --overwrite to replace it"
        raise OutputError(msg)
    if not dest.is_dir() or dest.is_symlink() or not (dest / MARKER).is_file():
        msg = (
            f"{COMMAND}: {dest} exists and is not a roslan SemanticKITTI export (no {MARKER}); "
            "refusing to replace it even with --overwrite (choose another -o DEST)"
        )
        raise OutputError(msg)


def export_semantickitti(
    outdir: Path, dest: Path | None = None, *, lidar: str | None = None, overwrite: bool = False
) -> Path:
    """Export one labelled LiDAR of the run ``outdir`` to ``dest`` (default
    ``OUTDIR/semantickitti``) in the SemanticKITTI layout (module docstring); returns
    ``dest``.

    Raises:
        PlotError: ``outdir`` is not a run, has no (labelled) LiDAR, or a file is unreadable.
        OutputError: ``dest`` exists (without ``overwrite``, or not an earlier export).
    """
    outdir = Path(outdir)
    dest = Path(dest) if dest is not None else outdir / "semantickitti"
    seq = _pick(outdir, lidar)
    _check_dest(dest, overwrite)
    poses = sensor_poses(outdir, seq.name, seq.t_ns)
    relative = np.linalg.inv(poses[0]) @ poses
    relative[0] = np.eye(4)  # exactly, as KITTI's first line (not inv(T) T's rounding)
    scale = float(_sensor_config(outdir, seq.name).get("intensity_scale", 255.0) or 0.0)
    try:
        dest.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{dest.name}.partial-", dir=dest.parent))
    except OSError as err:
        msg = f"{COMMAND}: cannot write {dest}: {err.strerror or err}"
        raise OutputError(msg) from err
    try:
        folder = tmp / "sequences" / "00"
        points = _write_scans(seq, folder, scale)
        atomic_write_text(folder / "poses.txt", _rows12(relative))
        times = "".join(f"{t:e}\n" for t in (seq.t_ns * 1e-9).tolist())
        atomic_write_text(folder / "times.txt", times)
        atomic_write_text(folder / "calib.txt", _calib_text())
        info = {
            "source": str(outdir.resolve()),
            "lidar": seq.name,
            "sequence": "00",
            "scans": len(seq),
            "points": points,
            "remission_scale": scale,
            "T_world_first_scan": poses[0].tolist(),
        }
        atomic_write_text(tmp / MARKER, json.dumps(info, indent=2) + "\n")
        tmp.chmod(0o777 & ~current_umask())  # mkdtemp creates 0700
        _replace(tmp, dest, overwrite)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    note_derived(outdir, [p for p in dest.rglob("*") if p.is_file()])
    return dest
