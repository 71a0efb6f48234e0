"""One HDL-32E turn in the richest built-in scene, end to end, against bare Embree.

Run by hand:  .venv/bin/python benchmarks/bench_lidar.py [--scene warehouse] [--repeat 30]

Prints, as medians over ``--repeat`` turns along the default landing trajectory flown
into the scene's goal:
  - the whole turn: firing poses + ray cast + sensor model + XYZIRT packing +
    PointCloud2 message + CDR serialization;
  - its parts;
  - bare Embree on the very same rays (embreex ``run`` only, same thread count, no
    pre/post-processing) and the turn's throughput as a fraction of it;
  - bare Embree on one thread (how much the thread pool buys).
"""

from __future__ import annotations

import argparse
import itertools
import os
import time
from concurrent.futures import ThreadPoolExecutor
from functools import partial
from typing import Any

import numpy as np

from roslan.config.base import Pose, validate_model
from roslan.io.messages import Flavor, MessageStore
from roslan.render.raycast import get_raycaster
from roslan.scene import load_scene
from roslan.sensors.beams import Lidar, LidarConfig, measure, pointcloud2, rays_in_world
from roslan.trajectory import TauTrajectory, TrajectoryConfig


def _bare(emb: Any, o: np.ndarray, d: np.ndarray, tfar: float, q: slice) -> Any:
    return emb.run(o[q], d[q], dists=np.float32(tfar), output=1)


def _median_ms(samples: list[float]) -> float:
    return float(np.median(samples) * 1e3)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="warehouse")
    ap.add_argument("--repeat", type=int, default=30)
    args = ap.parse_args()

    t = time.perf_counter()
    scene = load_scene(args.scene)
    t_load = time.perf_counter() - t
    t = time.perf_counter()
    caster = get_raycaster(scene)
    t_bvh = time.perf_counter() - t
    goal = Pose(position=scene.goal_position, rpy=scene.goal_rpy)
    traj = TauTrajectory(TrajectoryConfig(goal=goal), warn=False)
    lid = Lidar(validate_model(LidarConfig, {"type": "lidar", "name": "velodyne"}))
    s = lid.spec
    store = MessageStore(Flavor.ROS2)
    rng = np.random.default_rng(0)
    n_rays = s.azimuth_steps * s.n_lasers
    starts = np.linspace(0.0, traj.T - 0.1, args.repeat)

    emb = caster._embree
    n_chunks = max(caster.threads, -(-n_rays // 8192))
    bounds = np.linspace(0, n_rays, n_chunks + 1).astype(int)
    slices = [slice(int(a), int(b)) for a, b in itertools.pairwise(bounds)]
    pool = ThreadPoolExecutor(caster.threads)

    # Interleaved: each iteration times the whole turn, its parts, and bare Embree on the
    # very same rays, so CPU load from other processes hits all of them alike.
    whole, poses, meas, pack, bare, ratio, points = [], [], [], [], [], [], []
    o32 = d32 = np.zeros((0, 3), np.float32)
    for t0 in starts:
        t0_ns = round(t0 * 1e9)
        a = time.perf_counter()
        pts = lid.scan(traj, caster, t0_ns, rng)
        msg = pointcloud2(store, t0_ns, "velodyne", pts)
        raw = store.serialize(msg, "sensor_msgs/msg/PointCloud2")
        whole.append(time.perf_counter() - a)
        points.append(pts.shape[0])
        assert len(raw) > 22 * pts.shape[0]
        a = time.perf_counter()
        tk = t0 + np.arange(s.azimuth_steps) * s.column_period
        o, d = rays_in_world(traj, lid.T_body_sensor, tk, lid.frac, lid.directions)
        o32 = np.ascontiguousarray(o.reshape(-1, 3), dtype=np.float32)
        d32 = np.ascontiguousarray(d.reshape(-1, 3), dtype=np.float32)
        b = time.perf_counter()
        measure(caster, o32, d32, min_range=s.min_range, max_range=s.max_range,
                noise_sigma=s.noise_sigma, dropout=0.0, rng=rng, intensity_scale=255.0)  # fmt: skip
        c = time.perf_counter()
        store.serialize(pointcloud2(store, t0_ns, "velodyne", pts), "sensor_msgs/msg/PointCloud2")
        e = time.perf_counter()
        list(pool.map(partial(_bare, emb, o32, d32, float(s.max_range)), slices))
        f = time.perf_counter()
        poses.append(b - a)
        meas.append(c - b)
        pack.append(e - c)
        bare.append(f - e)
        ratio.append((f - e) / whole[-1])
    pool.shutdown()
    bare1 = []
    for _ in range(max(3, args.repeat // 5)):
        a = time.perf_counter()
        emb.run(o32, d32, dists=np.float32(s.max_range), output=1)
        bare1.append(time.perf_counter() - a)

    w = _median_ms(whole)
    eb = _median_ms(bare)
    print(f"scene {args.scene}: {scene.n_triangles} triangles "
          f"(load {t_load:.2f} s, BVH {t_bvh * 1e3:.0f} ms)")  # fmt: skip
    print(f"HDL-32E turn at {s.rate:g} Hz: {n_rays} rays, median "
          f"{int(np.median(points))} returns, {caster.threads} threads")  # fmt: skip
    print(f"  whole turn (poses+cast+model+packing): {w:.2f} ms median, "
          f"{min(whole) * 1e3:.2f} ms best -> {n_rays / w / 1e3:.2f} M rays/s")  # fmt: skip
    print(f"  firing poses {_median_ms(poses):.2f} ms | cast + sensor model "
          f"{_median_ms(meas):.2f} ms | PointCloud2 message + serialize "
          f"{_median_ms(pack):.2f} ms")  # fmt: skip
    print(f"  bare Embree, same rays, {caster.threads} threads: {eb:.2f} ms median, "
          f"{min(bare) * 1e3:.2f} ms best -> {n_rays / (eb * 1e-3) / 1e6:.2f} M rays/s; "
          f"1 thread: {_median_ms(bare1):.2f} ms")  # fmt: skip
    print(f"  turn throughput / bare Embree throughput = {eb / w:.2f} (ratio of medians), "
          f"{float(np.median(ratio)):.2f} (median of per-turn ratios), "
          f"{min(bare) / min(whole):.2f} (best to best)")  # fmt: skip
    print(f"  load average during the run: {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")


if __name__ == "__main__":
    main()
