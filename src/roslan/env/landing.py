"""``roslan.env.LandingEnv``: a Gymnasium environment where perception flies the ornithopter.

Built from the same YAML as ``roslan simulate`` (scene, vehicle, sensors, the
``trajectory:`` block's start state and goal) plus an optional ``closed_loop:`` block
(:mod:`roslan.config.closed_loop`). Each :meth:`LandingEnv.step` holds one action for one
control period (default 50 Hz) on the vehicle model of :mod:`roslan.env.dynamics`, runs
every sensor causally up to the step's end and returns their data
(:mod:`roslan.env.observe`). docs/guide/closed-loop.md documents the spaces, the reward
and the episode's end.
"""

from __future__ import annotations

import json
import numbers
import os
import weakref
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from roslan.config.base import Pose
from roslan.config.closed_loop import ClosedLoopConfig
from roslan.config.sim import SimConfig
from roslan.env.contact import ContactModel, Outcome, StepEvent, is_success, reward_terms
from roslan.env.dynamics import MAX_PITCH, DynamicsTrajectory
from roslan.env.knowledge import (
    CONSTANT_SHAPES,
    StartEstimate,
    constant_observation,
    draw_start_estimate,
)
from roslan.env.observe import EventPacket, ObservationBuilder
from roslan.errors import ActionError, ConfigError

if TYPE_CHECKING:
    from roslan.env.policies import PolicyContext

__all__ = ["DEFAULT_CONFIG", "LITE_CONFIG", "PERCHING_CONFIG", "LandingEnv", "load_env_config"]

DEFAULT_CONFIG = Path(__file__).resolve().parent.parent / "data" / "landing.yaml"
"""The configuration of ``roslan/Landing-v0`` and of ``roslan fly`` without CONFIG."""
LITE_CONFIG = Path(__file__).resolve().parent.parent / "data" / "landing_lite.yaml"
"""The configuration of ``roslan/LandingLite-v0``: the default landing with a 64x48 event
camera, for training (docs/guide/closed-loop.md, "LandingLite-v0")."""
PERCHING_CONFIG = Path(__file__).resolve().parent.parent / "data" / "perching.yaml"
"""The configuration of ``roslan/Perching-v0`` (the refinery's perching pipe)."""

F32 = NDArray[np.float32]


def load_env_config(
    config: str | Path | Mapping[str, Any] | SimConfig | None,
) -> tuple[SimConfig, Path | None]:
    """The validated config and the file it came from (None: the default file's folder
    is not used for a dict). Raises :class:`~roslan.errors.ConfigError` naming the key."""
    from roslan.config.base import load_yaml_model, validate_model

    if config is None:
        config = DEFAULT_CONFIG
    if isinstance(config, SimConfig):
        return config, None
    if isinstance(config, Mapping):
        return validate_model(SimConfig, dict(config), "<config dict>"), None
    path = Path(config)
    return load_yaml_model(SimConfig, path), path


_START_STREAM = 0x57A27  # the start spread's generator: [seed, this]


def _fmt(v: NDArray[np.float64]) -> str:
    return "[" + ", ".join(f"{float(x):.4g}" for x in v) + "]"


_ACTION_NAMES = ("ax", "ay", "az", "p", "q", "r")


def _is_real(x: Any) -> bool:
    """A real number (int, float, NumPy real scalar), not a bool, string or complex."""
    return isinstance(x, numbers.Real) and not isinstance(x, (bool, np.bool_))


class _Held:
    """What an environment holds that needs releasing: the running episode's sensors and
    the scene's back ends. :meth:`release` runs at ``close()``, when the environment is
    garbage-collected, and at interpreter exit for one never closed (``weakref.finalize``,
    an ``atexit`` handler): a recorded episode's hidden partial folder is removed and
    every sensor thread stopped while the interpreter is whole."""

    def __init__(self) -> None:
        self.session: Any = None
        self.scenes: dict[int, Any] = {}
        self.pid = os.getpid()  # a forked child's exit leaves its parent's episode alone

    def close_session(self) -> None:
        session, self.session = self.session, None
        if session is not None:
            session.abort()

    def release_scenes(self) -> None:
        scenes, self.scenes = self.scenes, {}
        for _, backends in scenes.values():
            backends.release()

    def release(self) -> None:
        if os.getpid() != self.pid:
            return
        self.close_session()
        self.release_scenes()


