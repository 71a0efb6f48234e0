"""The simulation pipeline: plan a run, merge every sensor's messages by stamp into the
bags, write the run folder (:func:`run_simulation`)."""

from __future__ import annotations

from roslan.pipeline.context import Context
from roslan.pipeline.engine import SensorEngine, StepOutput
from roslan.pipeline.live import LiveRun, open_run
from roslan.pipeline.plan import RunPlan, check_run, make_plan, preflight
from roslan.pipeline.run import RunOptions, run_simulation

__all__ = [
    "Context",
    "LiveRun",
    "RunOptions",
    "RunPlan",
    "SensorEngine",
    "StepOutput",
    "check_run",
    "make_plan",
    "open_run",
    "preflight",
    "run_simulation",
]
