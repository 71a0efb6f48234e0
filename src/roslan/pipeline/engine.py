"""One causal sensor engine behind ``simulate`` and the closed-loop environment.

:class:`SensorEngine` runs the ground truth and every sensor's message generator
(:class:`~roslan.sensors.base.Sensor`) on one :class:`~roslan.sensors.clock.Clock`:

* ``simulate``: a fixed clock (horizon = end from the start); :meth:`SensorEngine.sources`
  are the generators' lazy streams, merged by stamp into the bags
  (:func:`~roslan.pipeline.merge.pump`), exactly as before the engine existed;
* closed loop: a growing clock. :meth:`SensorEngine.advance` moves the horizon to the end
  of the control step and runs every generator until it needs the trajectory past it (it
  yields a wait marker, :func:`~roslan.sensors.base.wait`); :meth:`SensorEngine.finish`
  fixes the end and runs them out, then closes the sensors.

Each step returns a :class:`StepOutput`: the messages no later message can precede (below
every unfinished sensor's floor), in the one-shot merge order ``(stamp, component)``, so
that the steps' messages concatenated are a one-shot run's messages; and the step's
*taps*, the raw arrays each sensor measured (IMU samples, events, images, ranges).
"""

from __future__ import annotations

import contextlib
import heapq
import itertools
import time
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

from roslan.errors import SensorError
from roslan.pipeline.merge import CheckedStream, MergeItem, tagged
from roslan.sensors.base import WAIT_TOPIC, Message, Sensor, SimContext
from roslan.sensors.measurements import Measurement

__all__ = ["SensorEngine", "StepOutput"]


@dataclass
class StepOutput:
    """What one engine step produced.

    Attributes:
        horizon_ns: the step's end (trajectory ns): every sensor has measured up to it.
        messages: the messages released by this step, in the one-shot merge order
            (stamp, then component: ground truth, sensors in config order). A message
            whose stamp precedes the step's end may come in a later step (a frame whose
            shutter window or a scan whose sweep ends after it, an event packet still
            open), never out of order.
        taps: per sensor name, what it measured this step, in time order: a list of its
            kind's step outputs (:meth:`~roslan.sensors.clock.Clock.tap`, the dataclasses
            of :mod:`roslan.sensors.measurements`): ``ImuSamples`` (``t`` (N,) int64 ns,
            ``acc`` (N, 3) m/s^2, ``gyro`` (N, 3) rad/s, sensor frame); ``EventSamples``
            (``x``, ``y`` (N,) pixel, ``t`` (N,) int64 ns, ``p`` (N,) int8 1 ON / 0
            OFF); ``Frame`` (``t`` stamp ns, ``image`` as published, ``eye``);
            ``RangeSamples`` (``t``, ``range`` m); ``LaserScan`` (``t``, ``ranges``,
            ``intensities``); ``CloudScan`` (``t``, ``points``, the cloud's structured
            array). Each also reads like a mapping (``tap["t"]``).
    """

    horizon_ns: int
    messages: list[Message] = field(default_factory=list)
    taps: dict[str, list[Measurement]] = field(default_factory=dict)

    def tap(self, name: str) -> list[Measurement]:
        """The taps of sensor ``name`` (empty when it measured nothing this step)."""
        return self.taps.get(name, [])


class _Component:
    """One message generator of the engine and where it stands."""

    def __init__(self, order: int, stream: CheckedStream) -> None:
        self.order = order
        self.stream = stream
        self.it: Iterator[Message] = iter(stream)
        self.floor = 0
        self.done = False

    def pull(self, out: list[tuple[int, int, int, Message]], counter: Iterator[int]) -> None:
        """Messages until the generator waits (its floor) or ends."""
        order = self.order
        for msg in self.it:
            if msg.topic == WAIT_TOPIC:
                self.floor = msg.t_ns
                return
            out.append((msg.t_ns, order, next(counter), msg))
        self.done = True


