"""CPU of the causal engine stepped like a 50 Hz episode against ``roslan simulate``.

The packaged default job reduced to its event camera and IMU (what the closed-loop
environment's default carries) over the default landing: ``sim`` = ``run_simulation``
(its usual worker processes and render helpers), ``live`` = the live run
(:func:`roslan.pipeline.open_run`) stepped every 20 ms on the same trajectory behind a
:class:`~roslan.trajectory.base.HorizonGuard`, writing the same OUTDIR, everything in one
process, the event camera sampling every step's end; ``bare`` = the same without an
OUTDIR (no bags). Each case runs in a fresh process, cases alternated; CPU of the process
and its children.

    PYTHONPATH=src .venv/bin/python benchmarks/bench_live_run.py [--repeat 2]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

CHILD = """
import resource, sys, time
from pathlib import Path
import roslan.scene as scene_mod
from roslan.cli.simulate import load_config
from roslan.pipeline import RunOptions, open_run, run_simulation
from roslan.trajectory import TauTrajectory
from roslan.trajectory.base import HorizonGuard
from roslan.vehicle import base_link_trajectory

mode, out = sys.argv[1], Path(sys.argv[2])
cfg, _ = load_config(None)
keep = [s for s in cfg.sensors if s.type in ("imu", "event_camera")]
cfg = cfg.model_copy(update={"sensors": keep})
t0, w0 = time.process_time(), time.perf_counter()
if mode == "sim":
    run_simulation(cfg, out, quiet=True)
else:
    scene = scene_mod.load_scene(cfg.scene, seed=cfg.seed)
    traj = TauTrajectory(base_link_trajectory(cfg.trajectory, cfg.vehicle, scene))
    guard = HorizonGuard(traj)
    run = open_run(cfg, out if mode == "live" else None, guard, scene=scene)
    h, end = 0, traj.duration_ns
    while h + 20_000_000 < end:
        h += 20_000_000
        guard.set_horizon(h)
        run.advance(h)
    guard.finish()
    run.finish(end)
ru = resource.getrusage(resource.RUSAGE_CHILDREN)
cpu = time.process_time() - t0 + ru.ru_utime + ru.ru_stime
print(f"{mode} {cpu:.2f} {time.perf_counter() - w0:.2f}")
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    rows: dict[str, list[tuple[float, float]]] = {"sim": [], "live": [], "bare": []}
    with tempfile.TemporaryDirectory(prefix="roslan-live-bench-") as tmp:
        for i in range(args.repeat):
            for mode in rows:
                out = Path(tmp) / f"{mode}{i}"
                res = subprocess.run(
                    [sys.executable, "-c", CHILD, mode, str(out)],
                    check=True,
                    capture_output=True,
                    text=True,
                )
                _, cpu, wall = res.stdout.split()
                rows[mode].append((float(cpu), float(wall)))
                print(f"{mode} run {i}: CPU {float(cpu):6.1f} s, wall {float(wall):6.1f} s")
    sim = sorted(c for c, _ in rows["sim"])[len(rows["sim"]) // 2]
    for mode, vals in rows.items():
        med = sorted(c for c, _ in vals)[len(vals) // 2]
        print(f"median {mode}: CPU {med:.1f} s ({med / sim:.2f}x simulate)")


if __name__ == "__main__":
    main()
