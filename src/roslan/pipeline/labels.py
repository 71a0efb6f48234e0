"""The run's label tables (``output.labels``): ``classes.json`` and ``instances.json``
in OUTDIR (docs/guide/labels.md).

- ``classes.json``: ``[{"id", "name", "color"}]``, every class of the scene's table
  (:func:`roslan.scene.classes.scene_class_table`; ``color`` sRGB 0-255 for pictures);
- ``instances.json``: ``[{"id", "class_id", "object", "box3d": {"center", "size",
  "rpy"}}]``, every instance of the scene (:func:`roslan.scene.instances.scene_labels`)
  with its world-frame oriented box (m, rad).

The ids are those of every label output of the run (PNG images, events, scans, bags).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

from roslan.io.files import atomic_write_text
from roslan.scene.instances import labels_document

if TYPE_CHECKING:
    from roslan.scene.model import Scene

__all__ = ["CLASSES_FILE", "INSTANCES_FILE", "write_label_tables"]

CLASSES_FILE = "classes.json"
INSTANCES_FILE = "instances.json"


def write_label_tables(folder: Path, scene: Scene) -> None:
    """Write ``classes.json`` and ``instances.json`` of ``scene`` into ``folder``."""
    doc = labels_document(scene)
    classes = [{"id": c["id"], "name": c["name"], "color": c["color"]} for c in doc["classes"]]
    atomic_write_text(folder / CLASSES_FILE, json.dumps(classes, indent=1) + "\n")
    atomic_write_text(folder / INSTANCES_FILE, json.dumps(doc["instances"], indent=1) + "\n")
