"""``roslan plot lidar`` and the overview's LiDAR panel: the first *configured* LiDAR is
drawn (not the alphabetically first), every return lies inside the axes however far it
is, the z label reads upright, and the colourbar has its own room (it covers no axes)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import roslan.plots.lidar as lidar_plot
from roslan.rundir.readers import find_lidar

N = 400


def _scan(far: float, rings: bool) -> dict[str, np.ndarray]:
    """Mostly ground returns within 3 m, plus walls out to ``far`` m, up to 6 m high."""
    rng = np.random.default_rng(0)
    a = rng.uniform(0, 2 * np.pi, N)
    r = np.where(np.arange(N) % 20 == 0, far, rng.uniform(0.5, 3.0, N))
    z = np.where(np.arange(N) % 20 == 0, rng.uniform(0.0, 6.0, N), -1.0)
    ring = (np.arange(N) % 16) if rings else np.zeros(N)
    return {
        "x": (r * np.cos(a)).astype(np.float32),
        "y": (r * np.sin(a)).astype(np.float32),
        "z": z.astype(np.float32),
        "intensity": np.full(N, 0.5, np.float32),
        "ring": ring.astype(np.uint16),
        "time": np.zeros(N, np.float32),
    }


def _run(out: Path) -> Path:
    """An OUTDIR with two LiDARs, configured 'zlidar' first, then 'alidar' (rings all 0)."""
    sensors = [
        {"type": "lidar", "name": "zlidar", "rate": 10.0},
        {"type": "solid_state_lidar", "name": "alidar", "rate": 10.0},
    ]
    for cfg, far in zip(sensors, (30.0, 12.0), strict=True):
        folder = out / "lidar" / cfg["name"]
        folder.mkdir(parents=True)
        np.savez(folder / "000000.npz", stamp=np.int64(0), **_scan(far, cfg["type"] == "lidar"))
        (folder / "timestamps.txt").write_text(f"0.100000000 {cfg['name']}/000000.npz\n")
    (out / "run.json").write_text(json.dumps({"complete": True, "config": {"sensors": sensors}}))
    return out


def test_the_first_configured_lidar_comes_first(tmp_path: Path) -> None:
    run = _run(tmp_path / "run")
    assert [s.name for s in find_lidar(run, "x")] == ["zlidar", "alidar"]
    # before run.json exists (simulate draws the overview first): extrinsics.yaml's order
    (run / "run.json").unlink()
    (run / "calib").mkdir()
    (run / "calib" / "extrinsics.yaml").write_text(
        "sensors:\n  zlidar: {type: lidar}\n  alidar: {type: solid_state_lidar}\n"
    )
    assert [s.name for s in find_lidar(run, "x")] == ["zlidar", "alidar"]


def _drawn(run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, **kw: Any) -> Any:
    figs: list[Any] = []
    save = lidar_plot.save_figure

    def keep(fig: Any, out: Path, **kwargs: Any) -> Path:
        figs.append(fig)
        return save(fig, out, **kwargs)

    monkeypatch.setattr(lidar_plot, "save_figure", keep)
    lidar_plot.plot_lidar(run, tmp_path / "l.png", **kw)
    (fig,) = figs
    return fig


@pytest.mark.parametrize("sensor", ["zlidar", "alidar"])
def test_plot_lidar_keeps_every_point_and_its_colourbar_apart(
    sensor: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    run = _run(tmp_path / "run")
    fig = _drawn(run, tmp_path, monkeypatch, sensor=sensor)
    ax3 = next(a for a in fig.axes if a.name == "3d")
    ax2 = next(a for a in fig.axes if a.get_title().startswith("Bird"))
    cax = next(a for a in fig.axes if a not in (ax3, ax2))
    xyz = find_lidar(run, "x")[0 if sensor == "zlidar" else 1].read(0).xyz
    far = float(np.abs(xyz[:, :2]).max())
    assert far > 10.0
    for ax in (ax3, ax2):  # the far walls are not cut off
        lo, hi = ax.get_xlim()
        assert lo <= -far
        assert hi >= far
        lo, hi = ax.get_ylim()
        assert lo <= -far
        assert hi >= far
    lo, hi = ax3.get_zlim()
    assert lo <= float(xyz[:, 2].min())
    assert hi >= float(xyz[:, 2].max())
    # the z label is upright, not mirrored by the view angle
    assert ax3.zaxis.label.get_rotation() == 90
    assert ax3.zaxis.get_rotate_label(ax3.zaxis.label.get_text()) is False
    # the colourbar overlaps neither axes
    fig.canvas.draw()
    box = cax.get_position()
    for ax in (ax3, ax2):
        assert not box.overlaps(ax.get_position()), ax
    # a LiDAR without rings (solid-state: all 0) is coloured by height, not by ring
    assert ("ring" in cax.get_ylabel()) == (sensor == "zlidar")
