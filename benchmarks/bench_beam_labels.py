"""What ``output.labels`` costs a LiDAR: one HDL-32E turn with and without labels, A/B.

Run by hand:  .venv/bin/python benchmarks/bench_beam_labels.py [--scene warehouse] [--repeat 20]

Along the default landing trajectory flown into the scene's goal, alternating the two
(same process, same turns, so load from other processes hits both alike), prints the
median CPU seconds (``time.process_time``: every thread of the cast) of a turn's
``Lidar.scan`` plus its ``.npz`` file, unlabelled and labelled, their ratio, and the
compressed bytes per point of the ``label`` array in the file.
"""

from __future__ import annotations

import argparse
import io
import time
import zipfile

import numpy as np

from roslan.config.base import Pose, validate_model
from roslan.io.files import save_npz
from roslan.render.raycast import get_raycaster
from roslan.scene import load_scene
from roslan.sensors.beams import Lidar, LidarConfig
from roslan.sensors.beams.labels import triangle_labels
from roslan.trajectory import TauTrajectory, TrajectoryConfig


def _turn(lid: Lidar, traj: TauTrajectory, caster: object, t0_ns: int, table: object) -> bytes:
    pts = lid.scan(traj, caster, t0_ns, np.random.default_rng(0), labels=table)  # type: ignore[arg-type]
    buf = io.BytesIO()
    save_npz(buf, {"stamp": np.asarray(t0_ns), **{k: pts[k] for k in pts.dtype.names or ()}})
    return buf.getvalue()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="warehouse")
    ap.add_argument("--repeat", type=int, default=20)
    args = ap.parse_args()
    scene = load_scene(args.scene)
    caster = get_raycaster(scene)
    table = triangle_labels(scene)
    goal = Pose(position=scene.goal_position, rpy=scene.goal_rpy)
    traj = TauTrajectory(TrajectoryConfig(goal=goal), warn=False)
    lid = Lidar(validate_model(LidarConfig, {"type": "lidar", "name": "velodyne"}))
    plain, labelled, per_point = [], [], []
    for t0 in np.linspace(0.0, traj.T - 0.1, args.repeat):
        t0_ns = round(t0 * 1e9)
        for labels in (None, table) if len(plain) % 2 == 0 else (table, None):
            c = time.process_time()
            data = _turn(lid, traj, caster, t0_ns, labels)
            (labelled if labels is not None else plain).append(time.process_time() - c)
            if labels is not None:
                with zipfile.ZipFile(io.BytesIO(data)) as zf:
                    info = zf.getinfo("label.npy")
                    per_point.append(info.compress_size / ((info.file_size - 128) / 4))
    a, b = float(np.median(plain)), float(np.median(labelled))
    print(f"scene {args.scene}, {args.repeat} turns, HDL-32E at 10 Hz")
    print(f"turn + npz, CPU: unlabelled {a * 1e3:.1f} ms, labelled {b * 1e3:.1f} ms, x{b / a:.3f}")
    print(f"label array in the npz: {np.median(per_point):.2f} bytes per point (median)")


if __name__ == "__main__":
    main()
