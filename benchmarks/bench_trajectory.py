"""Full closed-form trajectory state at 10^6 instants (target: <= 0.5 s on 2 cores).

Run: .venv/bin/python benchmarks/bench_trajectory.py [N]
Prints wall and CPU time (this process's CPU time is the fairer figure while other
work shares the two cores) of the first call in this process (it includes the kernel
mapping fresh pages for the ~0.37 GB result) and the median of repeated calls (steady
state, what a sensor sampling the trajectory chunk after chunk sees), for the default
config and for one with a tilted goal and flapping.
"""

from __future__ import annotations

import statistics
import sys
import time
import warnings

import numpy as np

from roslan.trajectory import TauTrajectory, Trajectory, TrajectoryConfig, TrajectoryWarning


def bench(name: str, traj: Trajectory, n: int, repeats: int = 7) -> None:
    t = np.linspace(0.0, traj.T, n)
    wall, cpu = [], []
    for _ in range(repeats):
        w0, c0 = time.perf_counter(), time.process_time()
        st = traj.state(t)
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
        del st
    med = statistics.median(wall[1:])
    print(
        f"{name:<24} N={n:>9,d}  first {wall[0]:.3f} s  median wall {med:.3f} s  "
        f"min wall {min(wall[1:]):.3f} s  median CPU {statistics.median(cpu[1:]):.3f} s  "
        f"({n / med / 1e6:.1f} M states/s)"
    )


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 1_000_000
    warnings.simplefilter("ignore", TrajectoryWarning)
    bench("default", TauTrajectory(TrajectoryConfig()), n)
    cfg = TrajectoryConfig.model_validate(
        {
            "kappa": {"x": 0.4, "y": 0.6, "roll": 0.7, "pitch": 0.8, "yaw": 0.9},
            "goal": {"position": [1.0, 2.0, 0.5], "rpy": [0.1, -0.1, 1.0]},
            "flapping": {"frequency": 8.0, "heave": 0.05, "pitch": 0.1},
        }
    )
    bench("tilted goal + flapping", TauTrajectory(cfg), n)


if __name__ == "__main__":
    main()
