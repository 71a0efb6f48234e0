"""An independent reference for the DSEC flow maps of a run, from its files only.

Built as a new user would check them, with none of roslan's flow or lens code: depth at
``t0`` from ``depth.h5``, base_link poses from ``groundtruth.txt`` (TUM, quaternions turned
into matrices by SciPy), the camera mount from ``calib/extrinsics.yaml`` (its
``T_base_link_sensor`` composed with the ``/tf_static`` link -> optical transform listed
there), the lens from ``calib/<camera>.yaml`` (ROS camera_info), and OpenCV's
``undistortPointsIter`` / ``projectPoints`` for the lens model.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import NDArray

F64 = NDArray[np.float64]


@dataclass
class FlowRun:
    """What the reference needs of one event camera of a run."""

    outdir: Path
    camera: str
    folder: Path
    K: F64
    D: F64
    model: str
    width: int
    height: int
    T_base_opt: F64
    gt_t_ns: NDArray[np.int64]
    gt_T_wb: NDArray[np.float64]
    depth: NDArray[np.float32]
    depth_t_ns: NDArray[np.int64]
    start_us: int


def _tum_matrices(rows: F64) -> NDArray[np.float64]:
    from scipy.spatial.transform import Rotation

    T = np.tile(np.eye(4), (rows.shape[0], 1, 1))
    T[:, :3, :3] = Rotation.from_quat(rows[:, 4:8]).as_matrix()  # x y z w
    T[:, :3, 3] = rows[:, 1:4]
    return T


def load_flow_run(outdir: Path, camera: str, folder: str = "") -> FlowRun:
    """The files of event camera ``camera`` (its dataset files in ``outdir/folder``)."""
    import h5py

    calib = yaml.safe_load((outdir / "calib" / f"{camera}.yaml").read_text())
    K = np.array(calib["camera_matrix"]["data"], np.float64).reshape(3, 3)
    D = np.array(calib["distortion_coefficients"]["data"], np.float64)
    ext = yaml.safe_load((outdir / "calib" / "extrinsics.yaml").read_text())
    T_base_link = np.array(ext["sensors"][camera]["T_base_link_sensor"], np.float64)
    frame = ext["sensors"][camera]["frame_id"]
    (T_link_opt,) = [
        np.array(s["T"], np.float64)
        for s in ext["static_transforms"]
        if s["parent"] == frame and s["child"] == f"{frame}_optical"
    ]
    gt = np.loadtxt(outdir / "groundtruth.txt")
    gt_t_ns = np.array([round(t * 1e9) for t in gt[:, 0]], np.int64)
    with h5py.File(outdir / folder / "depth.h5", "r") as f:
        depth = f["davis/left/depth_image_raw"][:]
        depth_t_ns = f["davis/left/depth_image_raw_t_ns"][:]
    start_ns = _start_ns(outdir / folder / "events.h5")
    return FlowRun(
        outdir,
        camera,
        outdir / folder,
        K,
        D,
        calib["distortion_model"],
        int(calib["image_width"]),
        int(calib["image_height"]),
        T_base_link @ T_link_opt,
        gt_t_ns,
        _tum_matrices(gt),
        depth,
        depth_t_ns,
        start_ns // 1000,
    )


def _start_ns(events_h5: Path) -> int:
    import h5py

    with h5py.File(events_h5, "r") as f:
        return int(f["t_offset"][()]) * 1000


def forward_rows(folder: Path) -> NDArray[np.int64]:
    """``flow/forward_timestamps.txt`` as (N, 2) absolute microseconds."""
    lines = (folder / "flow" / "forward_timestamps.txt").read_text().splitlines()
    assert lines[0] == "# from_timestamp_us, to_timestamp_us"
    return np.array([[int(v) for v in ln.split(",")] for ln in lines[1:]], np.int64).reshape(-1, 2)


def read_flow_png(path: Path) -> tuple[F64, NDArray[np.bool_]]:
    """DSEC's own decoding (``flow_16bit_to_float``) of a flow PNG read by OpenCV."""
    import cv2

    bgr = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert bgr is not None
    assert bgr.dtype == np.uint16
    assert bgr.shape[2] == 3
    rgb = bgr[..., ::-1].astype(np.float64)
    return (rgb[..., :2] - 2**15) / 128.0, rgb[..., 2] == 1


def _pose_at(run: FlowRun, t_ns: int) -> F64:
    (i,) = np.flatnonzero(run.gt_t_ns == t_ns)  # the test runs put every t0, t1 on a row
    T: F64 = run.gt_T_wb[i] @ run.T_base_opt
    return T


def _cv_dist(run: FlowRun) -> F64:
    return run.D if run.D.size else np.zeros(5)


