"""Offline check of the event-based time to contact on a ``roslan simulate`` OUTDIR.

Runs :class:`roslan.events.DivergenceEstimator` over the OUTDIR's ``events.h5`` and
``imu.txt`` in 20 ms steps (the closed loop's default control period), with the ground's
normal from the ground-truth attitude (the closed-loop policy takes it from its own IMU
integration), and compares each estimate with the true time to contact of the camera with
the ground (camera height above the goal over its vertical speed, from
``groundtruth.txt``) and of the height gap. Prints the median relative errors over the
last 70 % of the descent and the CPU per step.

    roslan simulate landing.yaml -o out      # a downward event camera (`dvs`) and an IMU
    python benchmarks/eval_tau_events.py out

The camera must be the OUTDIR's first event camera, named ``dvs``, with an IMU named ``imu``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import h5py
import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from roslan.events.divergence import DivergenceEstimator

STEP = 0.02
R_LINK_OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def evaluate(out: Path) -> dict[str, float]:
    ext = yaml.safe_load((out / "calib" / "extrinsics.yaml").read_text())
    tf = {s: np.array(v["T_base_link_sensor"]) for s, v in ext["sensors"].items()}
    R_body_opt = tf["dvs"][:3, :3] @ R_LINK_OPTICAL
    fx, fy, cx, cy = np.loadtxt(out / "calib.txt")[:4]
    with h5py.File(out / "events.h5") as f:
        ex, ey = f["events/x"][:], f["events/y"][:]
        et = f["events/t"][:].astype(np.int64) * 1000
    imu = np.loadtxt(out / "imu.txt")
    it = np.round(imu[:, 0] * 1e9).astype(np.int64)
    gt = np.loadtxt(out / "groundtruth.txt")
    goal_z = json.loads((out / "run.json").read_text())["config"]["trajectory"]["goal"]["position"][
        2
    ]
    cal = yaml.safe_load((out / "calib" / "dvs.yaml").read_text())
    est = DivergenceEstimator(
        cal["image_width"], cal["image_height"], fx, fy, cx, cy,
        R_cam_imu=R_body_opt.T @ tf["imu"][:3, :3],
    )  # fmt: skip
    tg = gt[:, 0]
    R = Rotation.from_quat(gt[:, 4:8]).as_matrix()
    cam_z = gt[:, 3] + (R @ tf["dvs"][:3, 3])[:, 2]
    vz, vzc = np.gradient(gt[:, 3], tg), np.gradient(cam_z, tg)
    with np.errstate(divide="ignore", invalid="ignore"):
        tau_cam = (cam_z - goal_z) / vzc
        tau_gap = (gt[:, 3] - gt[-1, 3]) / vz
    moving = np.flatnonzero(vz < -0.05)
    t_td = float(tg[moving[-1]])
    rows = []
    cpu = time.process_time()
    n = int(np.ceil(et[-1] * 1e-9 / STEP))
    for k in range(1, n + 1):
        a, b = round((k - 1) * STEP * 1e9), round(k * STEP * 1e9)
        i0, i1 = np.searchsorted(et, [a, b])
        j0, j1 = np.searchsorted(it, [a, b])
        g = min(int(np.searchsorted(tg, b * 1e-9)), len(tg) - 1)
        normal = (R[g] @ R_body_opt).T @ np.array([0.0, 0.0, -1.0])
        e = est.update(
            ex[i0:i1], ey[i0:i1], et[i0:i1],
            gyro_t_ns=it[j0:j1], gyro=imu[j0:j1, 4:7], end_ns=b, normal=normal,
        )  # fmt: skip
        if e is not None:
            t = e.t_ns * 1e-9
            rows.append((t, e.tau, np.interp(t, tg, tau_cam), np.interp(t, tg, tau_gap)))
    cpu = time.process_time() - cpu
    r = np.array(rows)
    last = (r[:, 0] >= 0.3 * t_td) & (r[:, 0] < t_td - STEP)
    return {
        "steps": n,
        "cpu_ms_per_step": 1e3 * cpu / n,
        "median_error_camera_tau": float(np.median(np.abs(r[last, 1] / r[last, 2] - 1))),
        "p90_error_camera_tau": float(np.percentile(np.abs(r[last, 1] / r[last, 2] - 1), 90)),
        "median_error_gap_tau_uncorrected": float(np.median(np.abs(r[last, 1] / r[last, 3] - 1))),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir", type=Path)
    args = ap.parse_args()
    for k, v in evaluate(args.outdir).items():
        print(f"{k}: {v:.4g}")


if __name__ == "__main__":
    main()
