"""Sonar, altimeter and 2-D laser: cone minimum, box heights, box-room walls, REP 117."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from range_helpers import FakeContext, LinearTrajectory, box, plane, run_sensor, scene
from roslan.config.base import validate_model
from roslan.errors import ConfigError
from roslan.io.messages import Flavor, MessageStore
from roslan.sensors.beams import Altimeter, AltimeterConfig, Laser, LaserConfig, Sonar, SonarConfig


def _sonar(**kw: object) -> Sonar:
    return Sonar(validate_model(SonarConfig, {"type": "sonar", "name": "sonar", **kw}, "sim.yaml"))


def _altimeter(**kw: object) -> Altimeter:
    data = {"type": "altimeter", "name": "alt", **kw}
    return Altimeter(validate_model(AltimeterConfig, data, "sim.yaml"))


def _read(sensor: Sonar | Altimeter, ctx: FakeContext, t_ns: list[int]) -> np.ndarray:
    return sensor.read(ctx.trajectory, ctx.raycaster(), np.asarray(t_ns, np.int64), ctx.rng("r"))


def test_sonar_cone_returns_nearest_surface_off_axis(tmp_path: Path) -> None:
    # sonar 3 m above the ground, looking down; a 2 m tall box whose edge is 0.15 m off axis
    fov = math.radians(30.0)
    sc = scene(plane(), box((0.15, -1.0, 0.0), (1.5, 1.0, 2.0)))
    ctx = FakeContext(sc, LinearTrajectory((0.0, 0.0, 3.0)), tmp_path)
    sonar = _sonar(axis=(0, 0, -1), field_of_view=fov, noise_sigma=0.0, max_range=5.0)
    (r,) = _read(sonar, ctx, [0])
    # nearest box point inside the cone: its top edge at 1 m below, 0.15 m aside
    nearest = math.hypot(1.0, 0.15)
    edge = 1.0 / math.cos(fov / 2)
    assert nearest - 1e-6 <= r <= edge + 1e-6
    # a single ray along the axis (no cone) misses the box and sees the ground
    axis_only = _sonar(axis=(0, 0, -1), field_of_view=fov, rings=0, noise_sigma=0.0)
    (r0,) = _read(axis_only, ctx, [0])
    assert r0 == pytest.approx(3.0, abs=1e-5)
    # outside the cone the box is ignored
    # (a 4 deg cone spreads to 0.105 m at the ground, 3 m away: it misses the box side)
    narrow = _sonar(axis=(0, 0, -1), field_of_view=math.radians(4.0), noise_sigma=0.0)
    (r1,) = _read(narrow, ctx, [0])
    assert r1 > 2.9


def test_altimeter_over_a_box_measures_its_height(tmp_path: Path) -> None:
    height, box_h = 2.0, 0.8
    sc = scene(plane(), box((-0.5, -0.5, 0.0), (0.5, 0.5, box_h)))
    traj = LinearTrajectory((-2.0, 0.0, height), v=(4.0, 0.0, 0.0), duration=1.0)
    ctx = FakeContext(sc, traj, tmp_path)
    alt = _altimeter(noise_sigma=0.0, rate=100.0)
    msgs = run_sensor(alt, ctx)
    t = np.array([m.t_ns for m in msgs]) * 1e-9
    r = np.array([m.build(MessageStore(Flavor.ROS2)).range for m in msgs])
    x = -2.0 + 4.0 * t
    over = np.abs(x) < 0.45
    off = np.abs(x) > 0.55
    assert over.sum() > 10
    np.testing.assert_allclose(r[over], height - box_h, atol=1e-5)
    np.testing.assert_allclose(r[off], height, atol=1e-5)
    # the dataset file holds the same readings
    rows = np.loadtxt(tmp_path / "range_alt.txt")
    np.testing.assert_allclose(rows[:, 0], t, atol=1e-9)
    np.testing.assert_allclose(rows[:, 1], r, atol=1e-6)


def test_range_messages_and_rep117(tmp_path: Path) -> None:
    sc = scene(plane(z=0.0))
    # 0.01 m above the ground: closer than min_range -> -inf; looking up: nothing -> +inf
    ctx = FakeContext(sc, LinearTrajectory((0.0, 0.0, 0.01)), tmp_path)
    assert _read(_altimeter(noise_sigma=0.0), ctx, [0])[0] == -math.inf
    assert _read(_altimeter(axis=(0, 0, 1)), ctx, [0])[0] == math.inf
    high = FakeContext(sc, LinearTrajectory((0.0, 0.0, 50.0)), tmp_path)
    assert _read(_altimeter(), high, [0])[0] == math.inf  # beyond 12 m max range
    # noise: spread matches sigma, readings stay within the limits
    mid = FakeContext(sc, LinearTrajectory((0.0, 0.0, 2.0)), tmp_path)
    r = _read(_altimeter(noise_sigma=0.05), mid, list(range(0, 2000 * 10**6, 10**6)))
    assert abs(r.mean() - 2.0) < 0.01
    assert 0.04 < r.std() < 0.06
    # message fields
    for sensor, kind in ((_sonar(), 0), (_altimeter(), 1)):
        msgs = run_sensor(
            sensor, FakeContext(sc, LinearTrajectory((0, 0, 1.0), duration=0.1), tmp_path)
        )
        for flavor in Flavor:
            store = MessageStore(flavor)
            msg = msgs[0].build(store)
            raw = store.serialize(msg, msgs[0].msgtype)
            back = (
                store.typestore.deserialize_ros1(raw, msgs[0].msgtype)
                if flavor is Flavor.ROS1
                else store.typestore.deserialize_cdr(raw, msgs[0].msgtype)
            )
            assert back.radiation_type == kind
            assert back.field_of_view == pytest.approx(sensor.config.field_of_view)
            assert back.header.frame_id == sensor.config.name
    # the published frame's x axis is the beam (sensor_msgs/Range convention)
    (tf,) = _altimeter().static_transforms()
    np.testing.assert_allclose(tf.T[:3, :3] @ [1.0, 0.0, 0.0], [0.0, 0.0, -1.0], atol=1e-12)


def _wall_distance(
    p: np.ndarray, ang: np.ndarray, lo: tuple[float, float], hi: tuple[float, float]
) -> np.ndarray:
    """Distance from p along horizontal unit directions at angles ang to the room's walls."""
    dx, dy = np.cos(ang), np.sin(ang)
    with np.errstate(divide="ignore"):
        tx = np.where(dx > 0, (hi[0] - p[0]) / dx, (lo[0] - p[0]) / dx)
        ty = np.where(dy > 0, (hi[1] - p[1]) / dy, (lo[1] - p[1]) / dy)
    return np.minimum(np.abs(tx), np.abs(ty))


