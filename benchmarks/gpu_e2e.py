"""The default job's end-to-end figures on a many-core machine with a GPU (issue 27).

Runs, in fresh subprocesses and alternating, best of ``--repeat`` (default 2):

1. the packaged default job with ``--workers auto``;
2. the same with the event camera at ``max_rate: 1000``;
3. the default job with ``--workers auto`` and ``ROSLAN_SENSOR_THREADS=1`` (every frame
   and scan post-processed on its sensor's own thread, as before the per-sensor pools);
4. the default job and the ``max_rate: 1000`` one with ``--workers 3``: one process per
   render-heavy sensor and no render helpers of the event camera (``auto`` adds helpers up
   to half the CPUs: 5 on 16 cores), to see what the time-parallel chains give;
5. (``--with-serial``) the default job with ``--workers 0`` for comparison;

and prints for each: the real-time factor (wall / trajectory time), CPU seconds per
trajectory second (whole process tree), core utilisation over the run and while
streaming, the critical path (busy seconds of each process while streaming) and the
OpenGL renderer EGL gives (GL_RENDERER). Then the default job's frame camera and HDL-32E
each alone (``--workers 0``, :mod:`bench_sensor_threads`), once with 1 thread per sensor
and once with the automatic count: wall time, CPU time and the sensor's own thread. Every
figure and the machine description go to ``OUTDIR/gpu_e2e.json``. About 2-3 minutes on a
16-core machine with an H200; run from the repository root:

    PYTHONPATH=src:benchmarks python3 benchmarks/gpu_e2e.py OUTDIR
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import bench_sensor_threads
from bench_e2e import _report, run_case

CASES: list[tuple[str, str, float | None, str | None]] = [
    ("default job, --workers auto", "auto", None, None),
    ("event camera max_rate 1000, --workers auto", "auto", 1000.0, None),
    ("default job, --workers auto, ROSLAN_SENSOR_THREADS=1", "auto", None, "1"),
    ("default job, --workers 3 (no render helpers)", "3", None, None),
    ("event camera max_rate 1000, --workers 3 (no render helpers)", "3", 1000.0, None),
]


@contextlib.contextmanager
def _sensor_threads(value: str | None) -> Iterator[None]:
    """``ROSLAN_SENSOR_THREADS`` = ``value`` (None: unset) for the runs started inside."""
    old = os.environ.pop("ROSLAN_SENSOR_THREADS", None)
    if value is not None:
        os.environ["ROSLAN_SENSOR_THREADS"] = value
    try:
        yield
    finally:
        os.environ.pop("ROSLAN_SENSOR_THREADS", None)
        if old is not None:
            os.environ["ROSLAN_SENSOR_THREADS"] = old


def _sensors_alone(repeat: int = 1) -> dict[str, Any]:
    """The frame camera and the HDL-32E alone, 1 thread vs the automatic count."""
    runs: dict[str, list[dict[str, Any]]] = {}
    for _ in range(repeat):
        for kind in ("camera", "lidar"):
            for threads in (1, None):
                name = f"{kind} alone, --workers 0, threads {threads or 'auto'}"
                r = bench_sensor_threads.run_case(kind, threads)
                runs.setdefault(name, []).append(r)
                print(
                    f"--- {name} ({r['sensor_threads']} threads): wall {r['wall_s']:.2f} s, CPU "
                    f"{r['cpu_s']:.2f} s, sensor thread {r['sensor_s']:.2f} s",
                    flush=True,
                )
    return runs


def _machine() -> dict[str, Any]:
    info: dict[str, Any] = {
        "cpus": os.cpu_count(),
        "usable_cpus": len(os.sched_getaffinity(0)),
        "platform": platform.platform(),
        "python": platform.python_version(),
    }
    try:
        smi = subprocess.run(
            ["nvidia-smi", "--query-gpu=name,driver_version", "--format=csv,noheader"],
            capture_output=True,
            text=True,
            timeout=20,
        )
        info["gpu"] = smi.stdout.strip() or smi.stderr.strip()
    except (OSError, subprocess.SubprocessError) as err:
        info["gpu"] = f"none found ({err})"
    probe = (
        "from roslan.render.gl.context import create_context\n"
        "c = create_context()\n"
        "print(c.info['GL_RENDERER'], '/', c.info['GL_VERSION'])\n"
    )
    r = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    lines = (r.stdout.strip() or r.stderr.strip() or "?").splitlines()
    info["gl"] = lines[-1]
    return info


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir", type=Path, help="folder for gpu_e2e.json (created)")
    ap.add_argument("--repeat", type=int, default=2, help="runs per case (best is reported)")
    ap.add_argument("--with-serial", action="store_true", help="also run --workers 0")
    args = ap.parse_args()
    args.outdir.mkdir(parents=True, exist_ok=True)
    cases = list(CASES)
    if args.with_serial:
        cases.append(("default job, --workers 0", "0", None, None))
    machine = _machine()
    print(f"machine: {machine}", flush=True)
    runs: dict[str, list[dict[str, Any]]] = {name: [] for name, _, _, _ in cases}
    for _ in range(args.repeat):
        for name, workers, rate, threads in cases:
            with _sensor_threads(threads):
                r = run_case(1.0, workers, rate)
            r["scale"] = 1.0
            runs[name].append(r)
            print(f"--- {name}", flush=True)
            _report(r, workers)
    print("\nsummary (best of each case by wall time):")
    best = {}
    for name, rs in runs.items():
        b = min(rs, key=lambda r: r["wall_s"])
        best[name] = b
        path = "; ".join(f"{n} {t:.1f} s" for n, t in b["critical_path"][:3])
        print(
            f"  {name}: real-time factor {b['rtf_wall']:.2f} (wall {b['wall_s']:.1f} s, "
            f"set-up {b['stream_start_s']:.1f} s), {b['rtf_cpu']:.2f} CPU-s per trajectory "
            f"second, utilisation {b['utilisation_stream']:.2f} cores while streaming; "
            f"critical path: {path}"
        )
    alone = _sensors_alone()
    for name, rs in alone.items():
        b = min(rs, key=lambda r: r["wall_s"])
        best[name] = b
        print(
            f"  {name}: wall {b['wall_s']:.2f} s, CPU {b['cpu_s']:.2f} s, sensor thread "
            f"{b['sensor_s']:.2f} s ({b['sensor_threads']} threads)"
        )
    runs.update(alone)
    out = {"machine": machine, "runs": runs, "best": best}
    (args.outdir / "gpu_e2e.json").write_text(json.dumps(out, indent=1))
    print(f"wrote {args.outdir / 'gpu_e2e.json'}")


if __name__ == "__main__":
    main()
