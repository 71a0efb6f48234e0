"""Time-parallel event camera: its render instants as independent chains.

ESIM's adaptive sampler (:class:`~roslan.events.sampling.AdaptiveSampler`) steps from an
instant by ``lambda / max |flow|`` of that instant's render, but never past the next
*forced* instant (the camera_info / APS stamps and the ground-truth stamps), which it
always samples exactly. So the instants from one forced instant up to the next, a
**chain**, depend only on the renders inside the chain: chain ``k`` starts at ``s_k``
(0, then every forced instant) and ends before ``s_(k+1)`` (the last one at the
trajectory's end). Chains can be rendered by any process, in any order; in time order
they are the serial sampler's instants exactly, and every render is the same pixels in
every process. So every output is byte-identical whatever the number of render helpers,
and ESIM still consumes the renders in time order.

* :func:`render_chain` renders one chain: each instant's luminance, its flow speed, the
  step to the next instant, and what the event stream needs of it (ground-truth flow
  and depth at ground-truth instants only).
* :class:`ChainFarm` hands chains to ``helpers`` render helper processes (fresh
  interpreters with their own OpenGL context, :mod:`roslan.io.child`) and yields the
  rendered instants in time order. This process renders a chain itself only while no
  helper is ready (they take a few seconds to start): once they are, it only feeds their
  renders to ESIM, packets and files, which are then its whole work (the critical path
  on a GPU machine, docs/performance.md). A sensor worker starts its cameras' helpers as
  it starts itself (:func:`prestart`): their imports and numba kernels load during the
  run's set-up, so they are ready about a renderer's build after the camera's first
  instant (on the dev machine the camera renders 1 of the default landing's 128 chains
  itself). At most :data:`IN_FLIGHT` chains per helper
  and a look-ahead of ``IN_FLIGHT * (helpers + 1) + 2`` chains are outstanding (bounded
  memory: a DAVIS346 chain is ~3 MB).

Brightness sampling reads ESIM's state between renders, so it has no chains: the event
camera renders it in one sequence (:func:`brightness_instants`).
"""

from __future__ import annotations

import contextlib
import importlib
import math
import pickle
import queue
import threading
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray

from roslan.events.sampling import AdaptiveSampler
from roslan.io import child
from roslan.sensors.base import SimContext

if TYPE_CHECKING:
    from roslan.events.model import EventGenerator
    from roslan.scene.model import Scene
    from roslan.sensors.cameras.event_config import EventCameraConfig
    from roslan.trajectory.base import Trajectory

__all__ = [
    "IN_FLIGHT",
    "ChainFarm",
    "ChainJob",
    "ChainSensor",
    "Instant",
    "brightness_instants",
    "brightness_rate",
    "chain_starts",
    "helper_main",
    "prestart",
    "render_chain",
    "sample_instant",
]

IN_FLIGHT = 2
"""Chains a render helper holds at most (assigned, not yet taken by the event stream)."""

_HELPER_CODE = "from roslan.sensors.cameras.event_chains import helper_main; helper_main()"

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]


class _FlowCamera(Protocol):
    def flow(self, depth: NDArray[np.floating], v: F64, w: F64) -> F32: ...

    def max_flow_speed(self, depth: NDArray[np.floating], v: F64, w: F64) -> float: ...


class ChainSensor(Protocol):
    """What chains need of the event camera
    (:class:`~roslan.sensors.cameras.event.EventCamera`, which imports this module):
    its config, its renders and the flow of its lens, and its counters."""

    @property
    def config(self) -> EventCameraConfig: ...

    @property
    def camera(self) -> _FlowCamera: ...

    @property
    def stats(self) -> dict[str, float]: ...

    def render(
        self, ctx: SimContext, t_ns: int, *, need_depth: bool, exact_depth: bool = False
    ) -> tuple[F32, F32 | None, F64, F64]: ...


class Instant(NamedTuple):
    """One rendered instant, as the event stream consumes it."""

    t: int
    lum: F32
    depth: F32 | None
    """Ground-truth depth (only at ground-truth instants, and the ends of the DSEC flow
    maps' intervals, of a camera with ``depthmap`` or ``optic_flow``)."""
    flow: F32 | None
    """Ground-truth flow (only at ground-truth instants of a camera with ``optic_flow``)."""
    capped: bool
    """The step after this instant was cut to ``1 / max_rate`` (ESIM's lambda not met)."""
    ids: NDArray[np.int32] | None = None
    """The object each pixel sees where ``depth`` is kept, in a scene whose objects move
    (the DSEC flow maps carry those points with their objects); else None."""


def chain_starts(sampler: AdaptiveSampler) -> list[int]:
    """The first instant of every chain: 0, then every forced instant (ns)."""
    return [0, *sampler.forced.tolist()]


