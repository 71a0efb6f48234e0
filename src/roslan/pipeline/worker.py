"""Sensor worker processes: render-heavy sensors run beside the main process.

The main process of :func:`~roslan.pipeline.run.run_simulation` merges every sensor's
messages by stamp and writes the bags. Rendering sensors (cameras, event cameras, lidars)
dominate the time, so with ``workers`` > 0 they run in child processes instead, each
pipelined with the bag writing of the main process (so both cores of a small machine are
busy):

* a child is a fresh interpreter (``python -c``, never a ``fork`` of a process that may
  already hold EGL / Embree threads, never a re-import of the caller's ``__main__``) that
  gets one pickled :class:`WorkerJob` through a socket pair: the trajectory config, the
  seed and start time, every sensor config (``ctx.sensors``), the scene object, the
  temporary OUTDIR, the bag flavours, and which sensors it runs (their classes, so a
  class resolved by the parent is the one used);
* it builds its own :class:`~roslan.pipeline.context.Context` (same per-name random
  streams, same scene, hence byte-identical output), merges its sensors' streams by
  ``(t_ns, order)``, builds each message's wire bytes for every flavour being written and
  sends them as ``("m", t_ns, order, topic, msgtype, datas)`` through a byte-bounded
  queue drained by a sender thread (backpressure: a child runs at most
  :data:`QUEUE_BYTES` ahead of the writer, so memory stays flat in the trajectory's
  duration);
* after its streams end it calls each sensor's ``close(ctx)`` (dataset files go straight
  into the temporary OUTDIR) and sends ``("done", profile)`` with its per-sensor times;
* an exception is sent as ``("error", ...)`` and re-raised in the parent as the same
  exception type and message, with the child's traceback text attached as ``__cause__``;
  a child that dies (killed, crashed) raises :class:`WorkerError` in the parent.

The parent merges by ``(t_ns, order)`` where ``order`` is the stable position of each
component (ground truth 0, then sensors in config order), the same total order as the
single-process merge, so the bags are byte-identical whatever the number of workers.

Children ignore SIGINT (the parent handles Ctrl-C and terminates them), die with the
parent (``PR_SET_PDEATHSIG`` on Linux) and get EPIPE if the parent goes away anyway: the
rules of every roslan child process, :mod:`roslan.io.child`.
"""

from __future__ import annotations

import contextlib
import heapq
import multiprocessing
import os
import pickle
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection
from pathlib import Path
from typing import TYPE_CHECKING, Any

from roslan.errors import ConfigError
from roslan.io.child import (
    ChildError,
    ChildProcess,
    child_connection,
    end_child,
    error_blob,
    raise_error_record,
)
from roslan.pipeline.merge import MERGE_KEY, CheckedStream, MergeItem, tagged
from roslan.pipeline.threads import usable_cpus
from roslan.sensors.base import Message, SensorConfig
from roslan.sensors.registry import render_cost

if TYPE_CHECKING:
    from roslan.io.messages import MessageStore
    from roslan.scene.model import Scene
    from roslan.trajectory.config import TrajectoryConfig

__all__ = [
    "MAX_RENDER_HELPERS",
    "QUEUE_BYTES",
    "ByteQueue",
    "WorkerError",
    "WorkerJob",
    "WorkerPool",
    "plan_helpers",
    "plan_workers",
    "resolve_workers",
    "sensor_stats",
    "worker_nice",
]

QUEUE_BYTES = 64 << 20
"""Most message bytes a worker holds ready ahead of the writer (plus one message)."""

LIGHT_NICE = 5
"""``nice`` increment of the workers that are not on the critical path (every worker but
the costliest): on a machine with fewer cores than busy threads, the scheduler then
favours the worker that finishes last (the event camera in the default job), and the
others fill the gaps instead of slowing it down. Outputs do not depend on it."""


class WorkerError(ChildError):
    """A sensor worker process died or broke the protocol (not a sensor's own error)."""


# ---------------------------------------------------------------------------- planning
MAX_RENDER_HELPERS = 8
"""Most render helper processes of one event camera."""


