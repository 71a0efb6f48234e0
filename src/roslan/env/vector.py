"""Many landing environments in one process, sharing one scene: ``roslan/LandingLite-v0``'s
``vector_entry_point``.

``gymnasium.make_vec("roslan/LandingLite-v0", num_envs=N)`` (``vectorization_mode=
"vector_entry_point"``, the default for an id that has one) builds a
:class:`LandingVectorEnv`: N :class:`~roslan.env.landing.LandingEnv` stepped in turn in
this process, a :class:`gymnasium.vector.SyncVectorEnv` (its batching and its autoreset
semantics, ``autoreset_mode`` as gymnasium 1.x documents them; default ``NEXT_STEP``)
whose sub-environments share one scene per scene seed (:class:`SharedScenes`, released at
``close()``): the scene is built once, and with it one OpenGL upload (one renderer: the
process's OpenGL context is one already) and one Embree BVH. (N separate environments in
one process end up sharing them as well, through the scene loader's per-process cache; the
steps run one after another either way, so the CPU per env-step is a single env's.)
Each sub-environment keeps its own sensors, noise, trajectory and contact model, so
sub-environment ``i`` reset with seed ``s`` gives the observations of a single
environment reset with ``s`` (tested).

Sub-environment ``i`` is ``env.envs[i]``; ``reset(seed=s)`` seeds them ``s, s + 1, ...``
(gymnasium's convention).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from gymnasium.vector import AutoresetMode, SyncVectorEnv

from roslan.config.sim import SimConfig
from roslan.env.landing import LITE_CONFIG, LandingEnv, load_env_config

__all__ = ["LandingVectorEnv", "SharedScenes"]


class SharedScenes:
    """The scenes (and their back ends) of the sub-environments, one per scene seed in use:
    a seed no sub-environment flies any more is released when a new one is built."""

    def __init__(self) -> None:
        self.scenes: dict[int, tuple[Any, Any]] = {}
        self.in_use: dict[int, int] = {}
        """Sub-environment id -> the scene seed it flies."""

    def get(self, env: LandingEnv, seed: int) -> tuple[Any, Any]:
        self.in_use[id(env)] = seed
        if seed not in self.scenes:
            import roslan.scene as scene_mod
            from roslan.render.backends import SceneBackends

            used = set(self.in_use.values())
            for old in [s for s in self.scenes if s not in used]:
                self.scenes.pop(old)[1].release()
            cfg = env.base_config
            assert cfg.scene is not None
            base = env.config_path.parent if env.config_path is not None else None
            scene = scene_mod.load_scene(cfg.scene, base_dir=base, seed=seed)
            self.scenes[seed] = (scene, SceneBackends(scene))
        return self.scenes[seed]

    def release(self) -> None:
        scenes, self.scenes = self.scenes, {}
        self.in_use.clear()
        for _, backends in scenes.values():
            backends.release()


class _SharingEnv(LandingEnv):
    """A :class:`LandingEnv` whose scenes come from a :class:`SharedScenes` (the vector
    env owns and releases them)."""

    def __init__(self, shared: SharedScenes, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._shared = shared

    def _scene(self, seed: int) -> Any:
        if self.base_config.scene is None:
            return None, None
        return self._shared.get(self, seed)


class LandingVectorEnv(SyncVectorEnv):
    """N landing environments of one config in this process, sharing the scene (module
    docstring).

    Args:
        num_envs: N >= 1.
        config: as :class:`~roslan.env.landing.LandingEnv` (default: LandingLite-v0's).
        autoreset_mode: gymnasium's :class:`~gymnasium.vector.AutoresetMode` (or its
            value): ``NEXT_STEP`` (default: the step after an episode's end resets that
            sub-environment and returns its first observation), ``SAME_STEP`` (reset at
            once; ``info["final_obs"]``, ``info["final_info"]``) or ``DISABLED``.
        copy: return copies of the batched observations (gymnasium's default).
        render_mode: each sub-environment's (``"rgb_array"`` or None).
        vector_kwargs: ignored (an id's ``async`` settings).
        max_episode_steps: refused (the episode's end is ``closed_loop.time_limit``).
    """

    def __init__(
        self,
        num_envs: int = 1,
        config: str | Path | Mapping[str, Any] | SimConfig | None = LITE_CONFIG,
        *,
        autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
        copy: bool = True,
        render_mode: str | None = None,
        vector_kwargs: Mapping[str, Any] | None = None,
        max_episode_steps: int | None = None,
    ) -> None:
        from roslan.errors import ConfigError

        del vector_kwargs
        if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
            msg = f"num_envs = {num_envs!r}: allowed: an integer >= 1"
            raise ConfigError(msg)
        if max_episode_steps is not None:
            msg = (
                f"max_episode_steps = {max_episode_steps!r}: not supported by the landing's "
                "vector env; set closed_loop.time_limit (s) in the config instead"
            )
            raise ConfigError(msg)
        if config is None:
            config = LITE_CONFIG
        self.shared = SharedScenes()
        shared = self.shared
        cfg, path = load_env_config(config)

        def make() -> LandingEnv:
            env = _SharingEnv(shared, cfg, render_mode=render_mode)
            env.config_path = path  # (relative scene paths resolve as the file's)
            return env

        super().__init__(
            [make for _ in range(num_envs)],
            copy=copy,
            autoreset_mode=AutoresetMode(autoreset_mode),
        )

    def close_extras(self, **kwargs: Any) -> None:
        super().close_extras(**kwargs)
        self.shared.release()