def _next(sampler: AdaptiveSampler, t: int, rate: float) -> tuple[int | None, bool]:
    """The instant after ``t`` given the max rate of change there, and whether the step
    was capped by ``max_rate``."""
    capped = 0 < rate < math.inf and sampler.lam / rate * 1e9 < sampler.min_dt_ns
    return sampler.next_ns(t, rate), capped


def _render(
    sensor: ChainSensor, ctx: SimContext, t: int, gt: bool, *, need_depth: bool
) -> tuple[Instant, F32 | None, NDArray[np.float64], NDArray[np.float64]]:
    """The instant ``t`` rendered (``capped`` still False), with its depth (when
    ``need_depth`` or the ground truth needs it) and the camera's v and w: what the
    stream needs of it keeps the ground-truth flow and depth at ground-truth instants
    (``gt``) only."""
    c = sensor.config
    lum, depth, v, w = sensor.render(
        ctx, t, need_depth=need_depth or c.optic_flow or c.depthmap, exact_depth=gt
    )
    flow = sensor.camera.flow(depth, v, w) if depth is not None and c.optic_flow and gt else None
    keep = gt and (c.depthmap or c.optic_flow)
    ids = getattr(sensor, "last_ids", None) if keep else None
    return Instant(t, lum, depth if keep else None, flow, False, ids), depth, v, w


def render_chain(
    sensor: ChainSensor,
    ctx: SimContext,
    sampler: AdaptiveSampler,
    gt_set: set[int] | frozenset[int],
    start: int,
    stop: int | None,
) -> list[Instant]:
    """The instants from ``start`` until the sampler reaches ``stop`` (the next chain's
    start; None: the trajectory's end), rendered (optical-flow or fixed sampling)."""
    out: list[Instant] = []
    t: int | None = start
    while t is not None and (stop is None or t < stop):
        inst, speed = sample_instant(sensor, ctx, t, t in gt_set)
        t, capped = _next(sampler, t, speed)
        out.append(inst._replace(capped=capped))
    return out


def sample_instant(sensor: ChainSensor, ctx: SimContext, t: int, gt: bool) -> tuple[Instant, float]:
    """Instant ``t`` rendered (``capped`` still False) and the rate of change the
    sampler steps on after it: ``max |flow|`` (px/s) for optical-flow sampling, 0 for
    fixed sampling (``gt``: ``t`` is a ground-truth instant)."""
    flow_sampling = sensor.config.sampling == "optical_flow"
    inst, depth, v, w = _render(sensor, ctx, t, gt, need_depth=flow_sampling)
    speed = 0.0  # max |flow|, px/s
    if inst.flow is not None:  # (the ground-truth flow is at hand)
        speed = float(np.max(np.hypot(inst.flow[..., 0], inst.flow[..., 1])))
    elif depth is not None and flow_sampling:
        speed = sensor.camera.max_flow_speed(depth, v, w)
    return inst, speed if flow_sampling else 0.0


def brightness_rate(
    L: NDArray[np.float64], prev_L: NDArray[np.float64] | None, t: int, t_prev: int
) -> float:
    """Brightness sampling's rate of change at ``t``: ``max |dL/dt|`` of ESIM's log
    intensity between the last two instants (inf before there are two)."""
    if prev_L is None:
        return math.inf  # no estimate yet: smallest step
    return float(np.max(np.abs(L - prev_L))) / ((t - t_prev) * 1e-9)


def brightness_instants(
    sensor: ChainSensor,
    ctx: SimContext,
    sampler: AdaptiveSampler,
    gt_set: set[int],
    gen: EventGenerator,
) -> Iterator[Instant]:
    """The instants of brightness sampling, one at a time: the step after an instant reads
    ESIM's log intensity (``gen``) after the consumer has fed it that instant's render."""
    prev_L: NDArray[np.float64] | None = None
    t_prev = 0
    t: int | None = 0
    while t is not None:
        inst, _, _, _ = _render(sensor, ctx, t, t in gt_set, need_depth=False)
        yield inst  # the consumer runs ESIM on it before asking for the next
        L = gen.lp.copy()
        rate = brightness_rate(L, prev_L, t, t_prev)
        prev_L, t_prev = L, t
        t, capped = _next(sampler, t, rate)
        if capped:
            sensor.stats["capped"] = sensor.stats.get("capped", 0) + 1


# ---------------------------------------------------------------------------- helpers
@dataclass(frozen=True)
class ChainJob:
    """What a render helper needs (pickled to it; classes by name)."""

    sensor_class: Any
    config: EventCameraConfig
    trajectory: Trajectory
    scene: Scene
    sampler: AdaptiveSampler
    gt_times: tuple[int, ...]
    context_class: Callable[..., SimContext]
    """The class of the run's context (the pipeline's): the helper renders with
    ``context_class(trajectory, os.devnull, scene=scene)``."""


