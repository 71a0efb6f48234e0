"""Load time and triangle count of each built-in scene (plus clearance check and export).

Run by hand: ``.venv/bin/python benchmarks/bench_scene.py``. Each figure is the median of
``--repeat`` cold builds (the load_scene cache is bypassed), in one process.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from roslan.config.base import Pose
from roslan.render.raycast import get_raycaster
from roslan.scene import check_clearance, export_scene
from roslan.scene.builtin import empty
from roslan.scene.export import _GLB_CACHE
from roslan.scene.refinery import refinery
from roslan.scene.warehouse import warehouse
from roslan.trajectory import TauTrajectory, TrajectoryConfig


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    print(
        "| scene | objects | triangles | textures | build (s) | clearance check (s) | export (s) |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")
    for name, gen in (("warehouse", warehouse), ("refinery", refinery), ("empty", empty)):
        times = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            scene = gen(0)
            times.append(time.perf_counter() - t0)
        goal = Pose(position=scene.goal_position, rpy=scene.goal_rpy)
        traj = TauTrajectory(TrajectoryConfig(goal=goal))
        t0 = time.perf_counter()
        assert check_clearance(scene, traj, caster=get_raycaster(scene)) is None
        t_clear = time.perf_counter() - t0
        _GLB_CACHE.clear()
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            export_scene(scene, Path(tmp) / "x")
            t_export = time.perf_counter() - t0
        n_tex = len(
            {id(o.material.texture) for o in scene.objects if o.material.texture is not None}
        )
        print(
            f"| {name} | {len(scene.objects)} | {scene.n_triangles} | {n_tex} | "
            f"{statistics.median(times):.2f} | {t_clear:.3f} | {t_export:.2f} |"
        )


if __name__ == "__main__":
    main()
