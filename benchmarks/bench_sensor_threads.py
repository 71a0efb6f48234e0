"""Frame and scan post-processing on threads: one sensor of the default job alone,
``--workers 0``, with ``ROSLAN_SENSOR_THREADS`` = each of ``--threads``, alternated.

For each job (``camera``: the default job's 640x480 frame camera; ``lidar``: its
HDL-32E) and each thread count, a fresh subprocess runs the default landing with only
that sensor (plus the always-on ground truth) and prints the wall time, the CPU time
(whole process), the CPU time of the main thread (the merge and the sensor's own thread:
every render; with 1 thread also every frame's post-processing and the LiDAR's scans: the
sequential part, which bounds the wall time on an idle many-core machine and, unlike the
wall time, hardly depends on other load), the sensor's stream time (``--profile``'s
generator seconds: on its own thread, the render plus whatever waits for the pool) and
the streaming window; then the ratios against the first thread count, median over
``--repeat`` alternations.
Outputs are byte-identical for every thread count (tests/pipeline/test_sensor_threads.py).

    PYTHONPATH=src:benchmarks python3 benchmarks/bench_sensor_threads.py \\
        [--jobs camera lidar] [--threads 1 2] [--repeat 3] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path
from typing import Any

CHILD = textwrap.dedent(
    """
    import json, resource, sys, time
    from pathlib import Path
    from roslan.cli.simulate import load_config
    from roslan.pipeline import run_simulation

    kind, outdir = sys.argv[1], Path(sys.argv[2])
    cfg, _ = load_config(None)
    sensors = [s for s in cfg.sensors if s.type == kind]
    cfg = cfg.model_copy(update={"sensors": sensors})
    t0, c0, m0 = time.perf_counter(), time.process_time(), time.thread_time()
    run_simulation(cfg, outdir, quiet=True, profile=True, overview=False, workers=0)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    main_cpu = time.thread_time() - m0
    timing = json.loads((outdir / "timing.json").read_text())
    prof = timing["profile"]["sensors"][sensors[0].name]
    print(json.dumps({
        "wall_s": wall,
        "cpu_s": cpu,
        "main_thread_cpu_s": main_cpu,
        "stream_s": timing["stream_s"],
        "sensor_s": prof["generator_s"],
        "build_s": prof["build_s"],
        "sensor_threads": timing.get("sensor_threads", 1),
    }))
    """
)

JOBS = {"camera": "camera", "lidar": "lidar"}


def run_case(kind: str, threads: int | None) -> dict[str, Any]:
    """One run of the default job's ``kind`` sensor alone with ``threads`` per sensor
    (None: the automatic count)."""
    env = dict(os.environ)
    env.pop("ROSLAN_SENSOR_THREADS", None)
    if threads is not None:
        env["ROSLAN_SENSOR_THREADS"] = str(threads)
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-c", CHILD, kind, str(Path(tmp) / "out")]
        r = subprocess.run(cmd, capture_output=True, text=True, env=env, check=False)
    if r.returncode != 0:
        raise SystemExit(f"run failed ({r.returncode}):\n{r.stderr}")
    out: dict[str, Any] = json.loads(r.stdout.strip().splitlines()[-1])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", nargs="+", default=list(JOBS), choices=list(JOBS))
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--repeat", type=int, default=3, help="alternations of the settings")
    ap.add_argument("--json", type=Path, default=None, help="also write the results here")
    args = ap.parse_args()
    results: dict[str, dict[int, list[dict[str, Any]]]] = {
        j: {n: [] for n in args.threads} for j in args.jobs
    }
    for rep in range(args.repeat):
        for job in args.jobs:
            for n in args.threads:  # alternated: each setting sees the same background load
                r = run_case(JOBS[job], n)
                results[job][n].append(r)
                print(
                    f"[{rep}] {job:6s} threads={n}: wall {r['wall_s']:6.2f} s, CPU "
                    f"{r['cpu_s']:6.2f} s (main thread {r['main_thread_cpu_s']:6.2f} s), stream "
                    f"{r['stream_s']:6.2f} s, sensor thread {r['sensor_s']:6.2f} s",
                    flush=True,
                )
    print(f"\nmedians (ratio to threads={args.threads[0]}):")
    for job in args.jobs:
        base = {k: statistics.median(r[k] for r in results[job][args.threads[0]]) for k in KEYS}
        for n in args.threads:
            med = {k: statistics.median(r[k] for r in results[job][n]) for k in KEYS}
            print(
                f"  {job:6s} threads={n}: "
                + ", ".join(f"{k} {med[k]:.2f} ({med[k] / base[k]:.2f})" for k in KEYS)
            )
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=1))


KEYS = ("wall_s", "cpu_s", "main_thread_cpu_s", "stream_s", "sensor_s")


if __name__ == "__main__":
    main()