def _warm_helper(modules: Sequence[str]) -> None:
    """What a render helper needs before its job: the heavy imports (and ``modules``,
    named by whoever starts it: the run's context class) and the flow-speed kernel
    (numba's cache), so that a helper started early is ready soon after."""
    import cv2  # noqa: F401  (the event camera's module, which the job unpickles, needs it)
    import h5py  # noqa: F401  (likewise)

    import roslan.render.gl  # noqa: F401
    from roslan.events.sampling import max_flow_speed, pixel_rays

    for name in modules:
        importlib.import_module(name)
    K = np.array([[1.0, 0.0, 0.5], [0.0, 1.0, 0.5], [0.0, 0.0, 1.0]])
    v = np.zeros(3)
    max_flow_speed(np.ones((2, 2), np.float32), K, v, v, pixel_rays(K, 2, 2))


def helper_main(argv: Sequence[str] | None = None) -> None:
    """Render helper entry point (``python -c ... FD PID [MODULE...]``): warms up
    (importing the MODULEs too), gets a :class:`ChainJob`, says ``("ready",)`` once its
    renderer exists, then answers each ``("chain", k, start, stop)`` with
    ``("chain", k, instants)`` until ``("stop",)``."""
    import os
    import sys

    args = list(sys.argv[1:] if argv is None else argv)
    conn = child.child_connection(args)
    code = 0
    try:
        _warm_helper(args[2:])
        job: ChainJob = pickle.loads(conn.recv_bytes())
        sensor = job.sensor_class(job.config)
        # (renders only: an OUTDIR that cannot be written to)
        ctx = job.context_class(job.trajectory, Path(os.devnull), scene=job.scene)
        ctx.renderer()  # the GL context and the scene's buffers, before saying ready
        gt_set = frozenset(job.gt_times)
        dumps = pickle.dumps
        conn.send_bytes(dumps(("ready",)))
        while True:
            cmd = pickle.loads(conn.recv_bytes())
            if cmd[0] == "stop":
                break
            _, k, start, stop = cmd
            chain = render_chain(sensor, ctx, job.sampler, gt_set, start, stop)
            conn.send_bytes(dumps(("chain", k, chain), protocol=pickle.HIGHEST_PROTOCOL))
    except BaseException as err:
        code = 1
        with contextlib.suppress(BaseException):
            conn.send_bytes(child.error_blob(err))
    child.end_child(conn, code)


_PRESTARTED: list[_Helper] = []
"""Render helpers started ahead (:func:`prestart`), waiting for an event camera's job."""


def prestart(n: int, warm: Sequence[str] = ()) -> None:
    """Start ``n`` render helper interpreters now (a sensor worker does this as it starts,
    before its job arrives): their imports (with the modules ``warm``: the module of the
    run's context class) then overlap the run's set-up, and the next :class:`ChainFarm` of
    this process takes them instead of starting its own."""
    for _ in range(max(0, int(n))):
        _PRESTARTED.append(_Helper(warm))


def _take_helpers(n: int) -> list[_Helper]:
    """``n`` helpers: the prestarted ones first, then new ones."""
    out = [_PRESTARTED.pop(0) for _ in range(min(n, len(_PRESTARTED)))]
    try:
        while len(out) < n:
            out.append(_Helper())
    except BaseException:
        for h in out:
            h.kill()
        raise
    return out


class _Helper(child.ChildProcess):
    """One render helper process (owner side) and the thread reading its answers."""

    def __init__(self, warm: Sequence[str] = ()) -> None:
        super().__init__(_HELPER_CODE, "a render helper process", tuple(warm))
        self.name = "?"
        self.index = 0
        self.ready = False
        self.in_flight = 0
        self.inbox: queue.Queue[tuple[_Helper, Any]] | None = None
        self.reader: threading.Thread | None = None

    def describe(self) -> str:
        return f"render helper {self.index} (pid {self.proc.pid}) of event camera {self.name}"

    def start(self, job: ChainJob, index: int, inbox: queue.Queue[tuple[_Helper, Any]]) -> None:
        """Send it the job of camera ``job.config.name``; its answers go to ``inbox``."""
        self.name, self.index, self.inbox = job.config.name, index, inbox
        self.send(job)
        self.reader = threading.Thread(
            target=self._read, name=f"{self.name}-helper{index}", daemon=True
        )
        self.reader.start()

    def send(self, obj: Any) -> None:
        try:
            super().send(obj)
        except OSError:
            # it is gone: its reader thread puts its last record (its error, or eof) in
            # the inbox, which says more than a broken pipe; send it nothing more
            self.ready = False

    def _read(self) -> None:
        assert self.inbox is not None
        try:
            while True:
                rec = pickle.loads(self.conn.recv_bytes())
                self.inbox.put((self, rec))
                if rec[0] == "error":
                    return
        except (EOFError, OSError):
            self.inbox.put((self, ("eof",)))

    def finish(self) -> None:
        """Ask it to stop and reap it (ChildError if it fails to exit cleanly)."""
        self.send(("stop",))
        try:
            self.join()
        finally:
            if self.reader is not None:
                self.reader.join(child.JOIN_TIMEOUT_S)


