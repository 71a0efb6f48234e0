"""Disk use of a run's outputs, part by part, against the ``--dry-run`` estimate.

Runs a job (the packaged default job unless a config is given) into a temporary folder
and prints:

* the size of every top-level output (bags, events.txt, events.h5, lidar/, PNG folders,
  the rest) and of the whole OUTDIR, with the estimate of ``roslan.pipeline.estimate``
  and the ratio real / estimate;
* the ROS 2 / ROS 1 bag size ratio;
* per topic: raw message bytes and their compressed share in each bag's codec (the ratios
  the estimator's ``_RATIO`` table is calibrated with).

    .venv/bin/python benchmarks/bench_outputs.py [CONFIG] [--keep DIR] [--json FILE]
"""

from __future__ import annotations

import argparse
import bz2
import functools
import json
import shutil
import tempfile
from pathlib import Path
from typing import Any

import lz4.frame
from rosbags.highlevel import AnyReader

from roslan.cli.simulate import load_config
from roslan.io.bag import ZSTD_LEVEL, roslz4_compress
from roslan.pipeline import run_simulation
from roslan.pipeline.estimate import estimate_run

_CHUNK = 1 << 20


def _size(path: Path) -> int:
    if path.is_file():
        return path.stat().st_size
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())


def _topic_ratios(bag: Path, codec: str) -> dict[str, tuple[float, float]]:
    """topic -> (raw MB, compressed / raw) with ``codec`` over 1 MiB runs of its messages."""
    bufs: dict[str, bytearray] = {}
    with AnyReader([bag]) as reader:
        for conn, _, raw in reader.messages():
            bufs.setdefault(conn.topic, bytearray()).extend(raw)
    compress: Any
    if codec == "zstd":
        import zstandard

        compress = zstandard.ZstdCompressor(level=ZSTD_LEVEL).compress
    elif codec == "lz4":  # ROS 1: roslz4's frame layout; ROS 2 (MCAP): one lz4 frame
        compress = roslz4_compress if bag.suffix == ".bag" else lz4.frame.compress
    elif codec == "bz2":
        compress = functools.partial(bz2.compress, compresslevel=9)
    else:
        compress = bytes
    out = {}
    for topic, b in sorted(bufs.items(), key=lambda kv: -len(kv[1])):
        n = sum(len(compress(bytes(b[i : i + _CHUNK]))) for i in range(0, len(b), _CHUNK))
        out[topic] = (len(b) / 1e6, n / max(len(b), 1))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("config", nargs="?", type=Path, help="job YAML (default: the default job)")
    ap.add_argument("--keep", type=Path, help="write the run here instead of a temporary folder")
    ap.add_argument("--json", type=Path, help="also write the figures as JSON")
    args = ap.parse_args()

    cfg, _ = load_config(args.config)
    est = estimate_run(cfg)
    tmp = Path(tempfile.mkdtemp(prefix="bench_outputs_"))
    out = args.keep or tmp / "out"
    try:
        run = run_simulation(cfg, out, quiet=True, overview=True)
        parts = {p.name: _size(p) for p in out.iterdir()}
        total = sum(parts.values())
        big = {k: v for k, v in sorted(parts.items(), key=lambda kv: -kv[1]) if v > 1e6}
        rest = total - sum(big.values())
        duration = run["trajectory_duration_s"]
        print(f"{run['messages_total']} messages, {duration:.2f} s of trajectory")
        print(f"{'output':<22}{'MB':>10}")
        for name, v in big.items():
            print(f"{name:<22}{v / 1e6:>10.1f}")
        print(f"{'rest':<22}{rest / 1e6:>10.1f}")
        print(f"{'OUTDIR':<22}{total / 1e6:>10.1f}   estimate {est.bytes / 1e6:.1f} MB "
              f"(real / estimate {total / est.bytes:.2f})")  # fmt: skip
        figures: dict[str, Any] = {"parts": parts, "total": total, "estimate": est.bytes}
        bags = run["bags"]
        if "ros1" in bags and "ros2" in bags:
            r1, r2 = _size(out / bags["ros1"]), _size(out / bags["ros2"])
            figures["ros2_over_ros1"] = r2 / r1
            print(f"ROS 2 bag / ROS 1 bag: {r2 / r1:.2f}")
        compression = cfg.output.compression
        for flavor, codec in (("ros1", compression), ("ros2", cfg.output.ros2_compression)):
            if flavor not in bags:
                continue
            ratios = _topic_ratios(out / bags[flavor], codec)
            figures[f"ratios_{flavor}"] = ratios
            print(f"{flavor} ({codec}): topic, raw MB, compressed / raw")
            for topic, (mb, ratio) in list(ratios.items())[:6]:
                print(f"  {topic:<28}{mb:>8.1f}{ratio:>8.2f}")
        if args.json:
            args.json.write_text(json.dumps(figures, indent=1))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
