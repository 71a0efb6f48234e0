"""roslan/LandingLite-v0 (the training configuration) and its vector entry point: the
Gymnasium checker, determinism, the event camera's field of view and pixel model against
Landing-v0's, and N envs sharing a scene giving N single envs' observations."""

from __future__ import annotations

import math
from typing import Any

import gymnasium
import numpy as np
import pytest
import yaml

from roslan.env import DEFAULT_CONFIG, LITE_CONFIG, LandingEnv
from roslan.env.landing import load_env_config
from roslan.env.vector import LandingVectorEnv

pytest.importorskip("roslan.render.gl")


def _event_camera(path: Any) -> Any:
    cfg, _ = load_env_config(path)
    (cam,) = [s for s in cfg.sensors if s.type == "event_camera"]
    return cam


def _fov(model: Any) -> tuple[float, float]:
    """Horizontal and vertical field of view (rad) of a pinhole model, from the outer
    pixel edges (-0.5 and W - 0.5) through the principal point."""
    K = model.K
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    h = math.atan((cx + 0.5) / fx) + math.atan((model.width - 0.5 - cx) / fx)
    v = math.atan((cy + 0.5) / fy) + math.atan((model.height - 0.5 - cy) / fy)
    return h, v


def test_lite_event_camera_has_the_default_cameras_field_of_view_and_pixel() -> None:
    default, lite = _event_camera(DEFAULT_CONFIG), _event_camera(LITE_CONFIG)
    dm, lm = default.camera_model(), lite.camera_model()
    assert (lm.width, lm.height) == (64, 48)
    assert (dm.width, dm.height) == (346, 260)  # the DAVIS346
    assert dm.is_pinhole
    assert lm.is_pinhole
    (dh, dv), (lh, lv) = _fov(dm), _fov(lm)
    assert lh == pytest.approx(dh, abs=1e-9)  # the horizontal FOV, ~77.4 deg
    assert math.degrees(dh) == pytest.approx(2 * math.degrees(math.atan(173 / 216)), abs=1e-6)
    # 64x48 is 4:3, the DAVIS346 1.331:1: the vertical FOV differs by the aspect alone
    want_v = 2 * math.atan(24.0 / lm.K[1, 1])
    assert lv == pytest.approx(want_v, abs=1e-9)
    assert abs(math.degrees(lv - dv)) < 0.2
    # the per-pixel model (thresholds, noise rates, refractory period, low-pass) carries over
    assert lite.model_params() == default.model_params()
    assert lite.timestamp_resolution_ns == default.timestamp_resolution_ns
    # the rest of the config is Landing-v0's: the trajectory, scene, closed loop and IMU
    d, li = yaml.safe_load(DEFAULT_CONFIG.read_text()), yaml.safe_load(LITE_CONFIG.read_text())
    for key in ("trajectory", "scene", "seed", "closed_loop"):
        assert li[key] == d[key], key
    assert li["sensors"][0] == d["sensors"][0]  # the 1 kHz IMU
    assert li["sensors"][0]["rate"] == 1000.0


def test_lite_is_registered_with_the_information_boundary_observation() -> None:
    env = gymnasium.make("roslan/LandingLite-v0")
    base = env.unwrapped
    assert isinstance(base, LandingEnv)
    assert base.config_path == LITE_CONFIG
    space = base.observation_space.spaces
    assert {"imu", "events", "start_estimate", "goal", "time"} == set(space)
    assert space["events"].shape == (2, 48, 64)
    assert space["imu"].shape == (21, 8)  # ceil(1000 / 50) + 1 rows
    env.close()


def test_lite_passes_the_gymnasium_env_checker() -> None:
    from gymnasium.utils.env_checker import check_env

    env = LandingEnv(LITE_CONFIG, render_mode="rgb_array")
    check_env(env, skip_render_check=False)
    env.close()


def _actions(n: int, k: int = 1) -> np.ndarray:
    return np.random.default_rng(3).uniform(-1.0, 1.0, (n, k, 6)).astype(np.float32)


