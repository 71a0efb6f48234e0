"""Batch scaling (1 vs 2 local Dask workers) and the full paper dataset's wall time.

Run by hand::

    .venv/bin/python benchmarks/bench_batch.py              # scaling + full dataset
    .venv/bin/python benchmarks/bench_batch.py --no-dataset # scaling only
    .venv/bin/python benchmarks/bench_batch.py --dataset-duration 1.0  # shortened landings

Scaling: the same sweep of IMU + sonar landings in the empty scene (``--tasks`` tasks,
``--duration`` s of trajectory each) runs on a LocalCluster of 1 and of 2 workers;
efficiency = T1 / (2 * T2), both including cluster start-up (reported separately).
Dataset: ``roslan dataset`` (both scenes, full sensor suite) on 2 workers.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

from roslan.batch import parse_sweep, run_tasks, sweep_tasks
from roslan.batch.paper import build_dataset


def _sweep(n: int, duration: float) -> Any:
    # height 1 m, descent 1/(0.5*duration) m/s -> touchdown at `duration` s
    base = {
        "scene": "empty",
        "trajectory": {
            "k": 0.5,
            "initial": {"position": [-1.5, 0.5, 1.0], "descent_rate": 1.0 / (0.5 * duration)},
        },
        "sensors": [
            {"type": "imu", "name": "imu", "rate": 1000.0, "topic": "/imu"},
            {"type": "sonar", "name": "sonar", "rate": 20.0, "topic": "/sonar", "axis": [0, 0, -1]},
        ],
        "output": {"formats": ["ros1", "ros2"]},
    }
    return parse_sweep(
        {"base": base, "axes": [{"grid": {"seed": list(range(n))}}]}, base_dir=Path.cwd()
    )


def _cluster_startup(workers: int) -> float:
    import logging

    from distributed import Client, LocalCluster

    t0 = time.perf_counter()
    cluster = LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
        silence_logs=logging.CRITICAL,
    )
    client = Client(cluster)
    client.submit(lambda: __import__("roslan.pipeline") and 1).result()
    dt = time.perf_counter() - t0
    client.close()
    cluster.close()
    return dt


def scaling(n: int, duration: float, root: Path) -> dict[str, Any]:
    out: dict[str, Any] = {"tasks": n, "trajectory_s_each": duration}
    for workers in (1, 2):
        folder = root / f"w{workers}"
        t0 = time.perf_counter()
        report = run_tasks(
            sweep_tasks(_sweep(n, duration)), folder, workers=workers, progress=False
        )
        wall = time.perf_counter() - t0
        assert report.ok, [r.error for r in report.results if r.error]
        out[f"wall_s_{workers}w"] = wall
        out[f"task_s_sum_{workers}w"] = sum(r.wall_s or 0.0 for r in report.results)
        out[f"startup_s_{workers}w"] = _cluster_startup(workers)
        shutil.rmtree(folder)
    t1, t2 = out["wall_s_1w"], out["wall_s_2w"]
    out["speedup"] = t1 / t2
    out["efficiency"] = t1 / (2 * t2)
    s1 = t1 - out["startup_s_1w"]
    s2 = t2 - out["startup_s_2w"]
    out["efficiency_excluding_startup"] = s1 / (2 * s2)
    return out


def dataset(
    root: Path, duration: float | None, workers: int, sensors: list[dict[str, Any]] | None
) -> dict[str, Any]:
    t0 = time.perf_counter()
    runs, report = build_dataset(
        root / "dataset", workers=workers, duration=duration, sensors=sensors, progress=False
    )
    wall = time.perf_counter() - t0
    traj_s = sum(r.duration_s or 0.0 for r in report.results)
    size = sum(p.stat().st_size for p in (root / "dataset").rglob("*") if p.is_file())
    return {
        "simulations": len(runs),
        "complete": report.counts()["complete"],
        "failed": [f"{r.name}: {r.error}" for r in report.results if r.error],
        "workers": workers,
        "wall_s": wall,
        "trajectory_s_total": traj_s,
        "wall_per_trajectory_s": wall / traj_s if traj_s else None,
        "sim_wall_s_sum": sum(r.wall_s or 0.0 for r in report.results),
        "bytes": size,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--tasks", type=int, default=8)
    ap.add_argument("--duration", type=float, default=2.0, help="s of trajectory per sweep task")
    ap.add_argument("--no-dataset", action="store_true")
    ap.add_argument("--no-scaling", action="store_true")
    ap.add_argument("--dataset-duration", type=float, default=None)
    ap.add_argument("--workers", type=int, default=2, help="workers for the dataset run")
    ap.add_argument("--keep", metavar="DIR", help="write into DIR and keep it")
    ap.add_argument("--sensors", metavar="YAML", help="replace the dataset's sensor suite")
    args = ap.parse_args()
    root = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench_batch_"))
    root.mkdir(parents=True, exist_ok=True)
    result: dict[str, Any] = {
        "machine": f"{platform.machine()}, {os.cpu_count()} CPUs",
        "date": time.strftime("%Y-%m-%d"),
        "load_average_at_start": os.getloadavg(),
    }
    try:
        if not args.no_scaling:
            result["scaling"] = scaling(args.tasks, args.duration, root)
            print(json.dumps(result["scaling"], indent=2))
        if not args.no_dataset:
            import yaml

            sensors = yaml.safe_load(Path(args.sensors).read_text()) if args.sensors else None
            result["dataset"] = dataset(root, args.dataset_duration, args.workers, sensors)
            result["dataset"]["sensors"] = args.sensors or "paper suite"
            print(json.dumps(result["dataset"], indent=2))
        result["load_average_at_end"] = os.getloadavg()
        print(json.dumps(result, indent=2))
    finally:
        if not args.keep:
            shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
