"""CPU time and size of the bag and dataset codecs at each level, on a run's own data.

Reads an OUTDIR (e.g. ``bench_outputs.py --keep DIR`` of the default job) and compresses
the same data with every level the project considered (issue 27):

* the messages of ``landing.bag`` in 1 MiB runs (what a chunk holds): lz4 in ROS 1's
  roslz4 frame layout at the fast mode (0) and HC levels 3 and 9;
* the messages of the ROS 2 bag in 1 MiB runs: zstd levels 1 and 3, and lz4;
* every LiDAR scan ``lidar/*/*.npz`` saved again at deflate 1 and 6 (6 =
  ``np.savez_compressed``).

For each: CPU seconds (this thread's clock, best of ``--repeat``) and compressed MB.

    PYTHONPATH=src .venv/bin/python benchmarks/bench_codecs.py OUTDIR [--repeat 2]
"""

from __future__ import annotations

import argparse
import functools
import io
import time
from collections.abc import Callable
from pathlib import Path

import lz4.frame
import numpy as np
from rosbags.highlevel import AnyReader

from roslan.io.bag import roslz4_compress
from roslan.io.files import save_npz

_CHUNK = 1 << 20


def _runs(bag: Path) -> list[bytes]:
    """The bag's message bytes, in record order, cut into 1 MiB runs."""
    buf = bytearray()
    out: list[bytes] = []
    with AnyReader([bag]) as reader:
        for _, _, raw in reader.messages():
            buf.extend(raw)
            if len(buf) >= _CHUNK:
                out.append(bytes(buf))
                buf.clear()
    if buf:
        out.append(bytes(buf))
    return out


def _roslz4(level: int) -> Callable[[bytes], bytes]:
    return functools.partial(roslz4_compress, level=level)


def _zstd(level: int) -> Callable[[bytes], bytes]:
    try:
        from compression import zstd  # type: ignore[import-not-found, unused-ignore]
    except ImportError:
        from backports import zstd

    return lambda data: zstd.compress(data, level=level)


def _time(fn: Callable[[], int], repeat: int) -> tuple[float, int]:
    best, size = float("inf"), 0
    for _ in range(repeat):
        c0 = time.thread_time()
        size = fn()
        best = min(best, time.thread_time() - c0)
    return best, size


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir", type=Path)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    rows: list[tuple[str, float, int, int]] = []
    ros1 = args.outdir / "landing.bag"
    ros2 = args.outdir / "landing_ros2"
    if ros1.exists():
        runs = _runs(ros1)
        raw = sum(map(len, runs))
        for name, comp in (
            ("ROS 1 lz4 fast (0)", _roslz4(0)),
            ("ROS 1 lz4 HC 3", _roslz4(3)),
            ("ROS 1 lz4 HC 9", _roslz4(9)),
        ):
            cpu, size = _time(lambda c=comp: sum(len(c(r)) for r in runs), args.repeat)
            rows.append((name, cpu, size, raw))
    if ros2.exists():
        runs = _runs(ros2)
        raw = sum(map(len, runs))
        for name, comp in (
            ("ROS 2 zstd 1", _zstd(1)),
            ("ROS 2 zstd 3", _zstd(3)),
            ("ROS 2 lz4", lambda d: lz4.frame.compress(d, store_size=True)),
        ):
            cpu, size = _time(lambda c=comp: sum(len(c(r)) for r in runs), args.repeat)
            rows.append((name, cpu, size, raw))
    scans = sorted(args.outdir.glob("lidar/*/*.npz"))
    if scans:
        data = []
        for p in scans:
            with np.load(p) as z:
                data.append({k: z[k] for k in z.files})
        raw = sum(sum(a.nbytes for a in d.values()) for d in data)
        for level in (1, 6):

            def save_all(lv: int = level) -> int:
                n = 0
                for d in data:
                    bio = io.BytesIO()
                    save_npz(bio, d, level=lv)
                    n += len(bio.getvalue())
                return n

            cpu, size = _time(save_all, args.repeat)
            rows.append((f"LiDAR .npz deflate {level}", cpu, size, raw))
    print(f"{'codec':<24}{'CPU-s':>8}{'MB':>9}{'ratio':>8}")
    for name, cpu, size, raw in rows:
        print(f"{name:<24}{cpu:>8.2f}{size / 1e6:>9.1f}{size / max(raw, 1):>8.3f}")


if __name__ == "__main__":
    main()
