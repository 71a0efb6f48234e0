"""roslan.env.LandingEnv: Gymnasium conformance, determinism, async vectorization, actions,
bad configs, and recorded episodes read by the same readers as simulate's runs."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import pytest
import yaml

from env_helpers import tiny_config
from reader_helpers import evlib_events, mcap_topic_counts, ros1_topic_counts
from roslan.env import LandingEnv, make_policy
from roslan.env.episode import fly
from roslan.errors import ActionError, ConfigError

pytest.importorskip("roslan.render.gl")


def test_registered_ids_build_from_their_packaged_configs() -> None:
    for env_id, scene in (("roslan/Landing-v0", "warehouse"), ("roslan/Perching-v0", "refinery")):
        env = gymnasium.make(env_id)
        base = env.unwrapped
        assert isinstance(base, LandingEnv)
        assert base.base_config.scene == scene
        assert {"imu", "events"} <= set(base.observation_space.spaces)
        assert base.action_space.shape == (6,)
        env.close()


def test_passes_the_gymnasium_env_checker() -> None:
    from gymnasium.utils.env_checker import check_env

    env = LandingEnv(tiny_config(), render_mode="rgb_array")
    check_env(env, skip_render_check=False)
    env.close()


def _rollout(seed: int, steps: int = 12) -> list[dict[str, np.ndarray]]:
    env = LandingEnv(tiny_config())
    obs, info = env.reset(seed=seed)
    out = [obs]
    rng = np.random.default_rng(0)
    for _ in range(steps):
        action = rng.uniform(-1.0, 1.0, 6).astype(np.float32)
        obs, _, term, trunc, info = env.step(action)
        # the count image is the step's raw events (info) per pixel and polarity
        assert obs["events"].sum() == len(info["events"])
        out.append(obs)
        if term or trunc:
            break
    env.close()
    return out


def test_same_seed_and_actions_give_identical_observations() -> None:
    a, b = _rollout(5), _rollout(5)
    assert len(a) == len(b)
    for oa, ob in zip(a, b, strict=True):
        assert oa.keys() == ob.keys()
        for k in oa:
            np.testing.assert_array_equal(oa[k], ob[k])
    assert any(o["events"].sum() > 0 for o in a), "the event camera saw nothing"
    assert all(o["events"].dtype == np.float32 for o in a)
    c = _rollout(6)
    assert any(
        not np.array_equal(x["imu"], y["imu"]) for x, y in zip(a[1:], c[1:], strict=False)
    ), "another seed gave the same IMU noise"


def test_make_vec_async_runs_an_episode() -> None:
    envs = gymnasium.make_vec(
        "roslan/Landing-v0", num_envs=2, vectorization_mode="async", config=tiny_config()
    )
    try:
        envs.reset(seed=[1, 2])
        done = np.zeros(2, dtype=bool)
        for _ in range(100):  # zero command: the start's 2 m/s descent hits the ground
            _, _, term, trunc, _ = envs.step(np.zeros((2, 6), dtype=np.float32))
            done |= term | trunc
            if done.all():
                break
        assert done.all()
    finally:
        envs.close()


def test_actions_nan_raises_out_of_range_clips() -> None:
    env = LandingEnv(tiny_config())
    env.reset(seed=0)
    with pytest.raises(ActionError, match=r"action\[4\] \(q\) = nan"):
        env.step(np.array([0, 0, 0, 0, np.nan, 0], dtype=np.float32))
    env.reset(seed=0)
    with pytest.raises(ActionError, match=r"shape \(3,\)"):
        env.step(np.zeros(3))
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([500.0, 0, 0, 0, 0, 0]))
    assert info["clipped"]
    _, _, _, _, info = env.step(np.zeros(6))
    assert not info["clipped"]
    env.close()


def test_policy_context_is_the_episodes_goal_frame_and_action_bounds() -> None:
    env = LandingEnv(tiny_config())
    with pytest.raises(ActionError, match=r"policy_context\(\) before reset\(\)"):
        env.policy_context()
    _, info = env.reset(seed=4)
    ctx = env.policy_context()
    np.testing.assert_array_equal(ctx.R_world_goal, info["R_world_goal"])
    np.testing.assert_allclose(ctx.R_world_goal @ ctx.R_world_goal.T, np.eye(3), atol=1e-12)
    assert ctx.control_dt == pytest.approx(1.0 / env.metadata["render_fps"])
    high = env.action_space.high
    assert (ctx.max_acceleration, ctx.max_body_rate) == (float(high[0]), float(high[3]))
    assert ctx.config.seed == 4
    env.close()


@pytest.mark.parametrize(
    ("over", "key"),
    [
        ({"closed_loop": {"control_rate": 0.0}}, "closed_loop.control_rate"),
        ({"closed_loop": {"observation": {"events": "frames"}}}, "closed_loop.observation.events"),
        (
            {"closed_loop": {"dynamics": {"max_body_rate": -1}}},
            "closed_loop.dynamics.max_body_rate",
        ),
        (
            {"closed_loop": {"start_spread": {"rpy": [0.1, -0.1, 0.0]}}},
            "closed_loop.start_spread.rpy[1] = -0.1",
        ),
    ],
)
def test_bad_config_names_the_key(over: dict[str, Any], key: str) -> None:
    with pytest.raises(ConfigError, match=re.escape(key)):
        LandingEnv(tiny_config(**over))


def test_unknown_policy_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"unknown policy.*tau-state"):
        make_policy("tau-magic")
    with pytest.raises(ConfigError):
        fly(tiny_config(), "tau-magic", record=tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_an_unfinished_recorded_episode_leaves_no_outdir(tmp_path: Path) -> None:
    out = tmp_path / "out"
    env = LandingEnv(tiny_config(), record=out)
    env.reset(seed=0)
    for _ in range(3):
        env.step(np.zeros(6))
    env.close()
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_an_unrecorded_episode_creates_no_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Without ``record`` no file sink is attached: a whole episode (IMU, event camera
    with APS frames, optic flow and depth truth, a frame camera, LiDAR) creates nothing
    under TMPDIR nor in the working folder, and observes what the recorded episode does."""
    import tempfile

    cfg = tiny_config()
    cfg["sensors"][1].update(aps=True, optic_flow=True, depthmap=True, write_h5=True)
    cfg["sensors"] += [
        {"type": "camera", "name": "cam", "rate": 10.0, "resolution": [32, 24]},
        {"type": "lidar", "name": "lidar", "rate": 10.0, "preset": "vlp16", "azimuth_steps": 90},
    ]
    seen: dict[str, list[dict[str, Any]]] = {"rec": [], "quiet": []}

    def keep(into: str) -> Any:
        return lambda obs, info: seen[into].append({k: np.copy(v) for k, v in obs.items()})

    recorded = fly(cfg, "tau-state", seed=2, record=tmp_path / "rec", on_step=keep("rec"))
    assert (tmp_path / "rec" / "events.h5").is_file()
    quiet = tmp_path / "quiet"
    (quiet / "tmp").mkdir(parents=True)
    monkeypatch.setenv("TMPDIR", str(quiet / "tmp"))
    monkeypatch.setattr(tempfile, "tempdir", None)  # gettempdir() reads TMPDIR again
    monkeypatch.chdir(quiet)
    unrecorded = fly(cfg, "tau-state", seed=2, on_step=keep("quiet"))
    assert list(quiet.rglob("*")) == [quiet / "tmp"]
    assert unrecorded == recorded
    assert len(seen["quiet"]) == len(seen["rec"]) > 10
    assert any(np.any(o["events"]) for o in seen["rec"])
    for a, b in zip(seen["rec"], seen["quiet"], strict=True):
        assert a.keys() == b.keys()
        for k in a:
            np.testing.assert_array_equal(a[k], b[k], err_msg=k)