def reference_flow(run: FlowRun, t0_ns: int, t1_ns: int) -> tuple[F64, F64, F64]:
    """(H, W, 2) true displacement of each pixel (where nothing is hit at ``t0``: of the
    point at infinity on its ray), with each pixel's 3-D point in the world (H, W, 3; NaN
    where nothing is hit) and the camera centre at ``t1`` (3,)."""
    import cv2

    assert run.model in ("plumb_bob", "none")
    (k,) = np.flatnonzero(run.depth_t_ns == t0_ns)
    z = run.depth[k].astype(np.float64)
    H, W = z.shape
    u, v = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    pix = np.stack([u.ravel(), v.ravel()], 1).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)
    xy = cv2.undistortPoints(pix, run.K, _cv_dist(run), None, None, None, crit).reshape(-1, 2)
    rays = np.stack([xy[:, 0], xy[:, 1], np.ones(xy.shape[0])], 1)
    P_c0 = rays * z.reshape(-1, 1)
    T0, T1 = _pose_at(run, t0_ns), _pose_at(run, t1_ns)
    P_w = P_c0 @ T0[:3, :3].T + T0[:3, 3]
    T_1w = np.linalg.inv(T1)
    P_c1 = P_w @ T_1w[:3, :3].T + T_1w[:3, 3]
    sky = ~np.isfinite(z.ravel())
    P_c1[sky] = rays[sky] @ (T_1w[:3, :3] @ T0[:3, :3]).T  # a direction: rotation only
    ok = P_c1[:, 2] > 0
    p1 = np.full((H * W, 2), np.nan)
    proj, _ = cv2.projectPoints(P_c1[ok].reshape(-1, 1, 3), np.zeros(3), np.zeros(3), run.K,
                                _cv_dist(run))  # fmt: skip
    p1[ok] = proj.reshape(-1, 2)
    flow = (p1 - pix.reshape(-1, 2)).reshape(H, W, 2)
    return flow, P_w.reshape(H, W, 3), T1[:3, 3].copy()


Box = tuple[tuple[float, float, float], tuple[float, float, float]]


def _box_entry(C: F64, d: F64, box: Box, shrink: float = 0.0) -> F64:
    """Ray parameter ``t >= 0`` where ``C + t d`` (d: (N, 3)) enters the box (inf: misses)."""
    lo, hi = np.array(box[0]) + shrink, np.array(box[1]) - shrink
    with np.errstate(divide="ignore", invalid="ignore"):
        a, b = (lo - C) / d, (hi - C) / d
    t_in = np.nanmax(np.minimum(a, b), axis=1)
    t_out = np.nanmin(np.maximum(a, b), axis=1)
    hit = (t_in <= t_out) & (t_out > 0)
    return np.where(hit, np.maximum(t_in, 0.0), np.inf)


def on_boxes(P: F64, boxes: list[Box], eps: float = 5e-3) -> NDArray[np.bool_]:
    """Points (N, 3) within ``eps`` of a box's surface or of the floor (z = 0): a depth
    map's points at silhouettes lie in the air and are left out of the counts."""
    on = np.abs(P[:, 2]) < eps
    for lo, hi in boxes:
        a, b = np.array(lo), np.array(hi)
        lo_in, hi_in = a + eps, b - eps
        lo_out, hi_out = a - eps, b + eps
        outer = np.all((lo_out < P) & (hi_out > P), axis=1)
        inner = np.all((lo_in < P) & (hi_in > P), axis=1)
        on |= outer & ~inner
    return on


def hidden_at_t1(C1: F64, P: F64, boxes: list[Box]) -> NDArray[np.bool_]:
    """Whether the segment from the camera centre ``C1`` to each point ``P`` (N, 3) passes
    through one of ``boxes`` (shrunk by 2 mm: a point on a face is not hidden by it)."""
    d = P - C1
    t = np.full(P.shape[0], np.inf)
    for box in boxes:
        t = np.minimum(t, _box_entry(C1, d, box, shrink=2e-3))
    return t < 1.0


def first_hit_depth(run: FlowRun, T_wc: F64, pix: F64, boxes: list[Box]) -> F64:
    """z-depth (optical axis) of the first surface (boxes or the floor z = 0) on the rays of
    pixels ``pix`` (N, 2) of the camera at pose ``T_wc``: ray casting, no depth map."""
    import cv2

    if pix.shape[0] == 0:
        return np.zeros(0)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)
    xy = cv2.undistortPoints(
        pix.reshape(-1, 1, 2).astype(np.float64), run.K, _cv_dist(run), None, None, None, crit
    )
    rays = np.concatenate([xy.reshape(-1, 2), np.ones((pix.shape[0], 1))], axis=1)
    d = rays @ T_wc[:3, :3].T  # (z = 1 in the camera: t is the z-depth)
    C = T_wc[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        t_floor = np.where(d[:, 2] < 0, -C[2] / d[:, 2], np.inf)
    t = t_floor
    for box in boxes:
        t = np.minimum(t, _box_entry(C, d, box))
    return t