class ChainFarm:
    """The rendered instants of an optical-flow or fixed-rate event camera, in time order,
    from this process and ``helpers`` render helper processes (see the module docstring).

    ``render_here=False``: this process renders nothing, not even while its helpers start
    (benchmarks, tests; with no helper it still renders everything itself). Use as a
    context manager: leaving it stops the helpers (killed on an error)."""

    def __init__(
        self,
        sensor: ChainSensor,
        ctx: SimContext,
        sampler: AdaptiveSampler,
        gt_times: NDArray[np.int64],
        helpers: int,
        *,
        render_here: bool = True,
    ) -> None:
        self.sensor, self.ctx, self.sampler = sensor, ctx, sampler
        self.gt_set = frozenset(int(t) for t in gt_times.tolist())
        self.starts = chain_starts(sampler)
        self.inbox: queue.Queue[tuple[_Helper, Any]] = queue.Queue()
        self.helpers: list[_Helper] = []
        self.results: dict[int, list[Instant]] = {}
        self.next_k = 0  # first chain not yet given to anybody
        self.lookahead = IN_FLIGHT * (helpers + 1) + 2
        self.rendered_here = 0
        n = min(int(helpers), len(self.starts))
        self.render_here = render_here or n == 0
        if n > 0:
            job = ChainJob(
                type(sensor),
                sensor.config,
                ctx.trajectory,
                ctx.scene,
                sampler,
                tuple(sorted(self.gt_set)),
                type(ctx),
            )
            try:
                self.helpers = _take_helpers(n)
                for i, h in enumerate(self.helpers):
                    h.start(job, i, self.inbox)
            except BaseException:
                self.kill()
                raise

    def __enter__(self) -> ChainFarm:
        return self

    def __exit__(self, exc_type: object, exc: object, tb: object) -> None:
        if exc_type is None:
            self.close()
        else:
            self.kill()

    # ------------------------------------------------------------------ the stream
    def instants(self) -> Iterator[Instant]:
        """Every rendered instant, in time order."""
        for k in range(len(self.starts)):
            yield from self._chain(k)

    def _chain(self, k: int) -> list[Instant]:
        while True:
            self._drain(block=False)
            self._assign(k)
            if k in self.results:
                return self.results.pop(k)
            if self.render_here and k == self.next_k:  # no helper is ready to take it
                self.next_k += 1
                return self._render_here(k)
            self._drain(block=True)

    def _span(self, k: int) -> tuple[int, int | None]:
        """Chain ``k``'s first instant and the next chain's (None: the last chain)."""
        return self.starts[k], self.starts[k + 1] if k + 1 < len(self.starts) else None

    def _render_here(self, k: int) -> list[Instant]:
        self.rendered_here += 1
        return render_chain(self.sensor, self.ctx, self.sampler, self.gt_set, *self._span(k))

    def _assign(self, k: int) -> None:
        """Give ready helpers chains, up to the look-ahead past chain ``k``."""
        limit = min(len(self.starts), k + self.lookahead)
        for h in self.helpers:
            while h.ready and h.in_flight < IN_FLIGHT and self.next_k < limit:
                j = self.next_k
                self.next_k += 1
                h.send(("chain", j, *self._span(j)))
                h.in_flight += 1

    def _drain(self, *, block: bool) -> None:
        """Take the helpers' answers (wait for one if ``block``)."""
        while True:
            try:
                h, rec = self.inbox.get(block=block, timeout=None)
            except queue.Empty:
                return
            block = False
            kind = rec[0]
            if kind == "ready":
                h.ready = True
            elif kind == "chain":
                _, j, chain = rec
                self.results[j] = chain
                h.in_flight -= 1
            elif kind == "error":
                child.raise_error_record(rec, h.describe(), "the render helper process")
            else:  # eof: it died
                raise h.died("while rendering")

    # ------------------------------------------------------------------ the end
    def close(self) -> None:
        """Stop the helpers after the last chain (ChildError if one fails)."""
        helpers, self.helpers = self.helpers, []
        try:
            for h in helpers:
                h.finish()
        except BaseException:
            for h in helpers:
                h.kill()
            raise
        self.sensor.stats["chains"] = len(self.starts)
        self.sensor.stats["chains_rendered_here"] = self.rendered_here

    def kill(self) -> None:
        helpers, self.helpers = self.helpers, []
        for h in helpers:
            h.kill()