def _chained(s: SensorConfig) -> bool:
    """An event camera whose renders split into independent chains (every sampling but
    brightness, :mod:`roslan.sensors.cameras.event_chains`)."""
    return s.type == "event_camera" and getattr(s, "sampling", "brightness") != "brightness"


def resolve_workers(workers: int | str, sensors: Sequence[SensorConfig]) -> int:
    """Number of processes beside the main one for ``workers`` (``'auto'``, 0 or N >= 1):
    sensor worker processes first (at most one per render-heavy sensor), then render
    helpers of the event cameras (:func:`plan_helpers`).

    ``auto``: one per render-heavy sensor, at most the usable CPUs, plus render helpers
    while the processes together stay within half the usable CPUs (with the default
    suite's three render-heavy sensors none below 8 CPUs, where the renders already keep
    every core busy, and 5 on 16), and nothing on a single-CPU machine, for a job
    without render-heavy sensors, or when this process is itself a multiprocessing
    worker (``roslan dataset`` / Dask already runs simulations side by side: more
    processes would only oversubscribe the CPUs and memory). ``N``: at most N (never more
    than the render-heavy sensors plus :data:`MAX_RENDER_HELPERS` per event camera that
    can use them). ``0``: everything in this process.
    """
    heavy = sum(1 for s in sensors if render_cost(s.type) > 0)
    helpers = MAX_RENDER_HELPERS * sum(1 for s in sensors if _chained(s))
    if workers == "auto":
        cpus = usable_cpus()
        if cpus < 2 or multiprocessing.parent_process() is not None:
            return 0
        return min(cpus, heavy) + min(helpers, max(0, cpus // 2 - heavy))
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 0:
        msg = f"workers = {workers!r}: allowed 'auto', 0 (no worker processes) or an integer >= 1"
        raise ConfigError(msg)
    return min(workers, heavy + helpers)


def plan_workers(sensors: Sequence[SensorConfig], n_workers: int) -> list[list[int]]:
    """Split the render-heavy sensors (indices into ``sensors``) over ``n_workers``
    processes (at most one per sensor): costliest first onto the least loaded worker;
    each group sorted."""
    heavy = [i for i, s in enumerate(sensors) if render_cost(s.type) > 0]
    n = min(n_workers, len(heavy))
    if n <= 0:
        return []
    load = [0.0] * n
    groups: list[list[int]] = [[] for _ in range(n)]
    for i in sorted(heavy, key=lambda i: (-render_cost(sensors[i].type), i)):
        k = min(range(n), key=lambda k: (load[k], k))
        groups[k].append(i)
        load[k] += render_cost(sensors[i].type)
    return sorted(sorted(g) for g in groups)


def plan_helpers(sensors: Sequence[SensorConfig], n_workers: int) -> dict[str, int]:
    """Render helpers per event camera (name): the processes of ``n_workers`` beyond one
    per render-heavy sensor, dealt in turn to the event cameras whose renders form chains
    (config order), at most :data:`MAX_RENDER_HELPERS` each."""
    heavy = sum(1 for s in sensors if render_cost(s.type) > 0)
    chained = [s.name for s in sensors if _chained(s)]
    out = dict.fromkeys(chained, 0)
    spare = max(0, n_workers - heavy)
    for k in range(min(spare, MAX_RENDER_HELPERS * len(chained))):
        out[chained[k % len(chained)]] += 1
    return {name: n for name, n in out.items() if n > 0}


def worker_nice(groups: Sequence[Sequence[int]], sensors: Sequence[SensorConfig]) -> list[int]:
    """``nice`` increment of each group of :func:`plan_workers`: 0 for the costliest group
    (the first of equals), :data:`LIGHT_NICE` for the others."""
    loads = [sum(render_cost(sensors[i].type) for i in g) for g in groups]
    if not loads:
        return []
    top = loads.index(max(loads))
    return [0 if k == top else LIGHT_NICE for k in range(len(groups))]


# ---------------------------------------------------------------------------- the job
@dataclass(frozen=True)
class WorkerJob:
    """Everything a worker needs (pickled to it).

    ``assigned`` are indices into ``sensors``; ``classes`` their sensor classes; the
    merge order of sensor ``i`` is ``i + 1`` (ground truth is 0).
    """

    trajectory: TrajectoryConfig
    outdir: Path
    seed: int
    start_time_ns: int
    sensors: tuple[SensorConfig, ...]
    assigned: tuple[int, ...]
    classes: tuple[Any, ...]
    scene: Scene | None
    scene_spec: str | None
    base_dir: Path | None
    formats: tuple[str, ...]
    profile: bool
    queue_bytes: int = QUEUE_BYTES
    nice: int = 0
    sensor_threads: int = 1
    render_helpers: tuple[tuple[str, int], ...] = ()
    """Render helper processes per event camera name (:func:`plan_helpers`)."""


class ByteQueue:
    """A FIFO of byte blobs holding at most ``limit`` bytes, the blob being sent included
    (one larger blob is let in when nothing waits and nothing is being sent: a 282 MB
    cloud is never held twice). ``put`` blocks while full; ``fail`` wakes everybody up and
    makes ``put`` raise (the consumer is gone)."""

    def __init__(self, limit: int) -> None:
        self.limit = int(limit)
        self._items: deque[bytes | None] = deque()
        self._bytes = 0
        self._sending = 0  # bytes of the blob taken by get() and not yet sent()
        self._cond = threading.Condition()
        self.error: BaseException | None = None
        self.peak_bytes = 0

    @property
    def nbytes(self) -> int:
        return self._bytes

    def put(self, blob: bytes | None, timeout: float | None = None) -> None:
        """Append ``blob`` (None: end of stream), waiting while the queue is full.

        Raises:
            TimeoutError: still full after ``timeout`` seconds.
            BrokenPipeError: the consumer failed (its error is the ``__cause__``).
        """
        size = 0 if blob is None else len(blob)
        with self._cond:
            ok = self._cond.wait_for(
                lambda: (
                    self.error is not None
                    or not (self._items or self._sending)
                    or self._bytes + self._sending + size <= self.limit
                ),
                timeout,
            )
            if self.error is not None:
                raise BrokenPipeError("the worker's reader is gone") from self.error
            if not ok:
                raise TimeoutError("queue full")
            self._items.append(blob)
            self._bytes += size
            self.peak_bytes = max(self.peak_bytes, self._bytes)
            self._cond.notify_all()

    def get(self) -> bytes | None:
        """Pop the oldest blob, waiting for one."""
        with self._cond:
            self._cond.wait_for(lambda: bool(self._items))
            blob = self._items.popleft()
            size = 0 if blob is None else len(blob)
            self._bytes -= size
            self._sending = size
            self._cond.notify_all()
            return blob

    def sent(self) -> None:
        """The blob of the last :meth:`get` is sent: its bytes leave the queue's count."""
        with self._cond:
            self._sending = 0
            self._cond.notify_all()

    def fail(self, err: BaseException) -> None:
        with self._cond:
            self.error = err
            self._items.clear()
            self._bytes = self._sending = 0
            self._cond.notify_all()


# ---------------------------------------------------------------------------- child side
def _sender(conn: Connection, queue: ByteQueue) -> None:
    try:
        while True:
            blob = queue.get()
            if blob is None:
                return
            conn.send_bytes(blob)
            del blob
            queue.sent()
    except BaseException as err:  # parent gone (EPIPE): stop the producer
        queue.fail(err)


def _run_job(job: WorkerJob, put: Callable[[Any], None]) -> None:
    """Stream the assigned sensors of ``job``; ``put`` sends one protocol record."""
    from roslan.io.messages import Flavor, MessageStore
    from roslan.pipeline.context import Context
    from roslan.trajectory.spline import make_trajectory

    if job.nice > 0:
        with contextlib.suppress(OSError):  # threads started from here on inherit it
            os.nice(job.nice)
    traj = make_trajectory(job.trajectory, base_dir=job.base_dir)
    ctx = Context(
        traj,
        job.outdir,
        seed=job.seed,
        start_time_ns=job.start_time_ns,
        sensors=job.sensors,
        scene_spec=job.scene_spec,
        base_dir=job.base_dir,
        scene=job.scene,
        sensor_threads=job.sensor_threads,
        render_helpers=dict(job.render_helpers),
    )
    stores = [MessageStore(Flavor(f)) for f in job.formats]
    sensors = [cls(job.sensors[i]) for cls, i in zip(job.classes, job.assigned, strict=True)]
    streams = [
        CheckedStream(s.config.name, s.messages(ctx), {t.topic for t in s.topics()}, job.profile)
        for s in sensors
    ]
    build_s = [0.0] * len(sensors)
    index = {i + 1: k for k, i in enumerate(job.assigned)}  # merge order -> sensor position

    merged = heapq.merge(
        *(tagged(i + 1, st) for i, st in zip(job.assigned, streams, strict=True)),
        key=MERGE_KEY,
    )
    perf = time.perf_counter
    dumps = pickle.dumps
    for t_ns, order, msg in merged:
        t0 = perf()
        datas = tuple(bytes(store.encode(msg.build, msg.msgtype)) for store in stores)
        record = ("m", t_ns, order, msg.topic, msg.msgtype, datas)
        build_s[index[order]] += perf() - t0
        put(dumps(record, protocol=pickle.HIGHEST_PROTOCOL))
        del msg, datas, record  # not held while the next message is made (a big scan)
    close_s = []
    for s in sensors:
        t0 = perf()
        s.close(ctx)
        close_s.append(perf() - t0)
    profile = {
        st.name: {
            "generator_s": st.seconds,
            "build_s": build_s[k],
            "close_s": close_s[k],
            "messages": st.count,
            "worker_pid": os.getpid(),
            "worker_nice": os.nice(0),
            **sensor_stats(sensors[k]),
        }
        for k, st in enumerate(streams)
    }
    put(dumps(("done", profile), protocol=pickle.HIGHEST_PROTOCOL))


def sensor_stats(sensor: Any) -> dict[str, Any]:
    """``{"stats": ...}``: a sensor's own counters after its stream (e.g. the event
    camera's frames, capped steps and chains rendered here), where it keeps them."""
    stats = getattr(sensor, "stats", None)
    return {"stats": dict(stats)} if isinstance(stats, dict) and stats else {}


def main(argv: Sequence[str] | None = None) -> None:
    """Child entry point: ``python -c 'from roslan.pipeline.worker import main; main()' FD
    PID HELPERS``: HELPERS render helper interpreters of this worker's event cameras are
    started at once, so that their imports overlap the parent's set-up."""
    args = list(sys.argv[1:] if argv is None else argv)
    conn = child_connection(args)
    if len(args) > 2 and int(args[2]) > 0:
        from roslan.sensors.cameras.event_chains import prestart

        # (their renders use this run's context class: ChainJob.context_class)
        prestart(int(args[2]), warm=("roslan.pipeline.context",))
    queue: ByteQueue | None = None
    sender: threading.Thread | None = None
    code = 0
    try:
        job: WorkerJob = pickle.loads(conn.recv_bytes())
        queue = ByteQueue(job.queue_bytes)
        sender = threading.Thread(target=_sender, args=(conn, queue), daemon=True)
        sender.start()
        _run_job(job, queue.put)
    except BaseException as err:
        code = 1
        record = error_blob(err)
        with contextlib.suppress(BaseException):
            if queue is not None:
                queue.put(record)
            else:
                conn.send_bytes(record)
    if queue is not None and sender is not None:
        with contextlib.suppress(BaseException):
            queue.put(None)
        sender.join()
    end_child(conn, code)


# ---------------------------------------------------------------------------- parent side
_CHILD_CODE = "from roslan.pipeline.worker import main; main()"


class _Ready:
    """``Message.build`` of a worker's message: the ready wire bytes of ``store``'s flavour."""

    __slots__ = ("by_flavor",)

    def __init__(self, fmts: Sequence[str], datas: Sequence[bytes]) -> None:
        self.by_flavor = dict(zip(fmts, datas, strict=True))

    def __call__(self, store: MessageStore) -> bytes:
        return self.by_flavor[store.flavor]


class _Worker(ChildProcess):
    """One child process and its connection (parent side)."""

    error = WorkerError

    def __init__(self, names: list[str], helpers: int = 0) -> None:
        self.names = names
        super().__init__(_CHILD_CODE, "a sensor worker process", (str(helpers),))
        self.profile: dict[str, dict[str, Any]] = {}
        self.wait_s = 0.0
        self.done = False

    def describe(self) -> str:
        return f"the worker process (pid {self.proc.pid}) running {', '.join(self.names)}"

    def send_job(self, job: WorkerJob) -> None:
        try:
            self.send(job)
        except OSError as err:
            raise self.died("before finishing its sensors") from err

    def records(self, fmts: Sequence[str]) -> Iterator[MergeItem]:
        """This worker's messages as merge items; ends after its ``done`` record."""
        recv = self.conn.recv_bytes
        loads = pickle.loads
        perf = time.perf_counter
        while True:
            t0 = perf()
            try:
                blob = recv()
            except (EOFError, OSError) as err:
                raise self.died("before finishing its sensors") from err
            self.wait_s += perf() - t0
            rec = loads(blob)
            del blob  # not held while the message waits for the merge (a big scan)
            kind = rec[0]
            if kind == "m":
                _, t_ns, order, topic, msgtype, datas = rec
                yield t_ns, order, Message(t_ns, topic, msgtype, _Ready(fmts, datas))
            elif kind == "done":
                self.profile = rec[1]
                self.done = True
                return
            elif kind == "error":
                raise_error_record(rec, self.describe(), "the worker process")
            else:  # pragma: no cover - protocol bug
                msg = f"{self.describe()} sent an unknown record {kind!r}"
                raise WorkerError(msg)

    def finish(self) -> None:
        """Wait for a worker that sent ``done`` to exit (WorkerError if it fails)."""
        self.join()


class WorkerPool:
    """The worker processes of one run (parent side); ``helpers``: render helpers per
    event camera name (:func:`plan_helpers`), started by the worker running the camera.

    Start them early (:meth:`__init__` only launches the interpreters), :meth:`send` their
    jobs once the scene and OUTDIR are ready, merge :meth:`streams`, then :meth:`finish`;
    :meth:`kill` on any failure (before removing OUTDIR: children write into it).
    """

    def __init__(
        self,
        groups: Sequence[Sequence[int]],
        sensors: Sequence[SensorConfig],
        helpers: Mapping[str, int] | None = None,
    ) -> None:
        self.groups = [tuple(g) for g in groups]
        self.workers: list[_Worker] = []
        per_name = dict(helpers or {})
        try:
            for g in self.groups:
                names = [sensors[i].name for i in g]
                self.workers.append(_Worker(names, sum(per_name.get(n, 0) for n in names)))
        except BaseException:
            self.kill()
            raise

    @property
    def assigned(self) -> set[int]:
        return {i for g in self.groups for i in g}

    def send(self, make_job: Callable[[tuple[int, ...]], WorkerJob]) -> None:
        for g, w in zip(self.groups, self.workers, strict=True):
            w.send_job(make_job(g))

    def streams(self, fmts: Sequence[str]) -> list[Iterator[MergeItem]]:
        return [w.records(fmts) for w in self.workers]

    def profile(self) -> dict[str, dict[str, Any]]:
        out: dict[str, dict[str, Any]] = {}
        for w in self.workers:
            out.update(w.profile)
        return out

    def wait_seconds(self) -> list[dict[str, Any]]:
        return [{"sensors": w.names, "wait_s": w.wait_s} for w in self.workers]

    def finish(self) -> None:
        for w in self.workers:
            if not w.done:  # pragma: no cover - the merge consumed every stream
                msg = f"{w.describe()} did not finish"
                raise WorkerError(msg)
            w.finish()

    def kill(self) -> None:
        for w in self.workers:
            w.kill()
