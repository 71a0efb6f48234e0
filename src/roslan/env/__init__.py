"""Closed loop: a Gymnasium landing environment where perception flies the ornithopter.

``import roslan.env`` registers ``roslan/Landing-v0`` (the default landing in the
warehouse, :data:`~roslan.env.landing.DEFAULT_CONFIG`), ``roslan/LandingLite-v0`` (the
same landing with a 64x48 event camera, for training: :data:`~roslan.env.landing.
LITE_CONFIG`; ``gymnasium.make_vec`` builds :class:`~roslan.env.vector.LandingVectorEnv`,
N of them sharing one scene) and ``roslan/Perching-v0`` (the refinery's perching pipe).
:mod:`roslan.env.wrappers` offers smaller action sets.
docs/guide/closed-loop.md is the user guide.
"""

from __future__ import annotations

import gymnasium

from roslan.env.dynamics import DynamicsTrajectory, MeanState
from roslan.env.landing import (
    DEFAULT_CONFIG,
    LITE_CONFIG,
    PERCHING_CONFIG,
    LandingEnv,
    load_env_config,
)
from roslan.env.policies import (
    POLICIES,
    ConstantDescentPolicy,
    Policy,
    PolicyContext,
    TauStatePolicy,
    make_policy,
)
from roslan.env.wrappers import ReducedAction, VerticalAction

__all__ = [
    "DEFAULT_CONFIG",
    "LITE_CONFIG",
    "PERCHING_CONFIG",
    "POLICIES",
    "ConstantDescentPolicy",
    "DynamicsTrajectory",
    "LandingEnv",
    "MeanState",
    "Policy",
    "PolicyContext",
    "ReducedAction",
    "TauStatePolicy",
    "VerticalAction",
    "load_env_config",
    "make_policy",
]


def _register() -> None:
    for env_id, path in (
        ("roslan/Landing-v0", DEFAULT_CONFIG),
        ("roslan/Perching-v0", PERCHING_CONFIG),
    ):
        if env_id not in gymnasium.registry:
            gymnasium.register(
                id=env_id,
                entry_point="roslan.env.landing:LandingEnv",
                # GL never crosses a fork: async vector workers are spawned
                kwargs={"config": str(path), "vector_kwargs": {"context": "spawn"}},
                disable_env_checker=False,
            )

    if "roslan/LandingLite-v0" not in gymnasium.registry:
        # no vector_kwargs in the spec: gymnasium refuses them with vector_entry_point (an
        # "async" make_vec of it takes vector_kwargs={"context": "spawn"} from the caller)
        gymnasium.register(
            id="roslan/LandingLite-v0",
            entry_point="roslan.env.landing:LandingEnv",
            vector_entry_point="roslan.env.vector:LandingVectorEnv",
            kwargs={"config": str(LITE_CONFIG)},
            disable_env_checker=False,
        )


_register()
