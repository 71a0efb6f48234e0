"""End-to-end speed of the default demo suite (issue 9).

The packaged default job (warehouse, DAVIS346 event camera with adaptive sampling,
640x480 camera at 30 Hz, HDL-32E at 10 Hz, IMU at 1 kHz, sonar, altimeter, ground
truth, both bag formats, events.txt/h5) is run in a fresh subprocess per case, for the
default landing and for landings stretched 2x and 4x in time (same path, slower descent
rate), and prints:

* real-time factor = simulation wall time / trajectory duration (<= 1: faster than real
  time), also by CPU time (robust to other load on the machine);
* each sensor's share of the time (``roslan simulate --profile`` figures);
* peak resident memory (ru_maxrss of the child), which must stay flat with duration.

    .venv/bin/python benchmarks/bench_e2e.py [--scales 1 2 4] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
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
    from roslan.pipeline.cli import load_config
    from roslan.simulate import run_simulation

    scale, outdir = float(sys.argv[1]), Path(sys.argv[2])
    cfg, _ = load_config(None)
    traj = cfg.trajectory
    # same path, descent rate / scale: the landing lasts `scale` times longer
    initial = traj.initial.model_copy(update={"descent_rate": traj.initial.descent_rate / scale})
    cfg = cfg.model_copy(update={"trajectory": traj.model_copy(update={"initial": initial})})
    t0, c0 = time.perf_counter(), time.process_time()
    run = run_simulation(cfg, outdir, quiet=True, profile=True, overview=False)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    timing = json.loads((outdir / "timing.json").read_text())
    print(json.dumps({
        "duration_s": run["trajectory_duration_s"],
        "messages": run["messages_total"],
        "wall_s": wall,
        "cpu_s": cpu,
        "rtf_wall": wall / run["trajectory_duration_s"],
        "rtf_cpu": cpu / run["trajectory_duration_s"],
        "profile": timing["profile"],
        "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }))
    """
)


def run_case(scale: float) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as tmp:
        out = subprocess.run(
            [sys.executable, "-c", CHILD, str(scale), str(Path(tmp) / "out")],
            check=True,
            capture_output=True,
            text=True,
        )
    result: dict[str, Any] = json.loads(out.stdout.strip().splitlines()[-1])
    return result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scales", type=float, nargs="+", default=[1.0, 2.0, 4.0])
    ap.add_argument("--json", type=Path, default=None, help="also write the results here")
    args = ap.parse_args()
    results = []
    for scale in args.scales:
        r = run_case(scale)
        r["scale"] = scale
        results.append(r)
        sensors = r["profile"]["sensors"]
        total = sum(v["generator_s"] + v["build_s"] + v["close_s"] for v in sensors.values())
        total += r["profile"]["writers_s"]
        print(
            f"x{scale:g}: trajectory {r['duration_s']:.2f} s, wall {r['wall_s']:.1f} s, "
            f"RTF wall {r['rtf_wall']:.2f}, RTF cpu {r['rtf_cpu']:.2f}, "
            f"peak RSS {r['peak_rss_mib']:.0f} MiB, {r['messages']} messages"
        )
        for name, v in sensors.items():
            t = v["generator_s"] + v["build_s"] + v["close_s"]
            print(f"    {name:14s} {t:8.2f} s  {100 * t / total:5.1f} %")
        w = r["profile"]["writers_s"]
        print(f"    {'bag writers':14s} {w:8.2f} s  {100 * w / total:5.1f} %")
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
