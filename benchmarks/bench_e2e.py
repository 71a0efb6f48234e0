"""End-to-end speed of the default demo suite.

The packaged default job (warehouse, DAVIS346 event camera with adaptive sampling,
640x480 camera at 30 Hz, HDL-32E at 10 Hz, IMU at 1 kHz, sonar, altimeter, ground
truth, both bag formats, events.txt/h5) is run in a fresh subprocess per case, for the
default landing and for landings stretched 2x and 4x in time (same path, slower descent
rate), and prints:

* real-time factor = simulation wall time / trajectory duration (<= 1: faster than real
  time), also by CPU time (robust to other load on the machine);
* each sensor's share of the time (``roslan simulate --profile`` figures);
* peak resident memory, which must stay flat with duration: the sum over the whole process
  tree (the simulation and its sensor worker processes, sampled every 20 ms with psutil)
  and the largest single process (ru_maxrss of the run and of its children);
* with ``--workers 0 auto`` the same cases without and with sensor worker processes;
* core utilisation: CPU seconds of the whole process tree per wall second, over the run
  and during streaming only (the tree's CPU clock sampled every 20 ms with psutil);
* the critical path: each process's busy seconds during streaming (a worker: its sensors'
  generator, message building and close; the main process: streaming minus its waits for
  the workers), longest first, and the bag writer threads' CPU seconds;
* ``--max-rate HZ`` sets the event camera's ``max_rate`` (default: the job's 200 Hz).

    .venv/bin/python benchmarks/bench_e2e.py [--scales 1 2 4] [--workers auto] \\
        [--max-rate 1000] [--repeat 2] [--json FILE]
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import json
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path
from typing import Any

import psutil  # type: ignore[import-untyped]

CHILD = textwrap.dedent(
    """
    import json, resource, sys, time
    from pathlib import Path
    from roslan.cli.simulate import load_config
    from roslan.pipeline import run_simulation

    scale, outdir, workers = float(sys.argv[1]), Path(sys.argv[2]), sys.argv[3]
    workers = workers if workers == "auto" else int(workers)
    max_rate = float(sys.argv[4]) if sys.argv[4] != "-" else None
    cfg, _ = load_config(None)
    traj = cfg.trajectory
    # same path, descent rate / scale: the landing lasts `scale` times longer
    initial = traj.initial.model_copy(update={"descent_rate": traj.initial.descent_rate / scale})
    cfg = cfg.model_copy(update={"trajectory": traj.model_copy(update={"initial": initial})})
    if max_rate is not None:
        sensors = [
            s.model_copy(update={"max_rate": max_rate}) if s.type == "event_camera" else s
            for s in cfg.sensors
        ]
        cfg = cfg.model_copy(update={"sensors": sensors})
    epoch0 = time.time()
    t0, c0 = time.perf_counter(), time.process_time()
    run = run_simulation(cfg, outdir, quiet=True, profile=True, overview=False, workers=workers)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu += kids.ru_utime + kids.ru_stime  # the sensor workers' CPU time
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
        "peak_rss_children_mib": kids.ru_maxrss / 1024,
        "workers": timing["workers"],
        "worker_sensors": timing["worker_sensors"],
        "render_helpers": timing.get("render_helpers", {}),
        "epoch0": epoch0,
        # (absent before issue 27: the streaming window is then unknown)
        "stream_start_s": timing.get("stream_start_s", timing["setup_s"]),
        "stream_s": timing["stream_s"],
    }))
    """
)


def _tree_sample(proc: psutil.Process) -> tuple[int, float]:
    """Resident bytes of the process tree, and its CPU seconds so far (reaped children's
    included, through the parent's ``children_*`` times)."""
    rss, cpu = 0, 0.0
    for k, p in enumerate([proc, *proc.children(recursive=True)]):
        with contextlib.suppress(psutil.Error):  # exited meanwhile
            rss += p.memory_info().rss
            t = p.cpu_times()
            cpu += t.user + t.system
            if k == 0:
                cpu += t.children_user + t.children_system
    return rss, cpu


def _cpu_at(samples: list[tuple[float, float]], when: float) -> float:
    """Tree CPU seconds at epoch ``when`` (linear between the samples)."""
    for (ta, ca), (tb, cb) in itertools.pairwise(samples):
        if ta <= when <= tb:
            return ca + (cb - ca) * (when - ta) / max(tb - ta, 1e-9)
    return samples[-1][1] if when > samples[-1][0] else samples[0][1]


def run_case(scale: float, workers: str, max_rate: float | None = None) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as tmp:
        rate = "-" if max_rate is None else str(max_rate)
        cmd = [sys.executable, "-c", CHILD, str(scale), str(Path(tmp) / "out"), workers, rate]
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        ps = psutil.Process(proc.pid)
        peak = 0
        samples: list[tuple[float, float]] = []
        try:
            while proc.poll() is None:
                try:
                    rss, cpu = _tree_sample(ps)
                except psutil.Error:
                    break
                peak = max(peak, rss)
                samples.append((time.time(), cpu))
                time.sleep(0.02)
            out, err = proc.communicate()
        finally:
            if proc.poll() is None:  # interrupted: stop the simulation (it cleans up)
                proc.terminate()
                proc.wait()
        if proc.returncode != 0:
            raise SystemExit(f"simulation failed ({proc.returncode}):\n{err}")
    result: dict[str, Any] = json.loads(out.strip().splitlines()[-1])
    result["peak_tree_rss_mib"] = peak / 2**20
    start = result["epoch0"] + result["stream_start_s"]
    stream_cpu = _cpu_at(samples, start + result["stream_s"]) - _cpu_at(samples, start)
    result["stream_cpu_s"] = stream_cpu
    result["utilisation_stream"] = stream_cpu / result["stream_s"]
    result["utilisation_run"] = result["cpu_s"] / result["wall_s"]
    result["critical_path"] = critical_path(result)
    return result


def critical_path(r: dict[str, Any]) -> list[tuple[str, float]]:
    """Busy seconds of each process during streaming, longest first: a worker's sensors'
    generator + build + close; the main process: streaming minus its waits for workers."""
    prof = r["profile"]
    busy: dict[int, float] = {}
    names: dict[int, list[str]] = {}
    for name, v in prof["sensors"].items():
        if "worker_pid" in v:
            pid = v["worker_pid"]
            busy[pid] = busy.get(pid, 0.0) + v["generator_s"] + v["build_s"] + v["close_s"]
            names.setdefault(pid, []).append(name)
    out = [(f"worker {pid} ({', '.join(names[pid])})", t) for pid, t in busy.items()]
    waited = sum(w["wait_s"] for w in prof.get("worker_wait", []))
    out.append(("main process (merge, local sensors, bag hand-over)", r["stream_s"] - waited))
    return sorted(out, key=lambda kv: -kv[1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scales", type=float, nargs="+", default=[1.0, 2.0, 4.0])
    ap.add_argument(
        "--workers",
        nargs="+",
        default=["auto"],
        help="output.workers values to run each scale with ('auto', 0, N)",
    )
    ap.add_argument("--max-rate", type=float, default=None, help="event camera max_rate (Hz)")
    ap.add_argument("--repeat", type=int, default=1, help="runs of each case (alternating)")
    ap.add_argument("--json", type=Path, default=None, help="also write the results here")
    args = ap.parse_args()
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # kill -> cleanup as Ctrl-C
    results = []
    for _ in range(args.repeat):
        for scale in args.scales:  # settings alternate: both see the same background load
            for workers in args.workers:
                r = run_case(scale, str(workers), args.max_rate)
                r["scale"] = scale
                results.append(r)
                _report(r, str(workers))
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=2))


def _report(r: dict[str, Any], workers: str) -> None:
    scale = r["scale"]
    sensors = r["profile"]["sensors"]
    total = sum(v["generator_s"] + v["build_s"] + v["close_s"] for v in sensors.values())
    total += r["profile"]["writers_s"]
    print(
        f"x{scale:g} workers={workers} ({r['workers']}: {r['worker_sensors']}; render helpers "
        f"{r.get('render_helpers', {})}): trajectory "
        f"{r['duration_s']:.2f} s, wall {r['wall_s']:.1f} s, RTF wall {r['rtf_wall']:.2f}, "
        f"RTF cpu {r['rtf_cpu']:.2f}, peak RSS tree {r['peak_tree_rss_mib']:.0f} MiB "
        f"(largest process {max(r['peak_rss_mib'], r['peak_rss_children_mib']):.0f} MiB), "
        f"{r['messages']} messages",
        flush=True,
    )
    for name, v in sensors.items():
        t = v["generator_s"] + v["build_s"] + v["close_s"]
        where = " (worker)" if "worker_pid" in v else ""
        print(f"    {name:14s} {t:8.2f} s  {100 * t / total:5.1f} %{where}")
    w = r["profile"]["writers_s"]
    print(f"    {'bag writers':14s} {w:8.2f} s  {100 * w / total:5.1f} % (hand-over in main)")
    print(
        f"    bag writer threads: {r['profile'].get('bag_threads_cpu_s', 0.0):.2f} CPU-s, "
        f"chunk compression {r['profile'].get('chunk_compression_cpu_s', 0.0):.2f} CPU-s"
    )
    for ww in r["profile"].get("worker_wait", []):
        print(f"    main waited {ww['wait_s']:6.2f} s for {', '.join(ww['sensors'])}")
    print(
        f"    CPU {r['cpu_s']:.1f} s = {r['rtf_cpu']:.2f} CPU-s per trajectory second; "
        f"utilisation {r['utilisation_run']:.2f} cores over the run, "
        f"{r['utilisation_stream']:.2f} while streaming ({r['stream_s']:.1f} s after "
        f"{r['stream_start_s']:.1f} s of set-up)"
    )
    print("    critical path (busy seconds while streaming):")
    for name, t in r["critical_path"]:
        print(f"      {t:7.2f} s  {name}")


if __name__ == "__main__":
    main()
