"""roslan: multi-sensor simulation of bio-inspired ornithopter landings.

The closed-form tau-theory trajectory (:mod:`roslan.trajectory`) is sampled by
each simulated sensor at its own instants; the pipeline (:mod:`roslan.pipeline`)
merges their messages by stamp into ROS 1 / ROS 2 bags and dataset text files.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("roslan")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0"

__all__ = ["__version__"]
