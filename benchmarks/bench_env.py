"""Steps per process CPU-second of an unrecorded closed-loop episode, and the reset's
cost, A/B(/C) between trees.

Cases: ``default``, the default ``roslan/Landing-v0`` (warehouse, 1 kHz IMU, DAVIS346
event camera); ``lite``, ``roslan/LandingLite-v0`` (the same landing with a 64x48 event
camera, this checkout's ``src/roslan/data/landing_lite.yaml``, flown in every tree);
``imu``, the default config with only its IMU; ``reset``, the default
config's resets. For ``default``, ``lite`` and ``imu`` each run is a fresh interpreter that resets
the environment (seed 0, not timed) and then flies the tau-state policy for at most
``--steps`` control steps (or to the episode's end), timing only the steps with
``time.process_time()`` (every thread of the process; there are no children). For
``reset`` a fresh interpreter times its first reset (seed 0: CPU and wall, every lazy
import and the scene included) and then three resets with new seeds (1, 2, 3: the median
CPU), with the tree's default ``closed_loop`` (today's ``scene_seed: fixed``; trees older
than the key rebuild the scene for every new seed). Trees are alternated run by run (A,
B, C, A, B, C...), so all see the same machine load; the figure is the median over
``--repeat`` runs per tree and case.

    python benchmarks/bench_env.py --a /work/base/src --b src [--c OTHER/src] \
        [--repeat 3] [--steps 150] [--cases default,lite,imu,reset] [--vec 1,2,4,8]

``--vec 1,2,4,8``: then, in tree B only, ``gymnasium.make_vec("roslan/LandingLite-v0",
num_envs=N)`` (the vector entry point: N envs in one process sharing the scene), reset
with seed 0 (not timed), then ``--vec-steps`` vector steps of zero action (hold the
velocity: the 2 m/s descent stays in the air for about 110 steps), timed in process CPU
(threads included) and wall; env-steps per CPU-second and per wall second, the median
over ``--repeat`` runs per N.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
from pathlib import Path

CHILD = """
import sys, time
import numpy as np
from roslan.env import LandingEnv, make_policy
from roslan.env.landing import load_env_config
from roslan.env.policies import PolicyContext

case, steps = sys.argv[1], int(sys.argv[2])
try:
    cfg, _ = load_env_config(sys.argv[3] if case == "lite" else None)
except Exception as err:  # a tree older than a key of landing_lite.yaml
    print("n/a", str(err).splitlines()[0])
    raise SystemExit(0)
if case == "imu":
    cfg = cfg.model_copy(update={"sensors": [s for s in cfg.sensors if s.type == "imu"]})
env = LandingEnv(cfg)
if case == "reset":
    c0, w0 = time.process_time(), time.perf_counter()
    env.reset(seed=0)
    first = (time.process_time() - c0, time.perf_counter() - w0)
    cpus = []
    for seed in (1, 2, 3):
        c0 = time.process_time()
        env.reset(seed=seed)
        cpus.append(time.process_time() - c0)
    env.close()
    print(first[0], first[1], sorted(cpus)[1])
    raise SystemExit(0)
if case.startswith("vec"):  # N LandingLite-v0 sharing one scene (the vector entry point)
    import gymnasium
    env.close()
    num = int(case[3:])
    envs = gymnasium.make_vec("roslan/LandingLite-v0", num_envs=num,
                              vectorization_mode="vector_entry_point")
    envs.reset(seed=0)
    zero = np.zeros((num, 6), dtype=np.float32)
    c0, w0 = time.process_time(), time.perf_counter()
    for _ in range(steps):
        envs.step(zero)
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    envs.close()
    print(num * steps, cpu, wall)
    raise SystemExit(0)
obs, info = env.reset(seed=0)
pol = make_policy("tau-state")
if hasattr(env, "policy_context"):
    pol.reset(env.policy_context())
else:  # (trees before LandingEnv.policy_context)
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


LITE = Path(__file__).resolve().parent.parent / "src" / "roslan" / "data" / "landing_lite.yaml"
"""This checkout's LandingLite-v0 config: the ``lite`` case flies it in every tree (a tree
older than the file runs the same YAML)."""


def _run(src: str, case: str, steps: int) -> list[str]:
    env = dict(os.environ, PYTHONPATH=src)
    return subprocess.run(
        [sys.executable, "-c", CHILD, case, str(steps), str(LITE)],
        env=env,
        check=True,
        capture_output=True,
        text=True,
    ).stdout.split()