class LandingEnv(gym.Env[dict[str, NDArray[Any]], F32]):
    """A closed-loop landing (module docstring).

    Args:
        config: a YAML path, a dict of the same keys, a :class:`SimConfig`, or None for
            :data:`DEFAULT_CONFIG`.
        record: OUTDIR: the episode is written there as ``simulate`` writes a run, plus
            ``episode.json`` (the folder appears complete at the episode's end; a reset
            or ``close()`` before that leaves nothing). An existing OUTDIR is an
            OutputError at ``reset`` unless ``overwrite``.
        overwrite: let ``record`` replace an existing roslan OUTDIR (each episode then
            replaces the previous one).
        render_mode: ``"rgb_array"`` (or None).
        policy_name: recorded in episode.json (``roslan fly`` sets it).
        vector_kwargs: ignored here: the registered ids carry ``{"context": "spawn"}`` for
            ``gymnasium.make_vec(..., vectorization_mode="async")``, whose workers must not
            inherit an OpenGL context through fork.

    Action: ``Box(6,)`` float32 ``[ax, ay, az, p, q, r]``: the commanded acceleration of
    base_link in the world frame (m/s^2, each within +-``closed_loop.dynamics.
    max_acceleration``; gravity is the wings' job, so 0 holds the velocity) and the
    commanded body rates (rad/s, each within +-``max_body_rate``). Values out of range
    are clipped (``info["clipped"]``); NaN, inf, a value that is not a real number
    (complex, string, bool, object) or a wrong shape raise
    :class:`~roslan.errors.ActionError` naming the component.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 50}  # noqa: RUF012 (gym's name)

    def __init__(
        self,
        config: str | Path | Mapping[str, Any] | SimConfig | None = None,
        *,
        record: str | Path | None = None,
        overwrite: bool = False,
        render_mode: str | None = None,
        policy_name: str | None = None,
        vector_kwargs: Mapping[str, Any] | None = None,
    ) -> None:
        del vector_kwargs  # gymnasium.make_vec's (the registration's spawn default)
        cfg, path = load_env_config(config)
        self.base_config = cfg
        self.config_path = path
        self.closed_loop: ClosedLoopConfig = cfg.closed_loop or ClosedLoopConfig()
        if cfg.trajectory.file is not None:
            msg = (
                "trajectory.file: a closed-loop episode starts from the tau block's initial "
                "state; remove 'file' (the vehicle's path is flown, not read)"
            )
            raise ConfigError(msg)
        if render_mode not in (None, "rgb_array"):
            msg = f"render_mode = {render_mode!r}: allowed: 'rgb_array' or None"
            raise ConfigError(msg)
        self.render_mode = render_mode
        self.record = None if record is None else Path(record).absolute()
        self.overwrite = overwrite
        self.policy_name = policy_name
        self.step_ns = round(1e9 / self.closed_loop.control_rate)
        self.dt = self.step_ns * 1e-9
        self.metadata = {**self.metadata, "render_fps": self.closed_loop.control_rate}
        dyn = self.closed_loop.dynamics
        hi = np.array([dyn.max_acceleration] * 3 + [dyn.max_body_rate] * 3, dtype=np.float32)
        self._box = spaces.Box(-hi, hi, dtype=np.float32)
        self.action_space = self._box
        self._obs = ObservationBuilder(cfg.sensors, self.closed_loop)
        # the constant entries (start estimate, goal): what a policy knows (env.knowledge)
        for key, shape in CONSTANT_SHAPES.items():
            self._obs.constant(key, np.zeros(shape))
        self.observation_space = self._obs.space  # type: ignore[assignment]
        self.start_estimate: StartEstimate | None = None
        """The episode's start estimate (``closed_loop.start_estimate``), after ``reset``."""
        self.goal: Pose | None = None
        """The goal's pose in the world (where the contact point lands), after ``reset``."""
        self._held = _Held()
        # (holds the holder, not the environment: an unclosed one is still collected)
        self._finalizer = weakref.finalize(self, self._held.release)
        self._traj: DynamicsTrajectory | None = None
        self._contact: ContactModel | None = None
        self._done = True
        self._episode: dict[str, Any] = {}
        self._last_events = EventPacket.empty()
        self._return = 0.0

    @property
    def _session(self) -> Any:
        return self._held.session

    @_session.setter
    def _session(self, session: Any) -> None:
        self._held.session = session

    # ------------------------------------------------------------------ episode
    def _scene(self, seed: int) -> Any:
        """The scene of scene seed ``seed`` and its back ends (renderer, ray caster), kept
        while the seed stays: a new seed releases the old ones (the env owns them)."""
        if self.base_config.scene is None:
            return None, None
        held = self._held
        if seed not in held.scenes:
            import roslan.scene as scene_mod
            from roslan.render.backends import SceneBackends

            held.release_scenes()
            base = self.config_path.parent if self.config_path is not None else None
            scene = scene_mod.load_scene(self.base_config.scene, base_dir=base, seed=seed)
            held.scenes = {seed: (scene, SceneBackends(scene))}
        return held.scenes[seed]

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, NDArray[Any]], dict[str, Any]]:
        """Start an episode at the config's initial state. ``seed`` (default: drawn from
        the environment's generator) is the episode's ``seed``: sensor noise, the start's
        draws and, with ``closed_loop.scene_seed: per_episode``, the scene (:meth:`scene_seed`).
        ``options``: none are defined (None or ``{}``; any key is a ConfigError)."""
        if options is not None and (not isinstance(options, Mapping) or options):
            what = (
                f"keys {sorted(map(str, options))}"
                if isinstance(options, Mapping)
                else f"a {type(options).__name__}"
            )
            msg = (
                f"reset(options=...): {what}: LandingEnv.reset takes no options (allowed: "
                "None or {}); the episode is chosen by seed=, the rest by the config"
            )
            raise ConfigError(msg)
        super().reset(seed=seed)
        self._close_session()
        ep_seed = int(seed) if seed is not None else int(self.np_random.integers(0, 2**31 - 1))
        cfg = self._start(self.base_config.model_copy(update={"seed": ep_seed}), ep_seed)
        from roslan.vehicle import base_link_trajectory

        scene, backends = self._scene(self.scene_seed(ep_seed))
        traj_cfg = base_link_trajectory(cfg.trajectory, cfg.vehicle, scene)
        self._traj = traj = DynamicsTrajectory(traj_cfg, self.closed_loop.dynamics, self.step_ns)
        caster = backends.caster() if backends is not None else None
        self._contact = ContactModel(cfg, scene, traj, caster)
        goal = cfg.trajectory.goal
        self.goal = goal if isinstance(goal, Pose) else Pose(position=tuple(traj.p_world_goal))
        self.start_estimate = draw_start_estimate(traj, self.closed_loop.start_estimate, ep_seed)
        for key, value in constant_observation(self.start_estimate, self.goal).items():
            self._obs.constant(key, value)
        limit = self.closed_loop.time_limit
        self.time_limit_ns = round(
            1e9 * (limit if limit is not None else 4.0 * traj.reference_T + 1.0)
        )
        self.config = cfg
        from roslan.env.session import SensorSession

        self._session = SensorSession(
            cfg,
            traj,
            scene,
            backends=backends,
            record=self.record,
            overwrite=self.overwrite,
            config_path=self.config_path,
        )
        self._obs.reset()
        self._done = False
        self._return = 0.0
        self._episode = {
            "policy": self.policy_name,
            "seed": ep_seed,
            "scene_seed": self.scene_seed(ep_seed),
            "success": False,
            "reason": None,
            **Outcome().as_dict(),
        }
        out = self._session.advance(0)
        obs = self._obs.build(out.taps, (0, 0))
        self._last_events = self._obs.raw_events(out.taps)
        return obs, self._info(out, clipped=False)

    def scene_seed(self, seed: int) -> int:
        """The scene's seed for episode ``seed``: the config's ``seed`` when
        ``closed_loop.scene_seed`` is ``fixed``, ``seed`` itself when ``per_episode``
        (as ``simulate`` loads a run's scene with the run's seed)."""
        if self.closed_loop.scene_seed == "per_episode":
            return int(seed)
        return int(self.base_config.seed)

    def _start(self, cfg: SimConfig, seed: int) -> SimConfig:
        """The episode's config: the start moved by ``closed_loop.start_spread``, drawn
        from the episode's seed (its own stream: the sensors' noise is unchanged)."""
        spread = self.closed_loop.start_spread
        if spread.is_zero():
            return cfg
        from pydantic import ValidationError

        from roslan.trajectory import TauTrajectory, TrajectoryConfig

        nominal = TauTrajectory(cfg.trajectory, warn=False)
        u = np.random.default_rng([seed, _START_STREAM]).uniform(-1.0, 1.0, 7)
        gaps = nominal.initial_gaps + u[:6] * np.array([*spread.position, *spread.rpy])
        rate = nominal.descent_rate + u[6] * spread.descent_rate
        data = cfg.trajectory.model_dump()
        data["approach"] = None
        data["initial"] = {
            "position": [float(v) for v in gaps[:3]],
            "rpy": [float(v) for v in gaps[3:]],
            "descent_rate": float(rate),
        }
        try:
            traj = TrajectoryConfig.model_validate(data)
        except ValidationError as exc:
            err = exc.errors()[0]
            where = ".".join(str(p) for p in err["loc"])
            msg = (
                f"closed_loop.start_spread: the start drawn for seed {seed} (position "
                f"{_fmt(gaps[:3])} m, rpy {_fmt(gaps[3:])} rad, descent_rate {rate:.4g} m/s) "
                "is not a valid start: "
                f"trajectory.{where}: {err['msg']}; make the spread smaller than the start"
            )
            raise ConfigError(msg) from None
        return cfg.model_copy(update={"trajectory": traj})

    def _info(self, out: Any, *, clipped: bool) -> dict[str, Any]:
        assert self._traj is not None
        ms = self._traj.mean_state()
        return {
            "t": ms.t,
            "state": {"gaps": ms.gaps, "rates": ms.rates, "accels": ms.accels},
            "R_world_goal": self._traj.R_world_goal.copy(),
            "events": self._last_events,
            "taps": out.taps,
            "clipped": clipped,
            "reason": self._episode.get("reason"),
            "success": self._episode.get("success", False),
        }

    def check_action(self, action: Any) -> tuple[NDArray[np.float64], bool]:
        """The action as (6,) float64 within bounds and whether it was clipped.

        Raises:
            ActionError: wrong shape, a value that is not a real number (complex, string,
                bool, object) or NaN or infinite (named by index and meaning).
        """
        a = self._real_array(action)
        if a.shape != (6,):
            msg = (
                f"action: shape {a.shape}; expected (6,): [ax, ay, az] m/s^2 (world) and "
                "[p, q, r] rad/s (body rates)"
            )
            raise ActionError(msg)
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            i = int(bad[0])
            what = _ACTION_NAMES[i]
            msg = (
                f"action[{i}] ({what}) = {a[i]}: every action value must be finite "
                f"(bounds: +-{self._box.high[i]:g} "
                f"{'m/s^2' if i < 3 else 'rad/s'})"
            )
            raise ActionError(msg)
        hi = self._box.high.astype(np.float64)
        clipped = np.clip(a, -hi, hi)
        return clipped, bool(np.any(clipped != a))

    def _real_array(self, action: Any) -> NDArray[np.float64]:
        """``action`` as float64, refusing every value that is not a real number."""
        try:
            raw = np.asarray(action)
        except (ValueError, TypeError) as err:  # ragged sequences
            msg = f"action: not an array of 6 numbers ({err})"
            raise ActionError(msg) from None
        if raw.dtype.kind in "iuf":
            return raw.astype(np.float64, copy=False)
        flat = raw.reshape(-1)
        if raw.dtype.kind == "O":
            bad = [i for i, x in enumerate(flat) if not _is_real(x)]
            if not bad:  # e.g. an object array of Python floats
                return raw.astype(np.float64)
        elif raw.dtype.kind == "c":
            bad = [i for i, x in enumerate(flat) if x.imag != 0] or [0]
        else:  # strings, bytes, bools, dates...
            bad = [0]
        i = bad[0] if bad else 0
        where = f"action[{i}] ({_ACTION_NAMES[i]})" if raw.shape == (6,) else f"action[{i}]"
        value = flat[i] if flat.size else raw
        msg = (
            f"{where} = {value!r} ({type(value).__name__}, array dtype {raw.dtype}): every "
            "action value must be a real number (int or float): [ax, ay, az] m/s^2, "
            "[p, q, r] rad/s"
        )
        raise ActionError(msg)

    def step(
        self, action: Any
    ) -> tuple[dict[str, NDArray[Any]], float, bool, bool, dict[str, Any]]:
        """Hold ``action`` for one control period (class docstring)."""
        if self._done or self._traj is None or self._contact is None:
            msg = "step() after the episode ended: call reset() first"
            raise ActionError(msg)
        a, clipped = self.check_action(action)
        traj = self._traj
        t0 = traj.horizon_ns
        try:
            traj.step(a[:3], a[3:])
            t1 = traj.horizon_ns
            event = self._contact.check_step(t0, t1)
            terminated, truncated = event is not None, False
            if event is None and abs(traj.mean_state().gaps[4]) > MAX_PITCH:
                event = StepEvent("collision", t1, f"pitch beyond +-{MAX_PITCH} rad")
                terminated = True
            if event is None and t1 >= self.time_limit_ns:
                truncated = True
            if terminated or truncated:
                out, reward = self._end(event, t1)
            else:
                out = self._session.advance(t1)
                reward = reward_terms(self.closed_loop, self.dt, None, False, False)
        except BaseException:
            self._close_session()
            raise
        span = (t0, out.horizon_ns)
        obs = self._obs.build(out.taps, span)
        self._last_events = self._obs.raw_events(out.taps)
        self._return += reward
        info = self._info(out, clipped=clipped)
        if terminated or truncated:
            info["episode"] = dict(self._episode)
        return obs, float(reward), terminated, truncated, info

    def _end(self, event: StepEvent | None, t1: int) -> tuple[Any, float]:
        """Finish the run at the touchdown, collision or time limit; the final reward."""
        assert self._traj is not None
        assert self._contact is not None
        end = t1 if event is None else event.t_ns
        dt = (end - (t1 - self.step_ns)) * 1e-9
        outcome = Outcome()
        success = collided = False
        if event is None:
            reason = "time_limit"
        elif event.kind == "touchdown":
            outcome = self._contact.outcome(end)
            success = is_success(self.closed_loop, outcome)
            reason = "touchdown"
        else:
            reason, collided = "collision", True
        self._traj.finish(end)
        reward = reward_terms(self.closed_loop, dt, outcome, success, collided)
        self._episode.update(
            success=success,
            reason=reason,
            detail=None if event is None else event.what,
            steps=self._traj.steps,
            control_rate=self.closed_loop.control_rate,
            **outcome.as_dict(),
        )
        self._episode["return"] = self._return + reward
        self._done = True
        extra = {"episode.json": (json.dumps(self._episode, indent=2) + "\n").encode()}
        out = self._session.finish(self._traj.duration_ns, extra)
        self._session = None
        return out, reward

    def policy_context(self) -> PolicyContext:
        """What a policy may know before this episode's first step
        (:func:`roslan.env.knowledge.policy_context`: the nominal config, the control
        period, the goal, the action bounds and the start estimate); call after
        :meth:`reset` (ActionError before the first one)."""
        if self._traj is None:
            msg = "policy_context() before reset(): the episode's goal frame is not known yet"
            raise ActionError(msg)
        from roslan.env.knowledge import policy_context

        return policy_context(self)

    @property
    def episode(self) -> dict[str, Any]:
        """The episode's summary so far (episode.json's content once it ended)."""
        return dict(self._episode)

    # ------------------------------------------------------------------ render
    def render(self) -> NDArray[np.uint8] | None:
        """An RGB frame (H, W, 3) uint8 of the last step's events (ON blue, OFF red, on
        white) at the event camera's resolution; without an event camera, the last frame
        of the first frame camera, else a 48x64 grey frame."""
        if self.render_mode is None:
            return None
        ev = self._last_events
        h, w = self._obs.ev_shape
        if h and w:
            img = np.full((h, w, 3), 255, dtype=np.uint8)
            if len(ev):
                on = ev["p"] > 0
                img[ev["y"][on], ev["x"][on]] = (40, 80, 255)
                img[ev["y"][~on], ev["x"][~on]] = (255, 60, 40)
            return img
        frame = self._obs.image()
        if frame is not None:
            return np.repeat(frame[..., None], 3, axis=2) if frame.ndim == 2 else frame
        return np.full((48, 64, 3), 128, dtype=np.uint8)

    # ------------------------------------------------------------------ close
    def _close_session(self) -> None:
        self._held.close_session()
        self._done = True

    def close(self) -> None:
        """Stop a running episode (a recorded one that did not end leaves no OUTDIR, not
        even its hidden partial folder) and release the scene's renderer and ray caster.
        An environment never closed does the same when it is garbage-collected or at
        interpreter exit."""
        self._held.release()
        self._done = True
        super().close()
