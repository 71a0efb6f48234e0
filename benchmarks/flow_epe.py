"""Endpoint error of the DSEC flow PNGs against an independent reference (issue 37).

A 1.4 s landing in the warehouse (the default config's trajectory shortened: 0.9 s of
descent with the default flapping, 0.5 s hold), a DAVIS346 event camera at 25 Hz with
``optic_flow`` and ``depthmap``, twice: ``flow_interval`` 0.04 s (the root camera) and
0.1 s (``dvs100/``). The reference is built from the run's files only
(tests/helpers/flow_reference.py: depth.h5, groundtruth.txt at 200 Hz, calib/, OpenCV).

    PYTHONPATH=src python benchmarks/flow_epe.py /tmp/flow_epe [--workers N]

Prints, per camera, the median and 95th percentile EPE on valid pixels for a few frames
and over all maps, and the share of valid pixels (docs/guide/outputs-flow.md).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "helpers"))

from flow_reference import forward_rows, load_flow_run, read_flow_png, reference_flow

DVS = {
    "type": "event_camera", "rate": 25.0, "sensor": "davis346", "max_rate": 200.0,
    "optic_flow": True, "depthmap": True,
    "pose": {"position": [0.12, 0.03, 0.0], "rpy": [0.0, 0.349, 0.0]},
}  # fmt: skip


def config() -> object:
    from roslan.config.sim import SimConfig

    return SimConfig.model_validate(
        {
            "trajectory": {
                "k": 0.5,
                "initial": {"position": [-2.0, 0.6, 0.9], "rpy": [0.05, 0.15, 0.3],
                            "descent_rate": 2.0},
                "hold": 0.5,
                "flapping": {"frequency": 4.5, "heave": 0.008, "pitch": 0.035},
                "goal": {"position": [2.0, -1.0, 0.01], "rpy": [0.0, 0.0, 0.3]},
            },
            "scene": "warehouse",
            "seed": 0,
            "output": {"formats": ["ros1"], "ground_truth_rate": 200.0},
            "sensors": [
                {**DVS, "name": "dvs", "topic": "/dvs", "flow_interval": 0.04},
                {**DVS, "name": "dvs100", "topic": "/dvs100", "flow_interval": 0.1},
            ],
        }
    )  # fmt: skip


TOUCHDOWN_NS = 900_000_000  # T = z0 / (k v0) = 0.9 / (0.5 * 2.0)
SHOWN_MS = {40, 160, 400, 600, 800, 1000, 1200}
"""The t0 (ms) of the rows printed (the issue's table had 0, 40, 160, 600 and 1000 ms)."""


def report(out: Path, camera: str, folder: str) -> None:
    run = load_flow_run(out, camera, folder)
    rows = forward_rows(run.folder)
    errs, moving, n_valid, n_px = [], [], 0, 0
    print(f"\n{camera}: {rows.shape[0]} maps")
    print("| t0 (s) | t1 (s) | valid | leaves | other invalid | median EPE (px) | 95th pct (px) |")
    print("|---|---|---|---|---|---|---|")
    for i, (a, b) in enumerate(rows):
        t0, t1 = (a - run.start_us) * 1000, (b - run.start_us) * 1000
        flow, valid = read_flow_png(run.folder / "flow" / "forward" / f"{i:06d}.png")
        ref, _, _ = reference_flow(run, t0, t1)
        e = np.hypot(*(flow[valid] - ref[valid]).T)
        errs.append(e)
        if t1 <= TOUCHDOWN_NS:
            moving.append(e)
        n_valid += int(valid.sum())
        n_px += valid.size
        H, W = valid.shape
        u1 = np.arange(W)[None, :] + ref[..., 0]
        v1 = np.arange(H)[:, None] + ref[..., 1]
        inside = (u1 >= -0.5) & (u1 < W - 0.5) & (v1 >= -0.5) & (v1 < H - 0.5)
        if round(t0 * 1e-6) in SHOWN_MS or i == rows.shape[0] - 1:
            print(
                f"| {t0 * 1e-9:.2f} | {t1 * 1e-9:.2f} | {valid.mean():.1%} | "
                f"{(~inside).mean():.1%} | {(inside & ~valid).mean():.1%} | "
                f"{np.median(e):.4f} | {np.percentile(e, 95):.4f} |"
            )
    for name, part in (("all maps", errs), ("maps before touchdown", moving)):
        e = np.concatenate(part)
        print(
            f"{name}: median {np.median(e):.4f} px, 95th pct {np.percentile(e, 95):.4f} px, "
            f"max {e.max():.4f} px"
        )
    print(f"valid pixels: {n_valid / n_px:.1%}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("outdir", type=Path)
    ap.add_argument("--workers", default=0, type=int)
    args = ap.parse_args()
    if not (args.outdir / "run.json").exists():
        from roslan.pipeline import run_simulation

        run_simulation(config(), args.outdir, quiet=True, workers=args.workers, overview=False)  # type: ignore[arg-type]
    report(args.outdir, "dvs", "")
    report(args.outdir, "dvs100", "dvs100")


if __name__ == "__main__":
    main()