class SensorEngine:
    """The ground truth and the sensors of a run on one clock (see the module docstring).

    Args:
        ctx: the sensors' context; ``ctx.clock`` is the engine's clock (fixed for a
            trajectory known in advance, growing in closed loop).
        sensors: every sensor of the run, in config order (sensor ``i`` merges with order
            ``i + 1``).
        ground_truth: the ground-truth component (order 0), or None.
        skip: indices of sensors run elsewhere (``simulate``'s worker processes).
        profile: time each generator (:attr:`CheckedStream.seconds`).
    """

    def __init__(
        self,
        ctx: SimContext,
        sensors: Sequence[Sensor],
        ground_truth: Any = None,
        *,
        skip: Iterable[int] = (),
        profile: bool = False,
    ) -> None:
        self.ctx = ctx
        self.clock = ctx.clock
        self.sensors = list(sensors)
        skipped = set(skip)
        self.local = [i for i in range(len(self.sensors)) if i not in skipped]
        self.streams: list[CheckedStream] = []
        self.orders: list[int] = []
        if ground_truth is not None:
            topics = {t.topic for t in ground_truth.topics()}
            self.streams.append(
                CheckedStream("ground_truth", ground_truth.messages(ctx), topics, profile)
            )
            self.orders.append(0)
        for i in self.local:
            s = self.sensors[i]
            topics = {t.topic for t in s.topics()}
            self.streams.append(CheckedStream(s.config.name, s.messages(ctx), topics, profile))
            self.orders.append(i + 1)
        self._comps = [_Component(o, st) for o, st in zip(self.orders, self.streams, strict=True)]
        self._held: list[tuple[int, int, int, Message]] = []
        self._counter = itertools.count()
        self._closed = False

    # ------------------------------------------------------------------ one shot
    def sources(self) -> list[Iterator[MergeItem]]:
        """The components' lazy streams tagged with their merge key, for a fixed clock
        (``simulate``: one step over the whole trajectory, merged by the caller with any
        worker process's streams)."""
        if not self.clock.ended:
            msg = "SensorEngine.sources needs a fixed clock (the end known)"
            raise RuntimeError(msg)
        for st in self.streams:
            st.waits = False
        return [tagged(o, st) for o, st in zip(self.orders, self.streams, strict=True)]

    # ------------------------------------------------------------------ stepping
    def advance(self, horizon_ns: int) -> StepOutput:
        """Run every sensor up to ``horizon_ns`` (inclusive, trajectory ns) and return
        the step's messages and taps (the trajectory must be readable up to it)."""
        self.clock.advance(horizon_ns)
        return self._step()

    def finish(self, end_ns: int, *, close: bool = True) -> StepOutput:
        """End the run at ``end_ns`` (>= the last horizon): the sensors' last messages,
        then (``close``) the sensors' ``close`` (their dataset files)."""
        self.clock.end(end_ns)
        out = self._step()
        pending = [c for c in self._comps if not c.done]
        if pending:
            names = ", ".join(c.stream.name for c in pending)
            msg = f"sensors still waiting after the end of the run: {names}"
            raise SensorError(msg)
        if close:
            self.close_sensors()
        return out

    def _step(self) -> StepOutput:
        clock = self.clock
        taps: dict[str, list[Measurement]] | None = None
        if clock.taps is not None:
            taps = clock.taps = {}
        held, counter = self._held, self._counter
        fresh: list[tuple[int, int, int, Message]] = []
        for comp in self._comps:
            if not comp.done:
                comp.pull(fresh, counter)
        for item in fresh:
            heapq.heappush(held, item)
        floors = [c.floor for c in self._comps if not c.done]
        limit = min(floors) if floors else None
        out: list[Message] = []
        while held and (limit is None or held[0][0] < limit):
            out.append(heapq.heappop(held)[3])
        result = StepOutput(clock.horizon_ns, out, taps if taps is not None else {})
        if taps is not None:
            clock.taps = {}
        return result

    def enable_taps(self) -> None:
        """Collect the sensors' taps (:attr:`StepOutput.taps`) from now on."""
        if self.clock.taps is None:
            self.clock.taps = {}

    # ------------------------------------------------------------------ the end
    def close_sensors(self) -> dict[str, float]:
        """Every local sensor's ``close`` (dataset files); its seconds per sensor."""
        if self._closed:
            return {}
        self._closed = True
        seconds: dict[str, float] = {}
        for i in self.local:
            s = self.sensors[i]
            t0 = time.perf_counter()
            s.close(self.ctx)
            seconds[s.config.name] = time.perf_counter() - t0
        return seconds

    def abort(self) -> None:
        """Close every generator (sensors stop their threads and helper processes), then
        every local sensor's files (``close``: its dataset files are abandoned, but no
        file object is left for the garbage collector, which would warn of it)."""
        for st in self.streams:
            with contextlib.suppress(BaseException):
                st.close()
        if not self._closed:
            self._closed = True
            for i in self.local:
                with contextlib.suppress(Exception):
                    self.sensors[i].close(self.ctx)
