"""How many CPUs a run may use, and how many threads each frame or scan sensor gets for
its per-instant work (:class:`~roslan.io.ordered.OrderedPool`).

The CPUs are shared by the processes of a run: the main process (merge, bag threads,
local sensors) and its sensor worker processes (:mod:`roslan.pipeline.worker`). Each
camera-type and point-cloud sensor gets ``usable_cpus() // (processes + 1)`` threads (one
process's share is left to llvmpipe's render threads and the bag writer threads), at
most :data:`MAX_SENSOR_THREADS`, at least 1 (1: everything inline on the sensor's
thread, as on a 2-core machine, with or without worker processes: there the extra
threads only competed with the event camera, 2026-11-26, docs/performance.md). A run that is itself
a multiprocessing worker (``roslan dataset`` / Dask run simulations side by side) gets 1.
The environment variable ``ROSLAN_SENSOR_THREADS`` overrides the count. Outputs do not
depend on it.
"""

from __future__ import annotations

import multiprocessing
import os

from roslan.errors import ConfigError

__all__ = ["MAX_SENSOR_THREADS", "SENSOR_THREADS_ENV", "sensor_threads", "usable_cpus"]

SENSOR_THREADS_ENV = "ROSLAN_SENSOR_THREADS"
"""Environment variable overriding the per-sensor thread count (a positive integer)."""

MAX_SENSOR_THREADS = 4
"""Most threads per sensor by default: beyond, the sensor's own thread (render or cast)
is the bottleneck of a frame camera or LiDAR on a GPU workstation."""

_MAX_OVERRIDE = 256


def usable_cpus() -> int:
    """CPUs this process may run on (affinity mask where the OS has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - non-Linux
        return max(1, os.cpu_count() or 1)


def sensor_threads(processes: int) -> int:
    """Threads for each frame/scan sensor of a run whose sensors and writers run in
    ``processes`` processes (see the module docstring).

    Raises:
        ConfigError: ``ROSLAN_SENSOR_THREADS`` is set to something other than an integer
            in 1..256.
    """
    env = os.environ.get(SENSOR_THREADS_ENV)
    if env is not None and env.strip():
        try:
            n = int(env)
        except ValueError:
            n = 0
        if not 1 <= n <= _MAX_OVERRIDE:
            msg = (
                f"environment variable {SENSOR_THREADS_ENV} = {env!r}: allowed an integer "
                f"from 1 to {_MAX_OVERRIDE} (threads per frame/scan sensor; unset: automatic)"
            )
            raise ConfigError(msg)
        return n
    if multiprocessing.parent_process() is not None:
        return 1
    return max(1, min(MAX_SENSOR_THREADS, usable_cpus() // (max(1, int(processes)) + 1)))
