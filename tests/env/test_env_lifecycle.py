"""LandingEnv's lifecycle and API edges (issue 46 item 5): unclosed environments exit
cleanly and leave no folder, no ResourceWarning, every non-real action and unknown reset
option gets a clear error, the IMU observation never drops samples, the start's
acceleration lies within the action bounds, and ``roslan fly`` shows its progress."""

from __future__ import annotations

import gc
import subprocess
import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from env_helpers import tiny_config
from roslan.env import LandingEnv
from roslan.errors import ActionError, ConfigError


def _imu_only(**over: Any) -> dict[str, Any]:
    """The tiny landing with its IMU only and no scene: a reset costs milliseconds."""
    cfg = tiny_config(scene=None, **over)
    cfg["sensors"] = [s for s in cfg["sensors"] if s["type"] == "imu"]
    return cfg


# Ten forked children (the imports paid once) each leave three environments unclosed,
# one of them recording, mid-episode, and exit as a script does (falling off the end).
_UNCLOSED = """
import os, sys
root, helpers = sys.argv[1], sys.argv[2]
sys.path.insert(0, helpers)
import numpy as np
from env_helpers import tiny_config
from roslan.env import LandingEnv
cfg = tiny_config(scene=None)
cfg["sensors"] = [s for s in cfg["sensors"] if s["type"] == "imu"]
warm = LandingEnv(cfg, record=os.path.join(root, "warm"))  # the lazy imports, once
warm.reset(seed=0)
warm.close()
codes = []
for k in range(10):
    pid = os.fork()
    if pid == 0:
        envs = [LandingEnv(cfg), LandingEnv(cfg),
                LandingEnv(cfg, record=os.path.join(root, f"ep{k}"))]
        for i, env in enumerate(envs):
            env.reset(seed=i)
            env.step(np.zeros(6, np.float32))
        break
    codes.append(os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]))
else:
    print(codes)
"""


def test_unclosed_environments_exit_cleanly_ten_times_and_leave_no_folder(
    tmp_path: Path,
) -> None:
    helpers = str(Path(__file__).parents[1] / "helpers")
    out = subprocess.run(
        [sys.executable, "-c", _UNCLOSED, str(tmp_path), helpers],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == str([0] * 10), out.stderr
    assert "terminate called" not in out.stderr
    # the recording episodes never ended: no OUTDIR, and their hidden partial folders went
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_close_and_garbage_collection_remove_the_partial_folder(tmp_path: Path) -> None:
    env = LandingEnv(_imu_only(), record=tmp_path / "a")
    env.reset(seed=0)
    env.step(np.zeros(6, np.float32))
    assert any(p.name.startswith(".a.partial-") for p in tmp_path.iterdir())
    env.close()
    assert list(tmp_path.iterdir()) == []
    env = LandingEnv(_imu_only(), record=tmp_path / "b")
    env.reset(seed=0)
    assert any(p.name.startswith(".b.partial-") for p in tmp_path.iterdir())
    del env
    gc.collect()
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("record", [False, True])
def test_a_reset_loop_warns_of_no_unclosed_resource(tmp_path: Path, record: bool) -> None:
    env = LandingEnv(tiny_config(), record=tmp_path / "out" if record else None, overwrite=True)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ResourceWarning)
        for seed in (0, 1):  # each reset abandons the previous episode mid-way
            env.reset(seed=seed)
            for _ in range(3):
                env.step(np.zeros(6, np.float32))
            gc.collect()
        env.close()
        gc.collect()
    assert [str(w.message) for w in caught if w.category is ResourceWarning] == []


@pytest.mark.parametrize(
    ("action", "where"),
    [
        (np.array([0, 0, 1j, 0, 0, 0]), r"action\[2\] \(az\)"),
        (np.zeros(6, np.complex64), r"action\[0\] \(ax\)"),
        (["0"] * 6, r"action\[0\] \(ax\) = np.str_\('0'\)"),
        ([0.0, 0.0, 0.0, "x", 0.0, 0.0], r"action\[0\] \(ax\)"),
        (np.array([0.0, 0.0, 0.0, 0.0, None, 0.0], dtype=object), r"action\[4\] \(q\) = None"),
        (np.array([0.0, 0.0, 0.0, 0.0, 0.0, "r"], dtype=object), r"action\[5\] \(r\) = 'r'"),
        (np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1 + 2j], dtype=object), r"action\[5\] \(r\)"),
        (np.array([True] * 6), r"action\[0\] \(ax\)"),
        ([[0.0, 0.0], [0.0]], r"action: not an array of 6 numbers"),
    ],
)
def test_every_non_real_action_is_an_action_error_naming_the_component(
    action: Any, where: str
) -> None:
    env = LandingEnv(_imu_only())
    env.reset(seed=0)
    with pytest.raises(ActionError, match=where):
        env.step(action)
    env.close()


