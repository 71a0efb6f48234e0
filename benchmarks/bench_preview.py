"""Preview video and overview throughput on an existing OUTDIR (run by hand).

    .venv/bin/python benchmarks/bench_preview.py OUTDIR [--fps 30]

Prints seconds per overview.png and video frames per second for MP4 and GIF, and the
peak resident memory of this process.
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from pathlib import Path

from roslan.plots.overview import write_overview
from roslan.plots.preview import make_preview


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("outdir", type=Path)
    ap.add_argument("--fps", type=float, default=30.0)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        write_overview(args.outdir, Path(tmp) / "overview.png")
        print(f"overview.png: {time.perf_counter() - t0:.2f} s")
        for gif in (False, True):
            t0 = time.perf_counter()
            info = make_preview(
                args.outdir, Path(tmp) / ("p.gif" if gif else "p.mp4"), fps=args.fps, gif=gif
            )
            dt = time.perf_counter() - t0
            kind = "GIF" if gif else "MP4"
            print(
                f"{kind}: {info.frames} frames {info.size[0]}x{info.size[1]} in {dt:.2f} s "
                f"= {info.frames / dt:.1f} frames/s"
            )
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS {rss:.0f} MiB")


if __name__ == "__main__":
    main()
