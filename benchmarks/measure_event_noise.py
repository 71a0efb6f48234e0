"""Effects of the leak's initial phase and of the refractory period on a rendered clip.

Renders the DAVIS346 on the warehouse landing (the sensor's own render path, adaptive
sampling) and runs the realistic preset over the frames with:
  * leak_phase steady / zero / no leak: ON and OFF counts and ON/OFF ratio;
  * refractory periods 0 .. 2 ms: the fraction of level crossings dropped.

Usage: .venv/bin/python benchmarks/measure_event_noise.py [--seconds 1.5] [--start 0.0]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from roslan.events import EventGenerator
from roslan.events.sampling import AdaptiveSampler
from roslan.pipeline.context import Context
from roslan.scene import load_scene
from roslan.sensors.cameras import EventCamera, EventCameraConfig
from roslan.trajectory import TauTrajectory, TrajectoryConfig


def render_clip(scene_name: str, start: float, seconds: float) -> tuple[EventCameraConfig, list]:
    scene = load_scene(scene_name)
    traj = TauTrajectory(
        TrajectoryConfig(goal={"position": scene.goal_position, "rpy": scene.goal_rpy}), warn=False
    )
    cfg = EventCameraConfig.model_validate(
        {"type": "event_camera", "name": "dvs", "rate": 25, "topic": "/dvs",
         "sensor": "davis346", "pose": {"rpy": (0.0, 0.5, 0.0)}}
    )  # fmt: skip
    frames = []
    with tempfile.TemporaryDirectory() as tmp:
        ctx = Context(traj, Path(tmp), seed=0, sensors=[cfg], scene=scene)
        cam = EventCamera(cfg)
        t0 = round(start * 1e9)
        t_end = min(traj.duration_ns, t0 + round(seconds * 1e9))
        sampler = AdaptiveSampler(
            "optical_flow", cfg.adaptive_lambda, cfg.min_rate, cfg.max_rate, t_end
        )
        t: int | None = t0
        while t is not None:
            lum, depth, v, w = cam.render(ctx, t, need_depth=True)
            flow = cam.camera.flow(depth, v, w)
            frames.append((t, lum))
            t = sampler.next_ns(t, float(np.max(np.hypot(flow[..., 0], flow[..., 1]))))
    return cfg, frames


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="warehouse")
    ap.add_argument("--start", type=float, default=0.0)
    ap.add_argument("--seconds", type=float, default=1.5)
    args = ap.parse_args()
    cfg, frames = render_clip(args.scene, args.start, args.seconds)
    H, W = frames[0][1].shape
    base = cfg.model_params()
    print(f"{len(frames)} frames, {args.seconds} s from t = {args.start} s, {W}x{H}; {base}")

    def run(**over: object) -> tuple[int, int, int]:
        g = EventGenerator(W, H, base.with_overrides(**over), np.random.default_rng(0))  # type: ignore[arg-type]
        on = off = 0
        for tt, lum in frames:
            b = g.update(lum, tt)
            on += int(np.count_nonzero(b.p == 1))
            off += int(b.size) - int(np.count_nonzero(b.p == 1))
        return on, off, g.n_dropped

    print("leak phase (realistic otherwise)   ON      OFF   ON/OFF")
    for name, over in (
        ("no leak", {"leak_rate": 0.0}),
        ("steady", {"leak_phase": "steady"}),
        ("zero", {"leak_phase": "zero"}),
        ("no leak, no shot noise", {"leak_rate": 0.0, "shot_noise_rate": 0.0}),
    ):
        on, off, _ = run(**over)
        print(f"{name:32s} {on:8d} {off:8d} {on / max(off, 1):7.3f}")
    print("refractory (no noise)   emitted  dropped  dropped/crossings")
    for r in (0.0, 1e-4, 2e-4, 5e-4, 1e-3, 2e-3):
        on, off, d = run(refractory=r, leak_rate=0.0, shot_noise_rate=0.0)
        print(f"{r * 1e3:6.1f} ms {on + off:16d} {d:8d} {d / max(on + off + d, 1):10.3%}")


if __name__ == "__main__":
    main()