def test_real_actions_of_any_real_dtype_are_flown_alike() -> None:
    env = LandingEnv(_imu_only())
    a = [0.5, -0.25, 1.0, 0.0, 0.1, -0.1]
    for action in (a, np.array(a, np.float32), np.array(a, dtype=object), np.array(a) * 1.0):
        checked, clipped = env.check_action(action)
        assert checked.dtype == np.float64
        assert not clipped
        np.testing.assert_array_equal(checked, np.asarray(action).astype(np.float64))
    checked, _ = env.check_action(np.array([1, 2, 3, 0, 0, 0], np.int16))
    np.testing.assert_array_equal(checked, [1.0, 2.0, 3.0, 0.0, 0.0, 0.0])


def test_unknown_reset_options_are_a_config_error_naming_them() -> None:
    env = LandingEnv(_imu_only())
    env.reset(seed=0, options={})  # none and empty are fine (Gymnasium's wrappers pass {})
    env.reset(seed=0, options=None)
    with pytest.raises(ConfigError, match=r"keys \['scene_seed', 'x'\].*takes no options"):
        env.reset(seed=1, options={"x": 1, "scene_seed": 3})
    with pytest.raises(ConfigError, match="a list"):
        env.reset(seed=1, options=[1])  # type: ignore[arg-type]
    env.close()


def test_max_imu_samples_below_a_steps_samples_is_a_config_error() -> None:
    # 500 Hz over a 50 Hz step: 10 samples in every step
    with pytest.raises(ConfigError, match=r"max_imu_samples = 9: .* up to 10 samples.*at least 10"):
        LandingEnv(_imu_only(closed_loop={"observation": {"max_imu_samples": 9}}))
    env = LandingEnv(_imu_only(closed_loop={"observation": {"max_imu_samples": 10}}))
    env.reset(seed=0)
    for _ in range(5):
        obs, *_ = env.step(np.zeros(6, np.float32))
        rows = obs["imu"]
        assert rows.shape == (10, 8)
        assert rows[:, 0].sum() == 10  # every sample kept
        # consecutive samples 2 ms apart, the last one at the step's end
        np.testing.assert_allclose(np.diff(rows[:, 1]), 0.002, atol=1e-6)
        assert abs(rows[-1, 1]) < 1e-6
    env.close()


@pytest.mark.parametrize("spread", [None, {"position": [0.4, 0.4, 0.2], "descent_rate": 0.5}])
def test_the_starts_acceleration_lies_within_the_action_bounds(spread: Any) -> None:
    over: dict[str, Any] = {} if spread is None else {"closed_loop": {"start_spread": spread}}
    env = LandingEnv(_imu_only(**over))
    bound = env.closed_loop.dynamics.max_acceleration
    limited = 0
    for seed in range(4):
        _, info = env.reset(seed=seed)
        traj = env._traj
        assert traj is not None
        a_world = info["R_world_goal"] @ info["state"]["accels"][:3]
        assert np.all(np.abs(a_world) <= bound + 1e-9)
        closed = traj.start_acceleration  # the closed form's, at t = 0
        over_bound = np.abs(closed) > bound
        limited += int(over_bound.any())
        np.testing.assert_allclose(a_world, np.clip(closed, -bound, bound), atol=1e-9)
        np.testing.assert_allclose(np.abs(a_world[over_bound]), bound)
    # the tiny landing's own start pulls -20.4 m/s^2: it is limited on every seed
    assert limited >= (4 if spread is None else 1)
    env.close()


@pytest.mark.parametrize("quiet", [False, True])
def test_fly_shows_progress_off_a_terminal_and_nothing_when_quiet(
    quiet: bool, capsys: pytest.CaptureFixture[str]
) -> None:
    from roslan.cli.fly import FlyProgress
    from roslan.env.episode import fly

    progress = FlyProgress(quiet)
    seen: list[dict[str, Any]] = []

    def on_step(obs: dict[str, Any], info: dict[str, Any]) -> None:
        seen.append(info)
        progress.step(obs, info)

    ep = fly(tiny_config(), "tau-state", seed=1, on_step=on_step)
    progress.stop()
    err = capsys.readouterr().err
    if quiet:
        assert err == ""
        return
    n_events = sum(len(info["events"]) for info in seen)
    assert n_events > 1000
    assert err.splitlines() == [
        "roslan: building the scene and the sensors, first reset...",
        "roslan: flying the episode...",
        f"roslan: flew {seen[-1]['t']:.2f} s simulated, {ep['steps']} steps, {n_events:,} events",
    ]
