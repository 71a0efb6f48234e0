"""Event camera throughput: DAVIS346 on the warehouse landing.

Prints, measured in one run:
  * rendered frames/s (346x260 luminance + depth, the sensor's own render path);
  * event generation in events/s, realistic (the DAVIS346 default) and clean presets, on
    every rendered frame (float32, as rendered; and as float64, whose log/exp run in
    float64), every 8th frame (more change per step) and synthetic dense frames (~4
    crossings per pixel): numba kernels vs the NumPy reference, best of N wall and CPU;
  * serialization in events/s: EventArray packing for ROS 1 and ROS 2 (1 ms packets),
    events.txt formatting (numba vs NumPy), events.txt / events.h5 writers;
  * events per second of trajectory and frames per second of trajectory.

Usage: .venv/bin/python benchmarks/bench_events.py [--seconds 0.4] [--start 0.0] [--scene warehouse]
       [--repeat 3] [--max-rate 2000] (the demo job caps the sampling at 200 Hz)
Rendering dominates on a CPU machine: it covers a slice of the landing.
"""

from __future__ import annotations

import argparse
import itertools
import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Literal

import numpy as np

from roslan.events import EventBatch, EventGenerator
from roslan.events.files import (
    EventH5Writer,
    EventTextWriter,
    _format_events_txt_numpy,
    format_events_txt,
)
from roslan.events.reference import NumpyEventGenerator
from roslan.events.ros import pack_event_array
from roslan.events.sampling import AdaptiveSampler
from roslan.io.messages import Flavor
from roslan.pipeline.context import Context
from roslan.scene import load_scene
from roslan.sensors.cameras import EventCamera, EventCameraConfig
from roslan.trajectory import TauTrajectory, TrajectoryConfig


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="warehouse")
    ap.add_argument(
        "--start", type=float, default=0.0, help="trajectory time of the slice start, s"
    )
    ap.add_argument("--seconds", type=float, default=0.4, help="trajectory seconds rendered")
    ap.add_argument("--max-rate", type=float, default=2000.0)
    ap.add_argument("--repeat", type=int, default=3, help="best of N")
    args = ap.parse_args()
    load0 = os.getloadavg()[0]

    scene = load_scene(args.scene)
    traj = TauTrajectory(
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

        W, H = cam.camera.width, cam.camera.height
        presets = {
            "realistic": cfg.model_params(),
            "clean": cfg.model_copy(update={"preset": "clean"}).model_params(),
        }
        rng = np.random.default_rng(1)
        base = rng.uniform(0.05, 0.9, (H, W)).astype(np.float32)
        # ~4 crossings per pixel and frame: the event-dense extreme
        dense = [(i * 1_000_000, base * np.float32(2.5 if i % 2 else 1.0)) for i in range(21)]
        # float64 frames take log/exp in float64 (the arithmetic before float32 frames did)
        real64 = [(tt, lum.astype(np.float64)) for tt, lum in frames]
        workloads = {"real": frames, "real64": real64, "real/8": frames[::8], "dense": dense}
        gen_rows = []
        for pname, params in presets.items():
            for wname, wl in workloads.items():
                res = {}
                outs: list[EventBatch] = []
                for impl, cls in (("numpy", NumpyEventGenerator), ("numba", EventGenerator)):

                    def run(cls=cls, wl=wl, params=params) -> tuple[int, float, float]:
                        # timed: the updates after the first frame (not the generator's
                        # construction, ~3.5 ms of per-pixel draws, nor its first frame)
                        g = cls(W, H, params, np.random.default_rng(0))
                        g.update(wl[0][1], wl[0][0])
                        w, c = time.perf_counter(), time.process_time()
                        n = sum(g.update(lum, tt).size for tt, lum in wl[1:])
                        return n, time.perf_counter() - w, time.process_time() - c

                    runs = [run() for _ in range(args.repeat)]
                    res[impl] = (runs[0][0], min(r[1] for r in runs), min(r[2] for r in runs))
                    g = cls(W, H, params, np.random.default_rng(0))
                    outs.append(EventBatch.concatenate([g.update(lum, tt) for tt, lum in wl]))
                # the kernels are bit-identical to the NumPy reference
                assert all(np.array_equal(u, v) for u, v in zip(*outs, strict=True))
                gen_rows.append((pname, wname, len(wl) - 1, res))
        gen = EventGenerator(W, H, presets["realistic"], np.random.default_rng(0))
        batches = [gen.update(lum, tt) for tt, lum in frames]
        ev = EventBatch.concatenate(batches)
        n_ev = ev.size

        # serialization: 1 ms packets, both flavours
        start = 1_700_000_000_000_000_000
        j = ev.t // 1_000_000
        cuts = [0, *(np.flatnonzero(np.diff(j)) + 1).tolist(), n_ev]
        ser: dict[str, tuple[float, float]] = {}
        for flavor in Flavor:

            def pack(flavor: Flavor = flavor) -> int:
                for i0, i1 in itertools.pairwise(cuts):
                    pack_event_array(
                        flavor,
                        start + int(ev.t[i1 - 1]),
                        "dvs_optical",
                        260,
                        346,
                        ev.t[i0:i1] + start,
                        ev.x[i0:i1],
                        ev.y[i0:i1],
                        ev.p[i0:i1],
                    )
                return n_ev  # fmt: skip

            ser[f"pack {flavor.value}"] = best_of(pack, args.repeat)[1:]
        txt = format_events_txt(ev.t, ev.x, ev.y, ev.p)
        assert txt == _format_events_txt_numpy(ev.t, ev.x, ev.y, ev.p)
        for name, fmt in (("txt format numpy", _format_events_txt_numpy),
                          ("txt format numba", format_events_txt)):  # fmt: skip
            ser[name] = best_of(lambda fmt=fmt: len(fmt(ev.t, ev.x, ev.y, ev.p)), args.repeat)[1:]

        def write_files(txt: bool, h5: Literal["gzip", "lzf"] | None) -> int:
            ws: list[EventTextWriter | EventH5Writer] = []
            if txt:
                ws.append(EventTextWriter(Path(tmp) / "bench.txt"))
            if h5:
                ws.append(EventH5Writer(Path(tmp) / "bench.h5", W, H, compression=h5))
            for b in batches:  # one batch per rendered frame, as the sensor streams them
                for w in ws:
                    w.write(b)
            for w in ws:
                w.close()
            return n_ev

        files: dict[str, tuple[bool, Literal["gzip", "lzf"] | None]] = {
            "events.txt": (True, None),
            "events.h5 gzip": (False, "gzip"),
            "events.h5 lzf": (False, "lzf"),
            "txt + h5 gzip": (True, "gzip"),
        }
        for name, flags in files.items():
            ser[name] = best_of(lambda flags=flags: write_files(*flags), args.repeat)[1:]

    load = os.getloadavg()[0]
    print(
        f"scene {args.scene}, DAVIS346 346x260, realistic preset, "
        f"slice {args.start:.2f}+{span:.3f} s of {traj.duration:.2f} s"
    )
    print(f"rendered frames:      {n_frames} ({n_frames / span:.0f} per trajectory second)")
    ms = r_time / n_frames * 1e3
    print(f"render (lum+depth+flow): {n_frames / r_time:8.1f} frames/s  ({ms:.2f} ms/frame)")
    print(f"events:               {n_ev} ({n_ev / span / 1e6:.2f} M per trajectory second)")
    print(
        f"sampling cap {args.max_rate:g} Hz; load average (1 min) {load0:.2f} at the start, "
        f"{load:.2f} at the end; best of {args.repeat}, wall and CPU"
    )
    print("event generation (M events/s wall | CPU; ms per frame wall):")
    for pname, wname, nf, res in gen_rows:
        n, w0, c0 = res["numpy"]
        _, w1, c1 = res["numba"]
        print(
            f"  {pname:9s} {wname:6s} {n / nf:7.0f} ev/frame  numpy {n / w0 / 1e6:6.2f} | "
            f"{n / c0 / 1e6:6.2f} ({w0 / nf * 1e3:5.2f} ms)  numba {n / w1 / 1e6:6.2f} | "
            f"{n / c1 / 1e6:6.2f} ({w1 / nf * 1e3:5.3f} ms)  x{w0 / w1:5.1f}"
        )
    print("serialization (M events/s wall | CPU):")
    for k, (w, c) in ser.items():
        print(f"  {k:18s} {n_ev / w / 1e6:8.2f} | {n_ev / c / 1e6:8.2f}")
    print(f"events.txt bytes/event: {len(txt) / max(n_ev, 1):.1f}")


def best_of(fn: Callable[[], int], repeat: int) -> tuple[int, float, float]:
    """``(result, best wall s, best process CPU s)`` of ``repeat`` calls."""
    walls, cpus, out = [], [], 0
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        out = fn()
        walls.append(time.perf_counter() - w)
        cpus.append(time.process_time() - c)
    return out, min(walls), min(cpus)


if __name__ == "__main__":
    main()
