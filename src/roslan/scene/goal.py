"""The landing goal a scene offers: its landing marker or its perch.

A simulation config that names a scene but gives no ``trajectory.goal`` lands on the
scene's goal (:func:`goal_from_scene`): the warehouse's landing marker, the refinery's
perching pipe, a scene file's ``goal:`` (or its ``perch:`` placed by ``pose``). A scene
without one (``empty``, a scene file with neither) keeps the world origin, with a
warning. The goal is read without building the scene (a file is only parsed); a scene
that cannot be loaded (an unknown name, an invalid file, a missing mesh) raises its
:class:`SceneError` here, before any note or warning about its goal.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

from roslan.config.base import Pose
from roslan.errors import Note
from roslan.scene.loader import BUILTIN_SCENES, load_scene, parse_scene_file
from roslan.trajectory.config import TrajectoryConfig

__all__ = ["GoalNote", "SceneGoal", "goal_from_scene", "scene_goal"]


class GoalNote(Note):
    """An informational line (``note: ...`` on the command line): the goal came from the
    scene."""


@dataclass(frozen=True)
class SceneGoal:
    """A scene's landing goal in the world: ``pose`` and what it is (``kind``: ``landing
    marker``, ``perch`` or ``goal`` for a scene file's bare ``goal:``)."""

    pose: Pose
    kind: str


def _builtin_goal(name: str) -> SceneGoal | None:
    from roslan.scene.refinery import REFINERY_GOAL
    from roslan.scene.warehouse import WAREHOUSE_GOAL

    table = {"warehouse": (WAREHOUSE_GOAL, "landing marker"), "refinery": (REFINERY_GOAL, "perch")}
    if name not in table:
        return None
    (position, rpy), kind = table[name]
    return SceneGoal(Pose(position=position, rpy=rpy), kind)


def scene_path(spec: str | Path, base_dir: Path | None) -> Path:
    """The file a non-built-in scene ``spec`` names (relative to ``base_dir``)."""
    path = Path(spec).expanduser()
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    return path


def scene_goal(spec: str | Path, *, base_dir: Path | None = None) -> SceneGoal | None:
    """The landing goal the scene ``spec`` (a built-in name or a scene YAML) defines, or
    None when it defines none.

    Raises:
        SceneError: ``spec`` is neither a built-in name nor an existing file (with the
            closest built-in name), or the file is invalid (as :func:`load_scene` says).
    """
    text = str(spec)
    if text in BUILTIN_SCENES:
        return _builtin_goal(text)
    path = scene_path(text, base_dir)
    if not path.is_file():
        load_scene(text, base_dir=base_dir)  # raises load_scene's own error for the name
        return None
    with warnings.catch_warnings():  # loading the scene warns about the file once
        warnings.simplefilter("ignore")
        try:
            model = parse_scene_file(path)
        except OSError:  # the scene's own load reports the problem
            return None
    perch = model.perch
    if model.goal is not None:
        on_perch = perch is not None and perch.pose is None
        return SceneGoal(model.goal, "perch" if on_perch else "goal")
    if perch is not None and perch.pose is not None:
        return SceneGoal(perch.pose, "perch")
    return None


def _fmt(values: tuple[float, ...]) -> str:
    return "[" + ", ".join(f"{v:g}" for v in values) + "]"


def goal_from_scene(
    trajectory: TrajectoryConfig, scene: str | None, *, base_dir: Path | None = None
) -> TrajectoryConfig:
    """``trajectory`` with the scene's goal when it gives no ``goal`` of its own.

    Only a tau landing (no ``file:``) in a scene without a configured ``goal`` changes:
    it gets the scene's marker or perch, announced by a :class:`GoalNote`; a scene
    without one keeps the world origin, with a ``UserWarning`` (given only once the scene
    loads: a scene file without a goal is built first). Otherwise ``trajectory`` is
    returned unchanged (the same object).

    Raises:
        SceneError: the scene cannot be loaded (see :func:`scene_goal`).
    """
    if scene is None or trajectory.file is not None or "goal" in trajectory.model_fields_set:
        return trajectory
    found = scene_goal(scene, base_dir=base_dir)
    if found is None:
        if scene not in BUILTIN_SCENES:  # a file that fails to build errs before the warning
            with warnings.catch_warnings():  # (its own load warns once, later)
                warnings.simplefilter("ignore")
                load_scene(scene, base_dir=base_dir)
        warnings.warn(
            f"scene {scene!r} defines no landing marker or perch and trajectory.goal is "
            "not set: landing at the world origin (set trajectory.goal to land elsewhere)",
            UserWarning,
            stacklevel=2,
        )
        return trajectory
    pose = found.pose
    warnings.warn(
        f"trajectory.goal not set: landing on the {found.kind} of scene {scene!r}, position "
        f"{_fmt(pose.position)}, rpy {_fmt(pose.rpy)} (set trajectory.goal to land elsewhere)",
        GoalNote,
        stacklevel=2,
    )
    out: TrajectoryConfig = trajectory.model_copy(update={"goal": pose})
    return out
