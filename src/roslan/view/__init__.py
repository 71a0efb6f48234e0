"""``roslan view``: a Rerun recording of a run (optional extra ``roslan[view]``)."""

from __future__ import annotations

from roslan.view.recording import TIMELINE, ViewError, build_recording

__all__ = ["TIMELINE", "ViewError", "build_recording"]
