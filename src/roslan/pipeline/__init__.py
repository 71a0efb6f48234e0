"""The simulation pipeline: context handed to sensors, stamp-merged streaming to bags, CLI."""

from __future__ import annotations

from roslan.pipeline.context import Context
from roslan.pipeline.run import run_simulation

__all__ = ["Context", "run_simulation"]
