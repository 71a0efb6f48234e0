"""Smaller action sets for :class:`roslan.env.LandingEnv`.

:class:`ReducedAction` lets a policy fly some of the six action components
(``ax, ay, az`` m/s^2 in the world frame, ``p, q, r`` rad/s body rates) while the others
come from ``rest``:

* ``"zero"``: zero acceleration holds the velocity (the wings carry the weight) and zero
  body rates hold the attitude: e.g. a vertical-only agent keeps its launch drift;
* ``"tau-state"``: the closed form's own controller
  (:class:`~roslan.env.policies.TauStatePolicy`) flies them from the true state
  (``info["state"]``): a curriculum in which an agent learns one channel, e.g. the
  vertical braking, while ground truth closes the other gaps.

:class:`VerticalAction` is the vertical-only case. The wrapped environment's ``info``,
reward and episode end are unchanged; ``info["action"]`` holds the six values flown.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Literal

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from roslan.env.policies import TauStatePolicy
from roslan.errors import ActionError, ConfigError

__all__ = ["ACTION_NAMES", "ReducedAction", "VerticalAction"]

ACTION_NAMES = ("ax", "ay", "az", "p", "q", "r")
"""The six components of :class:`~roslan.env.LandingEnv`'s action, in order."""

Rest = Literal["zero", "tau-state"]


class ReducedAction(gym.Wrapper[Any, Any, Any, Any]):
    """Fly the action components ``keep`` (names out of :data:`ACTION_NAMES`; the reduced
    action holds them in :data:`ACTION_NAMES`' order, whatever the order of ``keep``);
    the others come from ``rest`` (module docstring).

    The action space is the wrapped one's ``Box`` restricted to ``keep``. A wrong shape
    or a NaN raises :class:`~roslan.errors.ActionError` naming the component; values
    beyond the bounds are clipped by the wrapped environment, as without the wrapper.
    """

    def __init__(self, env: gym.Env[Any, Any], keep: Sequence[str], rest: Rest = "zero") -> None:
        super().__init__(env)
        names = list(keep)
        unknown = [n for n in names if n not in ACTION_NAMES]
        if unknown or not names or len(set(names)) != len(names):
            msg = (
                f"ReducedAction: keep = {names!r}: give distinct names out of "
                f"{', '.join(ACTION_NAMES)}"
            )
            raise ConfigError(msg)
        if rest not in ("zero", "tau-state"):
            msg = f"ReducedAction: rest = {rest!r}: 'zero' or 'tau-state'"
            raise ConfigError(msg)
        self.keep = [ACTION_NAMES.index(n) for n in ACTION_NAMES if n in names]
        self.rest: Rest = rest
        box = env.action_space
        if not isinstance(box, spaces.Box) or box.shape != (6,):
            msg = f"ReducedAction: wraps LandingEnv's Box(6,) action, not {box}"
            raise ConfigError(msg)
        self.action_space = spaces.Box(box.low[self.keep], box.high[self.keep], dtype=np.float32)
        self._policy = TauStatePolicy() if rest == "tau-state" else None
        self._obs: Any = None
        self._info: dict[str, Any] = {}

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        if self._policy is not None:
            from roslan.env.knowledge import policy_context

            self._policy.reset(policy_context(self.env.unwrapped))
        self._obs, self._info = obs, info
        return obs, info

    def full_action(self, action: Any) -> NDArray[np.float64]:
        """The six values flown for the reduced ``action`` (after the last step's state)."""
        a = np.asarray(action, dtype=np.float64)
        n = len(self.keep)
        if a.shape != (n,):
            names = ", ".join(ACTION_NAMES[i] for i in self.keep)
            msg = f"action: shape {a.shape}; expected ({n},): [{names}]"
            raise ActionError(msg)
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            i = int(bad[0])
            msg = f"action[{i}] ({ACTION_NAMES[self.keep[i]]}) = {a[i]}: must be finite"
            raise ActionError(msg)
        if self._policy is None:
            full = np.zeros(6)
        else:
            full = np.asarray(self._policy.act(self._obs, self._info), dtype=np.float64)
        full[self.keep] = a
        return full

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        full = self.full_action(action)
        obs, reward, terminated, truncated, info = self.env.step(full)
        info["action"] = full
        self._obs, self._info = obs, info
        return obs, float(reward), terminated, truncated, info


class VerticalAction(ReducedAction):
    """Only ``az`` (m/s^2, world frame): ``Box(1,)``; the rest from ``rest``."""

    def __init__(self, env: gym.Env[Any, Any], rest: Rest = "zero") -> None:
        super().__init__(env, ["az"], rest)
