"""Pipeline throughput and memory: IMU (1 kHz) + ground truth (200 Hz), both bag formats.

Runs each case in a fresh subprocess (so ``ru_maxrss`` is that run's peak) and prints
trajectory duration, wall and CPU time, real-time factors (whole run by wall and by CPU
time -- the CPU figure is robust to other load on the machine -- and the streaming phase
alone, without the one-off trajectory export and plot) and peak memory.

    .venv/bin/python benchmarks/bench_pipeline.py [--durations 60 240]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

CHILD = textwrap.dedent(
    """
    import json, resource, sys, time, tracemalloc
    from pathlib import Path
    from roslan.config.sim import SimConfig
    from roslan.pipeline import run_simulation

    duration, outdir, trace = float(sys.argv[1]), Path(sys.argv[2]), sys.argv[3] == "1"
    # T = z0 / (k v0) with k = 0.5, v0 = 1 m/s: z0 = duration / 2 gives T = duration
    cfg = SimConfig.model_validate({
        "trajectory": {"k": 0.5, "initial": {"position": [-20.0, 5.0, duration / 2],
                                             "rpy": [0.05, 0.15, 0.3],
                                             "descent_rate": 1.0}},
        "sensors": [{"type": "imu", "name": "imu", "rate": 1000.0, "topic": "/imu"}],
        "output": {"formats": ["ros1", "ros2"], "ground_truth_rate": 200.0},
    })
    if trace:
        tracemalloc.start()
    t0, c0 = time.perf_counter(), time.process_time()
    run = run_simulation(cfg, outdir, quiet=True)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    timing = json.loads((outdir / "timing.json").read_text())
    out = {
        "duration_s": run["trajectory_duration_s"],
        "messages": run["messages_total"],
        "wall_s": wall,
        "cpu_s": cpu,
        "stream_s": timing["stream_s"],
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "bag_mb": (outdir / "landing.bag").stat().st_size / 2**20,
    }
    if trace:
        out["tracemalloc_peak_mb"] = tracemalloc.get_traced_memory()[1] / 2**20
    print(json.dumps(out))
    """
)


def run_case(duration: float, trace: bool) -> dict[str, float]:
    with tempfile.TemporaryDirectory() as tmp:
        proc = subprocess.run(
            [
                sys.executable,
                "-c",
                CHILD,
                str(duration),
                str(Path(tmp) / "out"),
                "1" if trace else "0",
            ],
            check=True,
            capture_output=True,
            text=True,
        )
    result: dict[str, float] = json.loads(proc.stdout.strip().splitlines()[-1])
    return result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--durations", type=float, nargs="+", default=[60.0, 240.0])
    args = ap.parse_args()
    print(
        f"{'traj s':>7} {'msgs':>8} {'wall s':>7} {'RTF':>6} {'cpu s':>6} {'RTF(cpu)':>8} "
        f"{'stream RTF':>10} "
        f"{'peak RSS MB':>11} "
        f"{'py heap MB':>10} {'bag MB':>7}"
    )
    for d in args.durations:
        r = run_case(d, trace=False)
        t = run_case(d, trace=True)
        print(
            f"{r['duration_s']:7.1f} {int(r['messages']):8d} {r['wall_s']:7.2f} "
            f"{r['duration_s'] / r['wall_s']:6.1f} {r['cpu_s']:6.2f} "
            f"{r['duration_s'] / r['cpu_s']:8.1f} {r['duration_s'] / r['stream_s']:10.1f} "
            f"{r['peak_rss_mb']:11.1f} {t['tracemalloc_peak_mb']:10.1f} {r['bag_mb']:7.1f}"
        )


if __name__ == "__main__":
    main()
