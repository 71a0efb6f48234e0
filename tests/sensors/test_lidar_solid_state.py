"""Solid-state (Livox-like) LiDAR: rosette inside the FOV, non-repetitive, timing, ranges."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from range_helpers import FakeContext, LinearTrajectory, run_sensor, scene, vertical_wall_x
from roslan.config.base import validate_model
from roslan.errors import ConfigError
from roslan.sensors.beams import SolidStateLidar, SolidStateLidarConfig

WALL_X = 6.0


def _sensor(**kw: object) -> SolidStateLidar:
    cfg = validate_model(
        SolidStateLidarConfig, {"type": "solid_state_lidar", "name": "livox", **kw}, "sim.yaml"
    )
    return SolidStateLidar(cfg)


def _frames(tmp_path: Path, sensor: SolidStateLidar, n: int) -> list[np.ndarray]:
    ctx = FakeContext(scene(vertical_wall_x(WALL_X)), LinearTrajectory((0.0, 0.0, 0.0)), tmp_path)
    caster = ctx.raycaster()
    rng = ctx.rng("livox")
    period = round(1e9 / sensor.config.rate)
    return [sensor.scan(ctx.trajectory, caster, k * period, rng) for k in range(n)]


def test_mid40_frame_inside_circular_fov_and_on_the_wall(tmp_path: Path) -> None:
    (pts,) = _frames(tmp_path, _sensor(noise_sigma=0.0), 1)
    assert pts.shape[0] == 10_000  # 100k points/s at 10 Hz, all on the wall
    np.testing.assert_allclose(pts["x"], WALL_X, atol=1e-4)
    r = np.sqrt(pts["x"] ** 2 + pts["y"] ** 2 + pts["z"] ** 2)
    off_axis = np.degrees(np.arccos(np.clip(pts["x"] / r, -1, 1)))
    assert off_axis.max() <= 38.4 / 2 + 1e-3
    assert off_axis.max() > 38.4 / 2 - 0.5  # the pattern reaches the edge
    t = pts["time"].astype(np.float64)
    assert t.min() >= 0.0
    assert t.max() < 0.1
    np.testing.assert_allclose(np.diff(t), 1e-5, atol=1.5e-8)  # 1 / point_rate (float32)


def test_rosette_is_not_repetitive(tmp_path: Path) -> None:
    frames = _frames(tmp_path, _sensor(noise_sigma=0.0), 3)

    def cells(p: np.ndarray) -> set[tuple[int, int]]:
        # directions binned on a 0.25 deg grid of the wall
        ay = np.degrees(np.arctan2(p["y"], p["x"]))
        az = np.degrees(np.arctan2(p["z"], p["x"]))
        return set(
            zip((ay // 0.25).astype(int).tolist(), (az // 0.25).astype(int).tolist(), strict=True)
        )

    c0 = cells(frames[0])
    c01 = c0 | cells(frames[1])
    c012 = c01 | cells(frames[2])
    # each new frame covers directions the previous ones did not
    assert len(c01) > 1.3 * len(c0)
    assert len(c012) > len(c01)
    assert not np.allclose(frames[0]["y"][:100], frames[1]["y"][:100], atol=1e-3)


def test_avia_lines_and_elliptic_fov(tmp_path: Path) -> None:
    (pts,) = _frames(tmp_path, _sensor(preset="avia", noise_sigma=0.0), 1)
    assert pts.shape[0] == 24_000
    assert sorted(np.unique(pts["ring"]).tolist()) == list(range(6))
    r = np.sqrt(pts["x"] ** 2 + pts["y"] ** 2 + pts["z"] ** 2)
    theta = np.arccos(np.clip(pts["x"] / r, -1, 1))
    lat = np.hypot(pts["y"], pts["z"])
    u = theta * pts["y"] / lat
    v = theta * pts["z"] / lat
    half_h, half_v = math.radians(70.4 / 2), math.radians(77.2 / 2)
    assert ((u / half_h) ** 2 + (v / half_v) ** 2).max() <= 1 + 1e-4
    # six instants share each firing time
    assert np.unique(pts["time"]).shape[0] == 4000


def test_stream_and_files(tmp_path: Path) -> None:
    s = _sensor()
    ctx = FakeContext(
        scene(vertical_wall_x(WALL_X)), LinearTrajectory((0.0, 0.0, 0.0), duration=0.3), tmp_path
    )
    msgs = run_sensor(s, ctx)
    assert [m.t_ns for m in msgs] == [0, 100_000_000, 200_000_000]
    assert {m.topic for m in msgs} == {"/livox/lidar"}
    assert len(list((tmp_path / "lidar" / "livox").glob("*.npz"))) == 3


@pytest.mark.parametrize(
    ("data", "key"),
    [
        ({"preset": "horizon"}, "preset"),
        ({"fov_deg": [200.0, 30.0]}, "fov_deg"),
        ({"point_rate": -5.0}, "point_rate"),
        ({"prism_rpm": [7294.0, 0.0]}, "prism_rpm"),
        ({"noise_sigma": -1.0}, "noise_sigma"),
        ({"min_range": 10.0, "max_range": 5.0}, "min_range"),
    ],
)
def test_bad_config_names_the_key(data: dict[str, object], key: str) -> None:
    with pytest.raises(ConfigError) as err:
        _sensor(**data)
    assert key in str(err.value)
    assert "sim.yaml" in str(err.value)
