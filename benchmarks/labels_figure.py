"""docs/img/labels.png: an event frame coloured by the events' instances beside the frame
camera's instance image at the same instant (docs/guide/labels.md).

    PYTHONPATH=src python benchmarks/labels_figure.py [OUT.png]

Runs a short labelled warehouse landing (an event camera and a frame camera on the same
mount, 240x180) into a temporary folder and draws 20 ms of events before the frame's
instant, each in its instance's colour (noise events white), next to the frame's
instance PNG in the same colours.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import cv2
import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from roslan.config.sim import SimConfig
from roslan.pipeline.run import run_simulation

RES = [240, 180]
JOB = {
    "scene": "warehouse",
    "trajectory": {
        "k": 0.5,
        "initial": {"position": [-2.0, 1.0, 2.0], "rpy": [0.0, 0.2, -0.3], "descent_rate": 4.0},
        "hold": 0.0,
    },
    "output": {"labels": True, "formats": ["ros2"], "workers": 0},
    "sensors": [
        {"type": "event_camera", "name": "dvs", "rate": 10.0, "resolution": RES},
        {"type": "camera", "name": "cam", "rate": 10.0, "resolution": RES},
    ],
}


def colours(ids: np.ndarray) -> np.ndarray:
    """A fixed colour per instance id (0: black)."""
    rng = np.random.default_rng(0)
    table = rng.uniform(0.25, 1.0, size=(int(ids.max()) + 1, 3))
    table[0] = 0.0
    return table[ids]


def main(out: Path) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        run = Path(tmp) / "run"
        run_simulation(SimConfig.model_validate(JOB), run, quiet=True, overview=False)
        k = 3  # the frame at 0.3 s
        t_ns = int(k * 1e8)
        inst = cv2.imread(str(run / "cam" / "instance" / f"{k:08d}.png"), cv2.IMREAD_UNCHANGED)
        with h5py.File(run / "events.h5") as f:
            t = f["events/t"][:] * 1000
            sel = (t > t_ns - 20_000_000) & (t <= t_ns)
            x, y = f["events/x"][:][sel], f["events/y"][:][sel]
            label = f["events/label"][:][sel]
    top = int(max(int(inst.max()), int((label >> 16).max()))) + 1
    ids_ev = (label >> 16).astype(np.int64)
    frame = np.zeros((RES[1], RES[0], 3))
    c = colours(np.concatenate([ids_ev, [top]]))[:-1]
    c[(label & 0xFFFF) == 1] = 1.0  # noise: white
    frame[y, x] = c
    fig, ax = plt.subplots(1, 2, figsize=(9.6, 3.8))
    ax[0].imshow(frame, interpolation="nearest")
    ax[0].set_title(f"events/label: 20 ms of events before t = {t_ns * 1e-9:.1f} s")
    ax[1].imshow(
        colours(np.where(inst > 0, inst, 0).astype(np.int64) % (top + 1)), interpolation="nearest"
    )
    ax[1].set_title("frame camera: instance/00000003.png")
    for a in ax:
        a.set_xticks([])
        a.set_yticks([])
    fig.suptitle("Same instance, same colour: event labels and the frame camera's instance image")
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("docs/img/labels.png"))
