"""Cost of the frame camera's shutter: exposure, rolling-shutter readout, auto-exposure.

The default job's frame camera (640x480 mono8, plumb_bob lens) over the default
landing's trajectory, one frame every ``1 / STEP`` s, rendered through the sensor's own
code (``Camera.frame_linear``: shutter plan, poses, renders, every row's own exposure
window, encoding), for several shutter
settings; the settings alternate within each round (the machine is shared). Prints per
setting the process CPU time and the best wall time per frame, the renders and the
rendered pixels per frame (relative to one full render), and the metering pass's cost
per frame when auto-exposure is on.

    PYTHONPATH=src python3 benchmarks/bench_shutter.py [ROUNDS]
"""

from __future__ import annotations

import sys
import time
from typing import Any

import numpy as np

from roslan.cli.simulate import load_config
from roslan.render.gl import get_renderer
from roslan.scene import load_scene
from roslan.sensors.cameras import Camera, CameraConfig
from roslan.sensors.cameras.row_exposure import RowShot, output_rays, plan_row_frame
from roslan.trajectory import TauTrajectory
from roslan.vehicle import base_link_trajectory
from shutter_setup import BenchCtx, body_poses

STEP = 10.0  # frames per trajectory second

SETTINGS: dict[str, dict[str, Any]] = {
    "global, no exposure (main's default)": {
        "exposure_time": 0.0,
        "readout_time": 0.0,
        "auto_exposure": None,
    },
    "global, 5 ms, 8 samples": {
        "exposure_time": 0.005,
        "readout_time": 0.0,
        "exposure_samples": 8,
        "auto_exposure": None,
    },
    "rolling 10 ms, no exposure, 4 samples": {
        "exposure_time": 0.0,
        "readout_time": 0.01,
        "exposure_samples": 4,
        "auto_exposure": None,
    },
    "default job's camera": {},
    "rolling 10 ms + 5 ms, 8 samples": {
        "exposure_time": 0.005,
        "readout_time": 0.01,
        "exposure_samples": 8,
        "auto_exposure": None,
    },
}


def main() -> None:
    rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    cfg, _ = load_config(None)
    cam_cfg = next(s for s in cfg.sensors if s.type == "camera")
    traj = TauTrajectory(base_link_trajectory(cfg.trajectory, cfg.vehicle), warn=False)
    ctx = BenchCtx(get_renderer(load_scene("warehouse")), traj)
    stamps = np.arange(0.05, traj.T - 0.05, 1.0 / STEP)
    stamps_ns = np.round(stamps * 1e9).astype(np.int64)
    cams: dict[str, Camera] = {}
    for name, keys in SETTINGS.items():
        data = cam_cfg.model_dump(mode="python") | keys
        cam = Camera(CameraConfig.model_validate(data))
        cam._plans(ctx)  # type: ignore[arg-type]
        cams[name] = cam
    cpu: dict[str, list[float]] = {n: [] for n in cams}
    wall: dict[str, list[float]] = {n: [] for n in cams}
    meter: dict[str, list[float]] = {n: [] for n in cams}
    rng = np.random.default_rng(0)
    for _ in range(rounds):
        for name, cam in cams.items():
            c0, w0 = time.process_time(), time.perf_counter()
            ex = cam.exposures(ctx, stamps_ns)  # type: ignore[arg-type]
            meter[name].append((time.process_time() - c0) / len(stamps))
            e = cam._eyes[0]
            c0, w0 = time.process_time(), time.perf_counter()
            for t, x in zip(stamps_ns.tolist(), ex.tolist(), strict=True):
                lin = cam.frame_linear(ctx, ctx.renderer(), e, t, x)  # type: ignore[arg-type]
                cam.finish_image(lin, rng, x)
            cpu[name].append((time.process_time() - c0) / len(stamps))
            wall[name].append((time.perf_counter() - w0) / len(stamps))
    base = float(np.mean(cpu[next(iter(cams))]))
    print(f"{len(stamps)} frames x {rounds} rounds; CPU per frame (all threads), best wall")
    for name, cam in cams.items():
        c = cam.config
        e = cam._eyes[0]
        t_mid = int(stamps_ns[len(stamps_ns) // 2])
        assert e.plan is not None
        if c.exposure_time <= 0 and c.readout_time <= 0:
            n, px = 1, 1.0
        else:
            T_bo = cam._T_body_sensor @ e.T_sensor_optical
            shot = RowShot(
                e.plan,
                output_rays(e.plan, e.model.width, e.model.height),
                lambda t, T_bo=T_bo: body_poses(traj, t) @ T_bo,
                t_mid,
                c.exposure_time,
                c.readout_time,
                c.exposure_samples,
            )
            rf, _ = plan_row_frame(shot)
            n = len(rf.bands)
            px = float(sum(b - a for _, a, b in rf.bands)) / e.plan.height
        m = float(np.mean(meter[name])) * 1e3
        print(
            f"  {name:40s} {np.mean(cpu[name]) * 1e3:6.1f} ms CPU "
            f"({np.mean(cpu[name]) / base:4.2f}x), best {min(wall[name]) * 1e3:6.1f} ms wall; "
            f"{n} renders, ~{px:.2f} full frames of rows"
            + (f"; metering {m:.1f} ms/frame" if c.auto_exposure is not None else "")
        )


if __name__ == "__main__":
    main()
