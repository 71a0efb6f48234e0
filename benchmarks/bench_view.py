"""``roslan view OUTDIR --save`` cost and reproducibility on an existing OUTDIR (run by hand).

    .venv/bin/python benchmarks/bench_view.py OUTDIR [--repeat 2] [--ab]

Each save runs in its own process (as the command does); the process's CPU seconds and
peak resident memory come from ``os.wait4``. Prints them, the file size, and whether every
save is the same file, byte for byte. ``--ab`` alternates saves with and without the
rewrite of the parts rerun-sdk stamps itself (``roslan.view.rrd_file``), A/B in one
virtual environment: compare within one run, never across machines or environments.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import subprocess
import sys
import tempfile
from pathlib import Path

CHILD = """
import sys
import roslan.view.recording as recording
if sys.argv[3] == "without":
    recording.canonicalize_envelope = lambda path, stamp_ns: None
from roslan.cli import main
sys.exit(main(["view", sys.argv[1], "--save", sys.argv[2]]))
"""


def _save(outdir: Path, out: Path, variant: str) -> tuple[float, float]:
    """CPU seconds and peak RSS (MiB) of one save in a child process."""
    cmd = [sys.executable, "-c", CHILD, str(outdir), str(out), variant]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"roslan view failed ({proc.returncode}) on {outdir}")
    return usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("outdir", type=Path, help="a roslan run folder")
    ap.add_argument("--repeat", type=int, default=2, help="saves per variant (default 2)")
    ap.add_argument("--ab", action="store_true", help="also save without the envelope rewrite")
    args = ap.parse_args()
    variants = ["with", "without"] if args.ab else ["with"]
    with tempfile.TemporaryDirectory() as tmp:
        digests: dict[str, list[tuple[int, str]]] = {v: [] for v in variants}
        for k in range(args.repeat):
            for v in variants:
                out = Path(tmp) / f"{v}{k}.rrd"
                cpu, rss = _save(args.outdir, out, v)
                print(f"{v:7s} save {k}: {cpu:.2f} CPU-s, {rss:.0f} MiB peak RSS")
                with out.open("rb") as f:
                    digests[v].append(
                        (out.stat().st_size, hashlib.file_digest(f, "sha256").hexdigest())
                    )
                out.unlink()
        for v, saves in digests.items():
            same = all(s == saves[0] for s in saves)
            print(f"{v:7s}: {saves[0][0] / 1e6:.1f} MB; {len(saves)} saves identical: {same}")


if __name__ == "__main__":
    main()
