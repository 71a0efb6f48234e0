"""``--dry-run`` run-time estimates against measured runs of the README's examples.

    .venv/bin/python benchmarks/bench_estimates.py [--out DIR] [--only job perch ...]

Runs the README's ``job``, ``perch``, ``vision`` and ``ranges`` YAMLs (read from
README.md) and the default job, each as ``roslan simulate`` in a child process, and
prints one Markdown row per run: the estimate's wall seconds (its assumption: an idle
machine with this machine's cores) and CPU seconds, the measured wall and CPU seconds
(user + sys of the run and its worker processes, from ``os.wait4``), their ratios, and
the load average before and after. On a busy machine only the CPU figures compare with
the estimate; the wall time does on an idle one.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ("job", "perch", "vision", "ranges")


def readme_examples() -> dict[str, str]:
    """name -> YAML text of each ``# NAME.yaml`` block of the README."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    out = {}
    for name in EXAMPLES:
        m = re.search(rf"```yaml\n# {name}\.yaml\n(.*?)```", text, re.S)
        if m is None:
            raise SystemExit(f"README.md has no `# {name}.yaml` block")
        out[name] = m.group(1)
    return out


def estimate(config: Path | None) -> tuple[float, float, int]:
    """(wall s, CPU s, cores) of ``estimate_run`` for a YAML (None: the default job)."""
    from roslan.config.base import load_yaml_model
    from roslan.config.sim import SimConfig
    from roslan.pipeline.estimate import estimate_run

    path = config or ROOT / "src" / "roslan" / "data" / "default.yaml"
    cfg = load_yaml_model(SimConfig, path)
    est = estimate_run(cfg, base_dir=path.parent)
    return est.seconds, est.cpu, est.cores


def measure(config: Path | None, out: Path) -> tuple[float, float]:
    """(wall s, CPU s) of ``roslan simulate CONFIG -o OUT`` in a child process."""
    cmd = [sys.executable, "-c", "from roslan.cli import main; raise SystemExit(main())"]
    cmd += ["simulate", *([str(config)] if config else []), "-o", str(out), "--quiet", "--profile"]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=config.parent if config else None)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"roslan simulate {config} failed")
    return wall, usage.ru_utime + usage.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=None, help="work folder (default: a temp dir)")
    ap.add_argument("--only", nargs="+", default=[*EXAMPLES, "default"])
    args = ap.parse_args()
    work = args.out or Path(tempfile.mkdtemp(prefix="bench_estimates_"))
    work.mkdir(parents=True, exist_ok=True)
    yamls = readme_examples()
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} cores")
    print("| example | estimate wall | estimate CPU | measured wall | measured CPU |"
          " CPU measured / estimated | load before / after |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for name in args.only:
        config = None
        if name != "default":
            config = work / f"{name}.yaml"
            config.write_text(yamls[name], encoding="utf-8")
        e_wall, e_cpu, cores = estimate(config)
        load0 = os.getloadavg()[0]
        wall, cpu = measure(config, work / f"{name}_out_{int(time.time())}")
        load1 = os.getloadavg()[0]
        print(
            f"| {name} | {e_wall:.1f} s ({cores} cores) | {e_cpu:.1f} s | {wall:.1f} s |"
            f" {cpu:.1f} s | {cpu / e_cpu:.2f} | {load0:.1f} / {load1:.1f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
