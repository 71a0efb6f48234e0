"""A 12.8 M-point LiDAR (128 rings x 100 000 azimuth steps, the largest allowed) runs
within 3 GB of RSS, and the chunked scan is the one-shot scan."""

from __future__ import annotations

import contextlib
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import psutil  # type: ignore[import-untyped]
import pytest
import yaml

from roslan.config.base import validate_model
from roslan.config.sim import SimConfig
from roslan.sensors.beams import lidar as lidar_mod
from roslan.sensors.beams.lidar import Lidar, LidarConfig

RSS_LIMIT = 3 << 30
"""Bytes: the run's processes together (main and worker) stay below this at every sample."""

RINGS, STEPS = 128, 100_000


def _hover(path: Path, seconds: float, z: float = 1.5) -> None:
    """base_link held still at the warehouse's centre, ``z`` m up, for ``seconds``."""
    t = np.arange(0.0, seconds + 1e-9, 0.01)
    still = np.tile([0.0, 0.0, z, 0.0, 0.0, 0.0, 1.0], (t.size, 1))
    np.savetxt(path, np.column_stack([t, still]), "%.9f")


def _peak_tree_rss(cmd: list[str], cwd: Path) -> tuple[int, int, str]:
    """Run ``cmd``; (exit status, peak summed RSS of it and its children, stderr)."""
    with subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE) as p:
        root = psutil.Process(p.pid)
        peak = 0
        while p.poll() is None:
            total = 0
            with contextlib.suppress(psutil.Error):  # the processes come and go
                for q in [root, *root.children(recursive=True)]:
                    with contextlib.suppress(psutil.Error):
                        total += q.memory_info().rss
            peak = max(peak, total)
            time.sleep(0.02)
        err = p.stderr.read().decode() if p.stderr else ""
    return p.returncode, peak, err


@pytest.mark.slow
def test_a_12_8_million_point_lidar_runs_within_3_gb(tmp_path: Path) -> None:
    _hover(tmp_path / "hover.txt", 0.25)  # two whole turns at 10 Hz
    elevations = np.round(np.linspace(-30.0, 30.0, RINGS), 3).tolist()
    job = {
        "trajectory": {"file": "hover.txt"},
        "scene": "warehouse",  # enclosed: every beam returns
        "sensors": [
            {
                "type": "lidar",
                "name": "dense",
                "preset": "custom",
                "elevations_deg": elevations,
                "azimuth_steps": STEPS,
                "rate": 10.0,
            }
        ],
    }
    (tmp_path / "job.yaml").write_text(yaml.safe_dump(job))
    roslan = [sys.executable, "-c", "from roslan.cli import main; raise SystemExit(main())"]
    rc, peak, err = _peak_tree_rss([*roslan, "simulate", "job.yaml", "-o", "out"], tmp_path)
    assert rc == 0, err
    assert peak < RSS_LIMIT, f"peak RSS {peak / 1e9:.2f} GB"
    out = tmp_path / "out"
    listing = (out / "lidar" / "dense" / "timestamps.txt").read_text().splitlines()
    assert [line.split()[1] for line in listing] == ["dense/000000.npz", "dense/000001.npz"]
    with np.load(out / "lidar" / "dense" / "000001.npz") as z:
        x, y, zz, ring, t = z["x"], z["y"], z["z"], z["ring"], z["time"]
    # enclosed: nearly every one of the 12.8 M beams returns (a few pass beyond 100 m)
    assert 0.95 * RINGS * STEPS <= x.shape[0] <= RINGS * STEPS
    assert np.all(np.diff(t) >= 0)  # firing order
    # the first column (1 us) fires its rings along +x, each at its ring's elevation
    first = t < 0.1 / STEPS
    assert first.sum() >= RINGS // 2
    assert (x[first] > 0).all()
    assert np.allclose(y[first], 0.0, atol=1e-3 * np.abs(x[first]).max())
    el = np.degrees(np.arctan2(zz[first], np.hypot(x[first], y[first])))
    assert np.allclose(el, np.asarray(elevations)[ring[first]], atol=0.01)
    print(f"peak RSS of the run's processes: {peak / 2**30:.2f} GiB")


def _small_lidar(**over: Any) -> Lidar:
    cfg = LidarConfig.model_validate(
        {
            "type": "lidar",
            "name": "lid",
            "preset": "custom",
            "elevations_deg": [-20.0, -5.0, 0.0, 7.0, 15.0],
            "azimuth_steps": 1000,
            "rate": 10.0,
            "noise_sigma": 0.01,
            "dropout": 0.2,
            **over,
        }
    )
    return Lidar(cfg)


@pytest.mark.parametrize("organized", [False, True])
def test_a_scan_cast_in_chunks_is_the_scan_cast_whole(
    organized: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    from roslan.render.raycast import get_raycaster
    from roslan.scene import load_scene
    from roslan.trajectory.spline import make_trajectory

    cfg = validate_model(SimConfig, {"scene": "warehouse"}, "job.yaml")
    traj = make_trajectory(cfg.trajectory)
    caster = get_raycaster(load_scene("warehouse"))
    whole = _small_lidar(organized=organized)
    assert whole.chunk_columns >= 1000  # one chunk
    ref = whole.scan(traj, caster, 1_000_000_000, np.random.default_rng(3))
    monkeypatch.setattr(lidar_mod, "SCAN_CHUNK_BEAMS", 5 * 37)  # 37 columns a chunk
    chunked = _small_lidar(organized=organized)
    assert chunked.chunk_columns == 37
    got = chunked.scan(traj, caster, 1_000_000_000, np.random.default_rng(3))
    assert got.dtype == ref.dtype
    assert got.shape == ref.shape
    for k in ref.dtype.names or ():  # the same numbers, NaN (no return) where they were
        assert np.array_equal(got[k], ref[k], equal_nan=k != "ring"), k
    if organized:
        assert np.isnan(ref["x"]).sum() > 0  # the dropouts: NaN rows kept in place