def test_laser_scan_in_a_box_room_matches_the_walls(tmp_path: Path) -> None:
    lo, hi = (-3.0, -2.0), (5.0, 4.0)
    room = box((lo[0], lo[1], 0.0), (hi[0], hi[1], 3.0), inward=True)
    p = np.array([0.5, 0.25, 1.0])
    yaw = 0.3
    ctx = FakeContext(scene(room), LinearTrajectory(tuple(p), yaw0=yaw), tmp_path)
    laser = Laser(
        validate_model(LaserConfig, {"type": "laser", "name": "laser", "noise_sigma": 0.0})
    )
    ranges, inten = laser.scan(ctx.trajectory, ctx.raycaster(), 0, ctx.rng("l"))
    n = math.floor(math.radians(270) / math.radians(0.25) + 1e-9) + 1
    assert ranges.shape == (n,)
    ang = -math.radians(135) + np.arange(n) * math.radians(0.25)
    expected = _wall_distance(p, ang + yaw, lo, hi)
    np.testing.assert_allclose(ranges, expected, rtol=1e-5, atol=1e-5)
    assert (inten > 0).all()
    # LaserScan message: REP 117 +inf where the room is beyond range_max
    short = Laser(validate_model(LaserConfig, {"type": "laser", "name": "l2", "range_max": 3.0}))
    msgs = run_sensor(
        short,
        FakeContext(scene(room), LinearTrajectory(tuple(p), yaw0=yaw, duration=0.075), tmp_path),
    )
    assert [m.t_ns for m in msgs] == [0, 25_000_000, 50_000_000]
    msg = msgs[0].build(MessageStore(Flavor.ROS1))
    far = expected > 3.0
    assert np.isposinf(np.asarray(msg.ranges)[far]).all()
    assert np.isfinite(np.asarray(msg.ranges)[~far]).all()
    assert msg.angle_max == pytest.approx(ang[-1])
    assert msg.time_increment == pytest.approx(math.radians(0.25) / (2 * math.pi * 40.0))
    lines = (tmp_path / "laser_l2.txt").read_text().splitlines()
    assert len(lines) == 3  # one row per scan, no header line
    assert len(lines[1].split()) == n + 1


