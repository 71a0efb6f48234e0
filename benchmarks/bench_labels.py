"""CPU cost of issue 47's labels on the default job, A/B alternated.

    python benchmarks/bench_labels.py BASE_SRC BRANCH_SRC [PAIRS]

Runs ``roslan simulate`` of the default job (src/roslan/data/default.yaml) as three
variants, in turn, ``PAIRS`` times: ``base`` (``PYTHONPATH=BASE_SRC``, the version without
labels), ``off`` (``PYTHONPATH=BRANCH_SRC``, labels off: the default) and ``on`` (the same
job with ``output.labels: true``), each into a fresh folder without the overview, and
prints each run's CPU seconds (user + sys of the process and every child it waited for)
and the ratios off/base and on/off of the sums. Only ratios within one invocation mean
anything on a shared machine.
"""

from __future__ import annotations

import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def main() -> None:
    base_src, branch_src = sys.argv[1], sys.argv[2]
    pairs = int(sys.argv[3]) if len(sys.argv) > 3 else 2
    default = Path(branch_src) / "roslan" / "data" / "default.yaml"
    tmp = Path(tempfile.mkdtemp(prefix="bench_labels_"))
    job = yaml.safe_load(default.read_text())
    job.setdefault("output", {})["labels"] = True
    on_yaml = tmp / "labels_on.yaml"
    on_yaml.write_text(yaml.safe_dump(job))
    variants = {
        "base": (base_src, [str(default)]),
        "off": (branch_src, [str(default)]),
        "on": (branch_src, [str(on_yaml)]),
    }
    cpu: dict[str, list[float]] = {k: [] for k in variants}
    for i in range(pairs):
        for name, (src, args) in variants.items():
            out = tmp / f"{name}_{i}"
            env = {**os.environ, "PYTHONPATH": src}
            t0, w0 = _cpu(), time.perf_counter()
            cmd = [
                sys.executable,
                "-m",
                "roslan",
                "simulate",
                *args,
                "-o",
                str(out),
                "--no-overview",
            ]
            subprocess.run(cmd, env=env, check=True, capture_output=True)
            cpu[name].append(_cpu() - t0)
            wall = time.perf_counter() - w0
            print(f"{name} run {i}: {cpu[name][-1]:.1f} CPU-s, {wall:.1f} s wall", flush=True)
            shutil.rmtree(out)
    s = {k: sum(v) for k, v in cpu.items()}
    print(f"off/base {s['off'] / s['base']:.3f}, on/off {s['on'] / s['off']:.3f} "
          f"(load average {os.getloadavg()[0]:.1f})")  # fmt: skip
    shutil.rmtree(tmp)


if __name__ == "__main__":
    main()
