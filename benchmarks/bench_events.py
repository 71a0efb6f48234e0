"""Event camera throughput: DAVIS346 on the warehouse landing.

Prints, measured in one run:
  * rendered frames/s (346x260 luminance + depth, the sensor's own render path);
  * event generation (ESIM pixel model, realistic preset) in events/s;
  * serialization in events/s: EventArray packing for ROS 1 and ROS 2 (1 ms packets),
    events.txt formatting, events.h5 appending;
  * events per second of trajectory and frames per second of trajectory.

Usage: .venv/bin/python benchmarks/bench_events.py [--seconds 0.4] [--start 0.0] [--scene warehouse]
Rendering dominates on a CPU machine: it covers a slice of the landing.
"""

from __future__ import annotations

import argparse
import itertools
import tempfile
import time
from pathlib import Path

import numpy as np

from roslan.events import EventBatch, EventGenerator
from roslan.events.files import EventH5Writer, format_events_txt
from roslan.events.ros import pack_event_array
from roslan.events.sampling import AdaptiveSampler
from roslan.io.messages import Flavor
from roslan.pipeline.context import Context
from roslan.scene import load_scene
from roslan.sensors.event_camera import EventCamera, EventCameraConfig
from roslan.trajectory import Trajectory, TrajectoryConfig


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="warehouse")
    ap.add_argument(
        "--start", type=float, default=0.0, help="trajectory time of the slice start, s"
    )
    ap.add_argument("--seconds", type=float, default=0.4, help="trajectory seconds rendered")
    ap.add_argument("--max-rate", type=float, default=2000.0)
    args = ap.parse_args()

    scene = load_scene(args.scene)
    traj = Trajectory(
        TrajectoryConfig(goal={"position": scene.goal_position, "rpy": scene.goal_rpy}), warn=False
    )
    cfg = EventCameraConfig.model_validate(
        {
            "type": "event_camera",
            "name": "dvs",
            "rate": 25,
            "topic": "/dvs",
            "sensor": "davis346",
            "pose": {"rpy": (0.0, 0.5, 0.0)},
            "max_rate": args.max_rate,
        }
    )
    with tempfile.TemporaryDirectory() as tmp:
        ctx = Context(traj, Path(tmp), seed=0, sensors=[cfg], scene=scene)
        cam = EventCamera(cfg)
        t0 = round(args.start * 1e9)
        t_end = min(traj.duration_ns, t0 + round(args.seconds * 1e9))
        sampler = AdaptiveSampler(
            "optical_flow", cfg.adaptive_lambda, cfg.min_rate, cfg.max_rate, t_end
        )
        cam.render(ctx, t0, need_depth=True)  # warm-up: context, shaders, scene upload
        frames: list[tuple[int, np.ndarray]] = []
        t: int | None = t0
        r_time = 0.0
        while t is not None:
            a = time.perf_counter()
            lum, depth, v, w = cam.render(ctx, t, need_depth=True)
            flow = cam.camera.flow(depth, v, w)
            r_time += time.perf_counter() - a
            frames.append((t, lum))
            t = sampler.next_ns(t, float(np.max(np.hypot(flow[..., 0], flow[..., 1]))))
        n_frames = len(frames)
        span = (t_end - t0) * 1e-9

        gen = EventGenerator(
            cam.camera.width, cam.camera.height, cfg.model_params(), np.random.default_rng(0)
        )
        a = time.perf_counter()
        batches = [gen.update(lum, tt) for tt, lum in frames]
        g_time = time.perf_counter() - a
        ev = EventBatch.concatenate(batches)
        n_ev = ev.size
        # event-dense input: every 8th frame (more change per step), and a synthetic
        # pair of frames with ~4 crossings per pixel (the capacity of the expansion)
        gen8 = EventGenerator(
            cam.camera.width, cam.camera.height, cfg.model_params(), np.random.default_rng(0)
        )
        a = time.perf_counter()
        n8 = sum(gen8.update(lum, tt).size for tt, lum in frames[::8])
        g8_time = time.perf_counter() - a
        rng = np.random.default_rng(1)
        gens = EventGenerator(cam.camera.width, cam.camera.height, cfg.model_params(), rng)
        base = rng.uniform(0.05, 0.9, (cam.camera.height, cam.camera.width)).astype(np.float32)
        gens.update(base, 0)
        a = time.perf_counter()
        ns = sum(
            gens.update(base * (2.5 if i % 2 else 1.0), i * 1_000_000).size for i in range(1, 21)
        )
        gs_time = time.perf_counter() - a

        # serialization: 1 ms packets, both flavours
        start = 1_700_000_000_000_000_000
        j = ev.t // 1_000_000
        cuts = [0, *(np.flatnonzero(np.diff(j)) + 1).tolist(), n_ev]
        times = {}
        for flavor in Flavor:
            a = time.perf_counter()
            total = 0
            for i0, i1 in itertools.pairwise(cuts):
                total += len(
                    pack_event_array(flavor, start + int(ev.t[i1 - 1]), "dvs_optical", 260, 346,
                                     ev.t[i0:i1] + start, ev.x[i0:i1], ev.y[i0:i1], ev.p[i0:i1])
                )  # fmt: skip
            times[flavor.value] = time.perf_counter() - a
        a = time.perf_counter()
        txt = format_events_txt(ev.t, ev.x, ev.y, ev.p)
        times["txt"] = time.perf_counter() - a
        a = time.perf_counter()
        h5 = EventH5Writer(Path(tmp) / "bench.h5", 346, 260)
        for b in batches:
            h5.write(b)
        h5.close()
        times["h5"] = time.perf_counter() - a

    print(
        f"scene {args.scene}, DAVIS346 346x260, realistic preset, "
        f"slice {args.start:.2f}+{span:.3f} s of {traj.duration:.2f} s"
    )
    print(f"rendered frames:      {n_frames} ({n_frames / span:.0f} per trajectory second)")
    ms = r_time / n_frames * 1e3
    print(f"render (lum+depth+flow): {n_frames / r_time:8.1f} frames/s  ({ms:.2f} ms/frame)")
    print(f"events:               {n_ev} ({n_ev / span / 1e6:.2f} M per trajectory second)")
    ms = g_time / n_frames * 1e3
    print(f"event generation:     {n_ev / g_time / 1e6:8.2f} M events/s  ({ms:.2f} ms/frame)")
    print(
        f"  every 8th frame:    {n8 / g8_time / 1e6:8.2f} M events/s  "
        f"({n8 / max(len(frames[::8]), 1):.0f} events/frame)"
    )
    print(
        f"  synthetic dense:    {ns / gs_time / 1e6:8.2f} M events/s  ({ns / 20:.0f} events/frame)"
    )
    for k, v in times.items():
        print(f"serialize {k:5s}:      {n_ev / v / 1e6:8.2f} M events/s")
    print(f"events.txt bytes/event: {len(txt) / max(n_ev, 1):.1f}")


if __name__ == "__main__":
    main()