def _single(seed: int, steps: int) -> list[dict[str, np.ndarray]]:
    env = LandingEnv(LITE_CONFIG)
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for a in _actions(steps)[:, 0]:
        obs, _, term, trunc, info = env.step(a)
        assert obs["events"].sum() == len(info["events"])
        out.append(obs)
        assert not term
        assert not trunc
    env.close()
    return out


@pytest.fixture(scope="module")
def singles() -> dict[int, list[dict[str, np.ndarray]]]:
    return {seed: _single(seed, 6) for seed in (11, 12)}


def test_lite_same_seed_gives_identical_observations(
    singles: dict[int, list[dict[str, np.ndarray]]],
) -> None:
    again = _single(11, 6)
    a = singles[11]
    for oa, ob in zip(a, again, strict=True):
        assert oa.keys() == ob.keys()
        for k in oa:
            np.testing.assert_array_equal(oa[k], ob[k])
    assert sum(o["events"].sum() for o in a) > 100, "the event camera saw nothing"
    other = singles[12]
    assert any(
        not np.array_equal(x["imu"], y["imu"]) for x, y in zip(a[1:], other[1:], strict=False)
    )
    assert not np.array_equal(a[0]["start_estimate"], other[0]["start_estimate"])


def test_vector_entry_point_gives_the_single_envs_observations(
    singles: dict[int, list[dict[str, np.ndarray]]],
) -> None:
    envs = gymnasium.make_vec(
        "roslan/LandingLite-v0", num_envs=2, vectorization_mode="vector_entry_point"
    )
    try:
        assert isinstance(envs, LandingVectorEnv)
        assert envs.metadata["autoreset_mode"] == gymnasium.vector.AutoresetMode.NEXT_STEP
        obs, _ = envs.reset(seed=11)  # sub-envs 11 and 12
        assert len(envs.shared.scenes) == 1  # one warehouse for both
        scene = envs.shared.scenes[0][0]
        assert all(e._session._run is not None for e in envs.envs)
        got = [obs]
        for a in _actions(6):
            obs, _, term, trunc, _ = envs.step(np.repeat(a, 2, axis=0))
            assert not (term.any())
            assert not (trunc.any())
            got.append(obs)
        for i, seed in enumerate((11, 12)):
            for t, want in enumerate(singles[seed]):
                for k in want:
                    np.testing.assert_array_equal(got[t][k][i], want[k], err_msg=f"{seed} {t} {k}")
        assert envs.shared.scenes[0][0] is scene
    finally:
        envs.close()
    assert envs.shared.scenes == {}


def test_vector_env_autoresets_on_the_next_step() -> None:
    cfg = yaml.safe_load(LITE_CONFIG.read_text())
    cfg["closed_loop"]["time_limit"] = 0.06  # three steps
    envs = LandingVectorEnv(2, cfg)
    try:
        first, _ = envs.reset(seed=[4, 9])
        t0 = first["time"].copy()  # the trajectory's clock at the start
        zero = np.zeros((2, 6), dtype=np.float32)
        trunc = np.zeros(2, dtype=bool)
        for _ in range(2):
            obs, _, term, trunc, _ = envs.step(zero)
            assert not (term.any())
            assert not (trunc.any())
        obs, _, term, trunc, _ = envs.step(zero)
        assert trunc.all()
        assert not term.any()
        assert (obs["time"] > t0).all()
        obs, reward, term, trunc, _ = envs.step(zero)  # NEXT_STEP: this step resets
        np.testing.assert_array_equal(obs["time"], t0)
        # a new episode, its seed drawn by each sub-env's generator (reset() without seed)
        seeds = [e.episode["seed"] for e in envs.envs]
        assert seeds[0] not in (4, 9)
        assert seeds[1] not in (4, 9)
        assert not np.array_equal(obs["start_estimate"], first["start_estimate"])
        np.testing.assert_array_equal(reward, [0.0, 0.0])
        assert not (term.any())
        assert not (trunc.any())
    finally:
        envs.close()


def test_vector_env_refuses_bad_arguments() -> None:
    from roslan.errors import ConfigError

    with pytest.raises(ConfigError, match="num_envs = 0"):
        LandingVectorEnv(0)
    with pytest.raises(ConfigError, match="max_episode_steps"):
        LandingVectorEnv(1, max_episode_steps=10)