def _once(src: str, case: str, steps: int) -> tuple[int, float] | None:
    """(steps, CPU-s), or None where the tree cannot load the case's config."""
    out = _run(src, case, steps)
    if "n/a" in out:
        print(f"  {case}: not in {src}: {' '.join(out[out.index('n/a') + 1 :])}")
        return None
    return int(out[-2]), float(out[-1])


def _vectors(src: str, sizes: list[int], steps: int, repeat: int) -> None:
    """The vector cases: N = each of ``sizes`` LandingLite-v0 in one process (tree B only)."""
    got: dict[int, list[tuple[float, float]]] = {n: [] for n in sizes}
    for _ in range(repeat):
        for n in sizes:
            env_steps, cpu, wall = (float(x) for x in _run(src, f"vec{n}", steps)[-3:])
            got[n].append((env_steps / cpu, env_steps / wall))
            print(f"  vec N={n}: {env_steps:.0f} env-steps, {cpu:.2f} CPU-s, {wall:.2f} s wall")
    for n, rows in got.items():
        per_cpu = statistics.median(r[0] for r in rows)
        per_wall = statistics.median(r[1] for r in rows)
        print(f"vec N={n}: {per_cpu:.1f} env-steps/CPU-s, {per_wall:.1f} env-steps/s wall")


def _resets(trees: dict[str, str], repeat: int) -> None:
    """The ``reset`` case: first reset CPU and wall, a new seed's reset CPU."""
    got: dict[str, list[tuple[float, ...]]] = {name: [] for name in trees}
    for _ in range(repeat):
        for name, src in trees.items():
            first_cpu, first_wall, new_cpu = (float(x) for x in _run(src, "reset", 0)[-3:])
            got[name].append((first_cpu, first_wall, new_cpu))
            print(
                f"  reset {name}: first {first_cpu:.2f} CPU-s ({first_wall:.2f} s wall), "
                f"new seed {new_cpu:.3f} CPU-s"
            )
    ref = statistics.median(r[2] for r in got["A"])
    for name, rows in got.items():
        med = [statistics.median(r[i] for r in rows) for i in range(3)]
        print(
            f"reset {name}: first {med[0]:.2f} CPU-s ({med[1]:.2f} s wall), new seed "
            f"{med[2]:.3f} CPU-s, {med[2] / ref:.3f}x A's"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--a", required=True, help="source tree A (PYTHONPATH), e.g. main's src")
    ap.add_argument("--b", required=True, help="source tree B (PYTHONPATH)")
    ap.add_argument("--c", default=None, help="source tree C (PYTHONPATH), optional")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--steps", type=int, default=150)
    ap.add_argument("--cases", default="default,imu,reset")
    ap.add_argument(
        "--vec",
        default="",
        help="N values, e.g. 1,2,4,8: LandingLite-v0's vector entry point in tree B, "
        "--vec-steps vector steps of zero action (hold velocity) each",
    )
    ap.add_argument("--vec-steps", type=int, default=60)
    args = ap.parse_args()
    trees = {"A": args.a, "B": args.b}
    if args.c:
        trees["C"] = args.c
    print(f"load average at start: {os.getloadavg()}")
    for case in filter(None, args.cases.split(",")):
        if case == "reset":
            _resets(trees, args.repeat)
            continue
        rates: dict[str, list[float]] = {name: [] for name in trees}
        for _ in range(args.repeat):
            for name, src in trees.items():
                got = _once(src, case, args.steps)
                if got is None:
                    continue
                n, cpu = got
                rates[name].append(n / cpu)
                print(f"  {case} {name}: {n} steps, {cpu:.2f} CPU-s, {n / cpu:.1f} steps/CPU-s")
        ref = next((statistics.median(r) for r in rates.values() if r), 1.0)
        first = next((name for name, r in rates.items() if r), "A")
        figures = ", ".join(
            f"{name} {statistics.median(r):.1f} steps/CPU-s "
            f"({statistics.median(r) / ref:.3f}x {first})"
            for name, r in rates.items()
            if r
        )
        print(f"{case}: {figures}")
    if args.vec:
        _vectors(args.b, [int(n) for n in args.vec.split(",")], args.vec_steps, args.repeat)
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
