"""The pictures on a real (tiny) ``roslan simulate`` run: the readers meet the files the
sensors actually write. The event camera is left out: on the shared 2-core machine it
took minutes even at 32 x 24 px; its files are covered by the synthetic OUTDIR of
test_plots.py, written in the documented layout."""

from __future__ import annotations

from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

CONFIG = {
    "trajectory": {
        "k": 0.5,
        "initial": {"position": [-1.0, 0.3, 1.0], "rpy": [0.0, 0.05, 0.1], "descent_rate": 1.0},
    },
    "scene": "empty",
    "seed": 0,
    "output": {"formats": ["ros1"]},
    "sensors": [
        {"type": "imu", "name": "imu", "rate": 100.0, "topic": "/imu"},
        {"type": "camera", "name": "cam", "rate": 5.0, "topic": "/cam", "resolution": [32, 24]},
        {"type": "lidar", "name": "velodyne", "rate": 5.0, "topic": "/velodyne", "preset": "vlp16"},
    ],
}


@pytest.mark.slow
def test_pictures_of_a_real_run(tmp_path: Path) -> None:
    from roslan.config.base import validate_model
    from roslan.config.sim import SimConfig
    from roslan.pipeline import run_simulation
    from roslan.plots.imu import plot_imu
    from roslan.plots.lidar import plot_lidar
    from roslan.plots.overview import write_overview
    from roslan.plots.preview import make_preview
    from roslan.plots.trajectory import plot_trajectory

    out = tmp_path / "run"
    config = validate_model(SimConfig, CONFIG, "test")
    run_simulation(config, out, quiet=True)
    for png in (
        plot_trajectory(out),
        plot_lidar(out),
        plot_imu(out),
        write_overview(out, tmp_path / "overview.png"),
    ):
        img = np.asarray(iio.imread(png))[..., :3]
        assert img.shape[0] > 500
        assert np.any(img < 235, axis=-1).mean() > 0.03
    info = make_preview(out, tmp_path / "p.mp4", fps=5, panel_width=160)
    frames = iio.imread(info.path, index=None)
    assert frames.shape[0] == info.frames > 5
    assert frames[info.frames // 2].std() > 10
