"""Steps per process CPU-second of an unrecorded closed-loop episode, A/B between trees.

Two cases: the default ``roslan/Landing-v0`` (warehouse, 1 kHz IMU, DAVIS346 event camera)
and the same config with only its IMU. Each run is a fresh interpreter that resets the
environment (seed 0, not timed) and then flies the tau-state policy for at most ``--steps``
control steps (or to the episode's end), timing only the steps with
``time.process_time()`` (every thread of the process; there are no children). Trees are
alternated run by run (A, B, A, B...), so both see the same machine load; the figure is
the median over ``--repeat`` runs per tree and case.

    python benchmarks/bench_env.py --a /work/base/src --b src [--repeat 3] [--steps 150]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys

CHILD = """
import sys, time
import numpy as np
from roslan.env import LandingEnv, make_policy
from roslan.env.landing import load_env_config
from roslan.env.policies import PolicyContext

case, steps = sys.argv[1], int(sys.argv[2])
cfg, _ = load_env_config(None)
if case == "imu":
    cfg = cfg.model_copy(update={"sensors": [s for s in cfg.sensors if s.type == "imu"]})
env = LandingEnv(cfg)
obs, info = env.reset(seed=0)
pol = make_policy("tau-state")
dyn = env.closed_loop.dynamics
pol.reset(PolicyContext(env.config, env.dt, env._traj.R_world_goal,
                        dyn.max_acceleration, dyn.max_body_rate))
n = 0
c0 = time.process_time()
while n < steps:
    obs, _, term, trunc, info = env.step(np.asarray(pol.act(obs, info)))
    n += 1
    if term or trunc:
        break
cpu = time.process_time() - c0
env.close()
print(n, cpu)
"""


def _once(src: str, case: str, steps: int) -> tuple[int, float]:
    env = dict(os.environ, PYTHONPATH=src)
    out = subprocess.run(
        [sys.executable, "-c", CHILD, case, str(steps)],
        env=env,
        check=True,
        capture_output=True,
        text=True,
    ).stdout.split()
    return int(out[-2]), float(out[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--a", required=True, help="source tree A (PYTHONPATH), e.g. main's src")
    ap.add_argument("--b", required=True, help="source tree B (PYTHONPATH)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--steps", type=int, default=150)
    ap.add_argument("--cases", default="default,imu")
    args = ap.parse_args()
    print(f"load average at start: {os.getloadavg()}")
    for case in args.cases.split(","):
        rates: dict[str, list[float]] = {"A": [], "B": []}
        for _ in range(args.repeat):
            for name, src in (("A", args.a), ("B", args.b)):
                n, cpu = _once(src, case, args.steps)
                rates[name].append(n / cpu)
                print(f"  {case} {name}: {n} steps, {cpu:.2f} CPU-s, {n / cpu:.1f} steps/CPU-s")
        a, b = statistics.median(rates["A"]), statistics.median(rates["B"])
        print(f"{case}: A {a:.1f} steps/CPU-s, B {b:.1f} steps/CPU-s, B/A {b / a:.3f}")
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
