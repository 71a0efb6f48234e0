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
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from roslan.config.base import Pose, validate_model
from roslan.io.messages import Flavor, MessageStore
from roslan.render.raycast import get_raycaster
from roslan.scene import load_scene
from roslan.sensors.beams import measure, pointcloud2, rays_in_world
from roslan.sensors.lidar import Lidar, LidarConfig
from roslan.trajectory import Trajectory, TrajectoryConfig


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
    traj = Trajectory(TrajectoryConfig(goal=goal), warn=False)
    lid = Lidar(validate_model(LidarConfig, {"type": "lidar", "name": "velodyne"}))
    s = lid.spec
    store = MessageStore(Flavor.ROS2)
    rng = np.random.default_rng(0)
    n_rays = s.azimuth_steps * s.n_lasers
    starts = np.linspace(0.0, traj.T - 0.1, args.repeat)

    whole, poses, cast, model, pack, points = [], [], [], [], [], []
    for t0 in starts:
        t0_ns = round(t0 * 1e9)
        a = time.perf_counter()
        pts = lid.scan(traj, caster, t0_ns, rng)
        msg = pointcloud2(store, t0_ns, "velodyne", pts)
        raw = store.serialize(msg, "sensor_msgs/msg/PointCloud2")
        whole.append(time.perf_counter() - a)
        points.append(pts.shape[0])
        assert len(raw) > 22 * pts.shape[0]
        # parts
        a = time.perf_counter()
        tk = t0 + np.arange(s.azimuth_steps) * s.column_period
        o, d = rays_in_world(traj, lid.T_body_sensor, tk, lid.frac, lid.directions)
        o, d = o.reshape(-1, 3), d.reshape(-1, 3)
        b = time.perf_counter()
        caster.cast(o, d, s.max_range)
        c = time.perf_counter()
        measure(caster, o, d, min_range=s.min_range, max_range=s.max_range,
                noise_sigma=s.noise_sigma, dropout=0.0, rng=rng, intensity_scale=255.0)  # fmt: skip
        e = time.perf_counter()
        store.serialize(pointcloud2(store, t0_ns, "velodyne", pts), "sensor_msgs/msg/PointCloud2")
        f = time.perf_counter()
        poses.append(b - a)
        cast.append(c - b)
        model.append(e - c - (c - b))
        pack.append(f - e)

    # bare Embree on the same rays: embreex run() over the same chunks and threads
    tk = starts[len(starts) // 2] + np.arange(s.azimuth_steps) * s.column_period
    o, d = rays_in_world(traj, lid.T_body_sensor, tk, lid.frac, lid.directions)
    o32 = np.ascontiguousarray(o.reshape(-1, 3), dtype=np.float32)
    d32 = np.ascontiguousarray(d.reshape(-1, 3), dtype=np.float32)
    emb = caster._embree
    n_chunks = max(caster.threads, -(-n_rays // 8192))
    bounds = np.linspace(0, n_rays, n_chunks + 1).astype(int)
    slices = [slice(int(a), int(b)) for a, b in itertools.pairwise(bounds)]

    def run(sl: slice) -> object:
        return emb.run(o32[sl], d32[sl], dists=np.float32(s.max_range), output=1)

    bare, bare1 = [], []
    with ThreadPoolExecutor(caster.threads) as pool:
        for _ in range(args.repeat):
            a = time.perf_counter()
            list(pool.map(run, slices))
            bare.append(time.perf_counter() - a)
    for _ in range(max(3, args.repeat // 3)):
        a = time.perf_counter()
        emb.run(o32, d32, dists=np.float32(s.max_range), output=1)
        bare1.append(time.perf_counter() - a)

    w = _median_ms(whole)
    eb = _median_ms(bare)
    print(f"scene {args.scene}: {scene.n_triangles} triangles (load {t_load:.2f} s, BVH {t_bvh * 1e3:.0f} ms)")
    print(f"HDL-32E turn at {s.rate:g} Hz: {n_rays} rays, median {int(np.median(points))} returns, "
          f"{caster.threads} threads")  # fmt: skip
    print(f"  whole turn (poses+cast+model+pack+serialize): {w:.2f} ms median, "
          f"{_median_ms([min(whole)]):.2f} ms best -> {n_rays / (w * 1e-3) / 1e6:.2f} M rays/s")  # fmt: skip
    print(f"  firing poses {_median_ms(poses):.2f} ms | cast {_median_ms(cast):.2f} ms | "
          f"sensor model {_median_ms(model):.2f} ms | PointCloud2 pack+serialize {_median_ms(pack):.2f} ms")  # fmt: skip
    print(f"  bare Embree, same rays, {caster.threads} threads: {eb:.2f} ms -> "
          f"{n_rays / (eb * 1e-3) / 1e6:.2f} M rays/s; 1 thread: {_median_ms(bare1):.2f} ms")  # fmt: skip
    print(f"  turn throughput / bare Embree throughput = {eb / w:.2f}")


if __name__ == "__main__":
    main()
