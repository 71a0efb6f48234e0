"""Fly one episode of a policy: the loop behind ``roslan fly`` and the benchmark."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from roslan.config.sim import SimConfig

__all__ = ["fly"]


def fly(
    config: str | Path | Mapping[str, Any] | SimConfig | None,
    policy: str,
    *,
    seed: int = 0,
    record: str | Path | None = None,
    overwrite: bool = False,
    on_step: Callable[[dict[str, Any], dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Fly policy ``policy`` (a :data:`~roslan.env.policies.POLICIES` name) for one
    episode from ``config`` (None: the default landing) with ``seed``; with ``record``,
    write OUTDIR (``simulate``'s files plus episode.json). ``on_step(obs, info)`` sees
    every step. Returns episode.json's content."""
    from roslan.env.knowledge import policy_context
    from roslan.env.landing import LandingEnv
    from roslan.env.policies import make_policy

    pol = make_policy(policy)  # an unknown name fails before anything is built
    env = LandingEnv(config, record=record, overwrite=overwrite, policy_name=policy)
    try:
        obs, info = env.reset(seed=seed)
        pol.reset(policy_context(env))
        if on_step is not None:
            on_step(obs, info)
        while True:
            action = np.asarray(pol.act(obs, info), dtype=np.float64)
            obs, _, terminated, truncated, info = env.step(action)
            if on_step is not None:
                on_step(obs, info)
            if terminated or truncated:
                return dict(info["episode"])
    finally:
        env.close()