@pytest.fixture(scope="module")
def flown(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``roslan fly CONFIG --policy tau-state -o OUT --seed 3`` on the tiny config."""
    from roslan.cli.app import main

    folder = tmp_path_factory.mktemp("fly")
    cfg = folder / "tiny.yaml"
    cfg.write_text(yaml.safe_dump(tiny_config()))
    out = folder / "out"
    assert (
        main(["fly", str(cfg), "--policy", "tau-state", "-o", str(out), "--seed", "3", "--quiet"])
        == 0
    )
    return out


def test_fly_writes_episode_json(flown: Path) -> None:
    ep = json.loads((flown / "episode.json").read_text())
    assert ep["policy"] == "tau-state"
    assert ep["seed"] == 3
    assert ep["reason"] == "touchdown"
    assert ep["success"] is True
    for key in (
        "touchdown_time",
        "touchdown_vertical_speed",
        "touchdown_horizontal_speed",
        "position_error",
        "heading_error",
    ):
        assert isinstance(ep[key], float), key
    assert ep["touchdown_vertical_speed"] <= 0.2
    assert ep["touchdown_time"] == pytest.approx(1.0, abs=0.05)
    run = json.loads((flown / "run.json").read_text())
    assert run["complete"] is True
    assert run["config"]["seed"] == 3
    assert "episode.json" in run["files"]  # what --overwrite may replace
    readme = (flown / "README.md").read_text()
    row = next(ln for ln in readme.splitlines() if ln.startswith("| `episode.json` |"))
    assert "policy, seed, success, reason" in row


def test_fly_outdir_is_read_by_rosbag_mcap_and_evlib(flown: Path, tmp_path: Path) -> None:
    run = json.loads((flown / "run.json").read_text())
    expected = {t: v["messages"] for t, v in run["topics"].items()}
    rows = ros1_topic_counts(flown / "landing.bag", tmp_path)
    assert {t: n for t, (_, n) in rows.items()} == expected
    assert rows["/imu"][0] == "sensor_msgs/Imu"
    assert mcap_topic_counts(flown / "landing_ros2") == expected
    df = evlib_events(flown / "events.h5")
    assert df.height > 0
    assert int(df["x"].max()) < 64
    assert int(df["y"].max()) < 48
    for name in ("groundtruth.txt", "imu.txt", "trajectory.csv", "README.md", "overview.png"):
        assert (flown / name).is_file(), name


def test_fly_cli_bad_config_names_the_key_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from roslan.cli.app import main

    bad = tmp_path / "bad.yaml"
    bad.write_text("closed_loop:\n  control_rate: -5\n")
    out = tmp_path / "out"
    assert main(["fly", str(bad), "--policy", "tau-state", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{bad}: closed_loop.control_rate = -5" in err
    assert not out.exists()


def test_fly_cli_offers_every_packaged_policy() -> None:
    from roslan.cli.fly import POLICY_NAMES
    from roslan.env import POLICIES

    assert sorted(POLICY_NAMES) == sorted(POLICIES)


def test_voxel_observation_holds_the_steps_events() -> None:
    env = LandingEnv(tiny_config(closed_loop={"observation": {"events": "voxel", "voxel_bins": 3}}))
    assert env.observation_space["events"].shape == (3, 48, 64)
    env.reset(seed=1)
    seen = 0
    for _ in range(5):
        obs, _, _, _, info = env.step(np.zeros(6))
        ev = info["events"]
        assert obs["events"].sum() == pytest.approx(float(np.sum(ev.p)), abs=1e-2)
        assert obs in env.observation_space
        seen += len(ev)
    assert seen > 0
    env.close()


def test_range_and_laser_observations_are_the_steps_latest_readings() -> None:
    """A downward sonar at the control rate is read in the step that reaches each reading
    (no batch lag), near the true height; a laser's observation is its last scan, REP 117's
    +-inf held at the range bounds."""
    cfg = tiny_config()
    cfg["sensors"] += [
        {"type": "sonar", "name": "sonar", "rate": 50.0, "axis": [0, 0, -1]},
        {"type": "laser", "name": "scan", "rate": 10.0, "range_max": 8.0},
    ]
    env = LandingEnv(cfg)
    assert env.observation_space["sonar"].shape == (1,)
    assert env.observation_space["scan"].shape == (1081,)
    obs, _ = env.reset(seed=1)
    assert obs["sonar"][0] > 0.5  # the reading at t = 0
    assert not obs["scan"].any()  # no scan has ended yet: zeros
    scans = 0
    for _ in range(12):
        obs, _, term, trunc, info = env.step(np.zeros(6, np.float32))
        end_ns = round(info["t"] * 1e9)
        (tap,) = info["taps"]["sonar"]
        assert tap["t"][-1] == end_ns  # this step's own reading, not one from a batch ago
        assert obs["sonar"][0] == np.float32(tap["range"][-1])
        # the goal lies on the empty scene's ground: the reading is the height gap, up to
        # the sonar's mount and noise
        assert abs(obs["sonar"][0] - info["state"]["gaps"][2]) < 0.15
        for q in info["taps"].get("scan", []):
            r = np.asarray(q["ranges"], np.float64)
            want = np.where(r < 0.1, 0.1, np.where(np.isfinite(r), r, 8.0))
            np.testing.assert_array_equal(obs["scan"], want.astype(np.float32))
            assert np.isposinf(r).any()  # the sky: no echo within 8 m, shown as 8 m
            scans += 1
        assert env.observation_space.contains(obs)
        if term or trunc:
            break
    env.close()
    assert scans >= 1


def test_lidar_and_stereo_observations_are_the_steps_latest_measurements() -> None:
    """A LiDAR's observation is its last scan's returns as ``valid, x, y, z`` rows (then
    zero rows), a stereo camera's both eyes' last frames; each as its typed tap holds it."""
    cfg = tiny_config()
    cfg["sensors"] += [
        {"type": "lidar", "name": "lidar", "rate": 10.0, "preset": "vlp16", "azimuth_steps": 90},
        {
            "type": "stereo_camera",
            "name": "stereo",
            "rate": 10.0,
            "resolution": [32, 24],
            "baseline": 0.1,
            "pose": {"position": [0.0, 0.0, -0.05], "rpy": [0.0, 1.5707963, 0.0]},
        },
    ]
    env = LandingEnv(cfg)
    assert env.observation_space["lidar"].shape == (16 * 90, 4)
    assert env.observation_space["stereo"].shape == (2, 24, 32, 3)  # rgb8, as published
    env.reset(seed=1)
    scans = frames = 0
    for _ in range(15):
        obs, _, term, trunc, info = env.step(np.zeros(6, np.float32))
        for q in info["taps"].get("lidar", []):
            pts = q.points
            ok = np.isfinite(pts["x"])
            n = int(ok.sum())
            assert 0 < n <= 16 * 90
            assert (obs["lidar"][:n, 0] == 1).all()
            assert not obs["lidar"][n:].any()
            np.testing.assert_array_equal(obs["lidar"][:n, 1], pts["x"][ok])
            np.testing.assert_array_equal(obs["lidar"][:n, 3], pts["z"][ok])
            scans += 1
        eyes = {q.eye: q.image for q in info["taps"].get("stereo", [])}
        if eyes:
            np.testing.assert_array_equal(obs["stereo"][0], eyes["left"])
            np.testing.assert_array_equal(obs["stereo"][1], eyes["right"])
            frames += 1
        assert env.observation_space.contains(obs)
        if term or trunc:
            break
    env.close()
    assert scans >= 1
    assert frames >= 1


def test_start_spread_draws_each_episodes_start_from_its_seed() -> None:
    """closed_loop.start_spread moves each episode's start within the spread, the same for
    the same seed and different across seeds; the episode's config carries the start it
    flew, and tau-state lands from every drawn start."""
    spread = {"position": [0.3, 0.2, 0.1], "rpy": [0.05, 0.05, 0.2], "descent_rate": 0.3}
    base = tiny_config()
    nominal = base["trajectory"]["initial"]
    env = LandingEnv(tiny_config(closed_loop={"start_spread": spread}))
    starts = []
    for seed in (1, 2, 3, 1):
        _obs, info = env.reset(seed=seed)
        ini = env.config.trajectory.initial
        assert ini.position is not None
        assert ini.descent_rate is not None
        start = np.array([*ini.position, *ini.rpy, ini.descent_rate])
        want = np.array([*nominal["position"], *nominal["rpy"], nominal["descent_rate"]])
        width = np.array([*spread["position"], *spread["rpy"], spread["descent_rate"]])
        assert np.all(np.abs(start - want) <= width + 1e-12)
        # the environment flies from it: the state at t = 0 is the drawn start
        np.testing.assert_allclose(info["state"]["gaps"][:3], start[:3], atol=0.2)
        starts.append(start)
    env.close()
    assert np.array_equal(starts[0], starts[3])
    assert not np.array_equal(starts[0], starts[1])
    assert not np.array_equal(starts[1], starts[2])
    for seed in (4, 5):
        ep = fly(tiny_config(closed_loop={"start_spread": spread}), "tau-state", seed=seed)
        assert ep["success"], ep


def test_a_start_spread_past_the_goal_is_a_clear_error() -> None:
    """A spread larger than the start's height draws starts below the goal: the reset of
    such a seed names the key, the seed, the start and the rule it breaks."""
    env = LandingEnv(tiny_config(closed_loop={"start_spread": {"position": [0, 0, 5.0]}}))
    failed = []
    for seed in range(12):  # z0 = 1 m +- 5 m: most draws lie below the goal
        try:
            env.reset(seed=seed)
        except ConfigError as exc:
            text = str(exc)
            assert text.startswith(f"closed_loop.start_spread: the start drawn for seed {seed}")
            assert "trajectory.initial.position" in text
            assert "must be > 0" in text
            assert "np.float64" not in text
            failed.append(seed)
    env.close()
    assert 0 < len(failed) < 12


GUIDE = Path(__file__).resolve().parents[2] / "docs" / "guide" / "closed-loop.md"
README = Path(__file__).resolve().parents[2] / "README.md"


def test_the_guide_lists_every_info_key_and_the_examples_use_no_other() -> None:
    """The guide's ``info`` paragraph names exactly the keys a step's ``info`` has (plus
    ``episode`` at the end), and every ``info["key"]`` the README's and the guide's
    examples read is among them."""
    text = GUIDE.read_text(encoding="utf-8")
    paragraph = text.split("\n`info` holds ", 1)[1].split("\n\n", 1)[0]
    listed = set(re.findall(r"(?:^|[,(]\s|and\s|end\s)`(\w+)`", paragraph, re.M))
    env = LandingEnv(tiny_config())
    _, info = env.reset(seed=0)
    _, _, _, _, stepped = env.step(np.zeros(6, dtype=np.float32))
    env.close()
    assert listed == set(info) | set(stepped) | {"episode"}, sorted(listed)
    used = set(re.findall(r'info\["(\w+)"\]', README.read_text() + text))
    assert "R_world_goal" in used
    assert used <= listed | {"action"}, used - listed  # `action`: the wrappers' (documented there)