@pytest.mark.parametrize("n_beams", [360, 20])  # 20: fewer beams than one knot holds
def test_moving_laser_uses_each_beams_instant(tmp_path: Path, n_beams: int) -> None:
    """A scan at 5 Hz while flying at 5 m/s through the room: each beam hits the wall where
    the sensor was at its own instant (the whole 360 deg turn, and a 20-beam fan whose
    beams all fall in one knot of the firing grid)."""
    lo, hi = (-10.0, -10.0), (10.0, 10.0)
    room = box((lo[0], lo[1], 0.0), (hi[0], hi[1], 3.0), inward=True)
    v = np.array([5.0, 0.0, 0.0])
    traj = LinearTrajectory((0.0, 0.0, 1.0), v=tuple(v))
    a0 = -math.pi if n_beams == 360 else -math.radians(10.0)
    cfg = {"type": "laser", "name": "l", "noise_sigma": 0.0, "rate": 5.0, "range_max": 40.0,
           "angle_min": a0, "angle_max": a0 + math.radians(n_beams - 1),
           "angle_increment": math.radians(1.0)}  # fmt: skip
    laser = Laser(validate_model(LaserConfig, cfg))
    ranges, _ = laser.scan(
        traj, FakeContext(scene(room), traj, tmp_path).raycaster(), 0, np.random.default_rng(0)
    )
    n = ranges.shape[0]
    assert n == n_beams
    ang = a0 + np.arange(n) * math.radians(1.0)
    t = np.arange(n) * laser.config.beam_time
    assert t[-1] > 0.18 * n / 360  # the beams span their share of the 0.2 s turn
    pos = np.array([0.0, 0.0, 1.0]) + t[:, None] * v
    expected = np.array([_wall_distance(pos[i], ang[i : i + 1], lo, hi)[0] for i in range(n)])
    np.testing.assert_allclose(ranges, expected, atol=1e-4)
    one_pose = _wall_distance(np.zeros(3), ang, lo, hi)  # every beam from the first pose
    assert np.abs(one_pose - ranges).max() > 0.5 * n / 360


@pytest.mark.parametrize(
    ("factory", "data", "key"),
    [
        (_sonar, {"noise_sigma": -0.1}, "noise_sigma"),
        (_sonar, {"min_range": 5.0, "max_range": 1.0}, "min_range"),
        (_sonar, {"field_of_view": 4.0}, "field_of_view"),
        (_altimeter, {"axis": (0, 0, 0)}, "axis"),
        (_altimeter, {"dropout": 1.0}, "dropout"),
        (_altimeter, {"beam": 1.0}, "beam"),
    ],
)
def test_bad_range_config_names_the_key(factory: object, data: dict[str, object], key: str) -> None:
    with pytest.raises(ConfigError) as err:
        factory(**data)  # type: ignore[operator]
    assert key in str(err.value)
    assert "sim.yaml" in str(err.value)


@pytest.mark.parametrize(
    ("data", "key"),
    [
        ({"angle_min": 1.0, "angle_max": -1.0}, "angle_min"),
        ({"angle_increment": -0.1}, "angle_increment"),
        ({"range_min": -1.0}, "range_min"),
        ({"time_increment": 0.01}, "time_increment"),
        ({"noise_sigma": -0.01}, "noise_sigma"),
    ],
)
def test_bad_laser_config_names_the_key(data: dict[str, object], key: str) -> None:
    with pytest.raises(ConfigError) as err:
        validate_model(LaserConfig, {"type": "laser", "name": "l", **data}, "sim.yaml")
    assert key in str(err.value)


def test_range_readings_ask_for_the_scene_at_their_instants(tmp_path: Path) -> None:
    # every reading's rays carry its own trajectory time (Scene.at(t), roslan.scene.pose)
    ctx = FakeContext(scene(plane()), LinearTrajectory((0.0, 0.0, 3.0)), tmp_path)
    caster = ctx.raycaster()
    seen: list[np.ndarray] = []

    class Recording:
        def cast(self, o: np.ndarray, d: np.ndarray, r: float, *, t: np.ndarray) -> object:
            seen.append(np.asarray(t))
            return caster.cast(o, d, r, t=t)

    sonar = _sonar(axis=(0, 0, -1), noise_sigma=0.0, max_range=5.0)
    t_ns = np.array([0, 250_000_000, 1_000_000_000], np.int64)
    r = sonar.read(ctx.trajectory, Recording(), t_ns, ctx.rng("r"))  # type: ignore[arg-type]
    np.testing.assert_allclose(r, 3.0, atol=1e-5)
    (t,) = seen
    n_r = t.shape[0] // 3
    assert n_r >= 1
    np.testing.assert_array_equal(t, np.repeat(t_ns * 1e-9, n_r))
