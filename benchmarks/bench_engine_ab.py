"""A/B CPU cost of ``roslan simulate`` between two source trees (e.g. main and a branch).

Runs the packaged default job (or ``--config``) with ``PYTHONPATH`` set to each tree in
turn, A B A B ... (``--repeat`` pairs, so that a drift of the machine's load hits both
alike), each in a fresh process, and prints per run and as medians: the CPU seconds of
the whole process tree (user + system of the run and every child it waited for: sensor
workers, render helpers) per trajectory second, and the wall time. CPU time is the
figure to compare on a shared machine; wall time moves with the other load.

    .venv/bin/python benchmarks/bench_engine_ab.py --a /work/main/src --b src [--repeat 3]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _run(src: Path, config: str | None, outdir: Path) -> tuple[float, float, float]:
    """(CPU s of the process tree, wall s, trajectory s) of one ``simulate``."""
    env = {**os.environ, "PYTHONPATH": str(src.absolute())}
    cmd = [sys.executable, "-m", "roslan", "simulate", "-o", str(outdir), "--quiet"]
    if config is not None:
        cmd.insert(4, config)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, env=env, check=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    duration = float(json.loads((outdir / "run.json").read_text())["trajectory_duration_s"])
    return cpu, wall, duration


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--a", type=Path, required=True, help="source tree A (holds roslan/)")
    ap.add_argument("--b", type=Path, required=True, help="source tree B")
    ap.add_argument("--config", default=None, help="job YAML (default: the packaged job)")
    ap.add_argument("--repeat", type=int, default=3, help="A/B pairs")
    args = ap.parse_args()
    per: dict[str, list[tuple[float, float, float]]] = {"A": [], "B": []}
    with tempfile.TemporaryDirectory(prefix="roslan-ab-") as tmp:
        for i in range(args.repeat):
            for name, src in (("A", args.a), ("B", args.b)):
                out = Path(tmp) / f"{name}{i}"
                cpu, wall, dur = _run(src, args.config, out)
                per[name].append((cpu, wall, dur))
                rate = cpu / dur
                print(f"{name} run {i}: {rate:7.2f} CPU s per trajectory s, wall {wall:6.1f} s")
    med = {k: statistics.median(c / d for c, _, d in v) for k, v in per.items()}
    wall = {k: statistics.median(w for _, w, _ in v) for k, v in per.items()}
    for k in ("A", "B"):
        print(f"median {k}: {med[k]:.2f} CPU s per trajectory s, wall {wall[k]:.1f} s")
    print(f"B / A (CPU): {med['B'] / med['A']:.3f}")


if __name__ == "__main__":
    main()
