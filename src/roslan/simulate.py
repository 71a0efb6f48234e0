"""Public entry point of the simulation pipeline: :func:`run_simulation`.

See :mod:`roslan.pipeline.run` for the steps and the output folder contract.
"""

from __future__ import annotations

from roslan.pipeline.run import run_simulation

__all__ = ["run_simulation"]
