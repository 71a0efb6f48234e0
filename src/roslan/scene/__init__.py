"""Scenes: the one geometry every sensor sees.

``load_scene(spec)`` gives a :class:`Scene` from a built-in name (``warehouse``,
``refinery``, ``empty``) or a scene YAML file (see :mod:`roslan.scene.spec`);
``check_clearance`` tests a trajectory against it; ``export_scene`` writes GLB models,
``poses.yaml`` and a reloadable ``scene.yaml``; ``add_perch`` puts a bar, branch or
pipe perch at a goal; ``scene_labels`` gives the classes and instances of a scene
(:mod:`roslan.scene.instances`).
"""

from roslan.scene.clearance import check_clearance
from roslan.scene.export import export_scene
from roslan.scene.instances import scene_labels
from roslan.scene.loader import BUILTIN_SCENES, load_scene
from roslan.scene.model import Lights, Material, Scene, SceneObject
from roslan.scene.perch import PERCH_TYPES, add_perch
from roslan.scene.refinery import REFINERY_GOAL
from roslan.scene.warehouse import WAREHOUSE_GOAL

__all__ = [
    "BUILTIN_SCENES",
    "PERCH_TYPES",
    "REFINERY_GOAL",
    "WAREHOUSE_GOAL",
    "Lights",
    "Material",
    "Scene",
    "SceneObject",
    "add_perch",
    "check_clearance",
    "export_scene",
    "load_scene",
    "scene_labels",
]
