"""The event camera on a growing trajectory (closed loop): its render instants, causally.

With the whole trajectory known (``simulate``), the event camera renders independent
chains, some of them in render helper processes, ahead of its stream
(:mod:`~roslan.sensors.cameras.event_chains`). In closed loop the trajectory only exists
up to the current step's end (:class:`~roslan.sensors.clock.Clock`), so the instants are
rendered one after the other here, each as soon as the horizon reaches it, with the very
same sampler steps (:func:`~roslan.sensors.cameras.event_chains.sample_instant`,
:func:`~roslan.sensors.cameras.event_chains.brightness_rate`): stepped with the same end,
the instants, and so every event, are a one-shot run's. With ``clock.align`` every step's
end is also sampled (a step's events then reach its end; the instants then depend on the
steps).

The forced instants (camera_info / APS at ``rate``, ground truth at
``ground_truth_rate``) are grids ``i / rate`` whose last instant depends on the end of the
run: :class:`ForcedInstants` reveals them a little past the horizon, enough for every
step the sampler may take, and exactly up to the end once it is known.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from roslan.events.sampling import AdaptiveSampler
from roslan.sensors.base import Message, SimContext, sample_times_ns, wait
from roslan.sensors.cameras.event_chains import (
    ChainSensor,
    Instant,
    _next,
    brightness_rate,
    sample_instant,
)
from roslan.sensors.cameras.flow_truth import flow_end_times
from roslan.sensors.clock import Clock

if TYPE_CHECKING:
    from roslan.events.model import EventGenerator
    from roslan.sensors.cameras.event_config import EventCameraConfig

__all__ = ["ForcedInstants", "causal_instants"]

_OPEN_END = 2**62
"""The sampler's end while the run's end is unknown (never reached)."""


class ForcedInstants:
    """The event camera's forced instants as far as they are known (see the module
    docstring); :meth:`cover` gives a sampler exact for a step from any instant up to
    the one asked for.

    Attributes:
        info, gt: (N,) int64 camera_info / APS and ground-truth instants known so far.
        info_set, gt_set: the same as sets (updated in place).
        truth_set: the ground-truth instants and the ends of the DSEC flow maps' intervals
            (rendered with their exact depth).
    """

    def __init__(self, config: EventCameraConfig, clock: Clock) -> None:
        self.config = config
        self.clock = clock
        self.gt_rate = config.ground_truth_rate or config.rate
        self.has_gt = bool(config.optic_flow or config.depthmap)
        self.until = -1
        self.info = np.zeros(0, np.int64)
        self.gt = np.zeros(0, np.int64)
        self.info_set: set[int] = set()
        self.gt_set: set[int] = set()
        self.truth_set: set[int] = set()
        self.sampler: AdaptiveSampler | None = None
        self.listeners: list[Callable[[ForcedInstants], None]] = []
        """Called after every extension (the stream's ground-truth instants)."""
        self._ended = False

    def cover(self, t_ns: int) -> AdaptiveSampler:
        """A sampler whose step from any instant ``<= t_ns`` is a one-shot run's."""
        c, clock = self.config, self.clock
        need = t_ns + max(1, round(1e9 / c.max_rate), round(1e9 / c.min_rate)) + 1
        stale = clock.ended and not self._ended
        if self.sampler is not None and not stale and need <= self.until:
            return self.sampler
        if clock.end_ns is not None:
            until, end, self._ended = clock.end_ns, clock.end_ns, True
        else:  # a little ahead at once: the grids are rebuilt seldom
            until, end = max(need, 2 * self.until), _OPEN_END
        self.until = until
        self.info = sample_times_ns(c.rate, until)
        self.gt = sample_times_ns(self.gt_rate, until) if self.has_gt else np.zeros(0, np.int64)
        # the flow maps' interval ends up to ``until``: a one-shot run's up to there
        ends = (
            flow_end_times(self.gt, c.flow_interval_ns, until)
            if c.optic_flow
            else np.zeros(0, np.int64)
        )
        truth = np.union1d(self.gt, ends)
        self.info_set.update(self.info.tolist())
        self.gt_set.update(self.gt.tolist())
        self.truth_set.update(truth.tolist())
        self.sampler = AdaptiveSampler(
            c.sampling,
            c.adaptive_lambda,
            c.min_rate,
            c.max_rate,
            end,
            np.union1d(self.info, truth),
        )
        for fn in self.listeners:
            fn(self)
        return self.sampler


def causal_instants(
    sensor: ChainSensor,
    ctx: SimContext,
    forced: ForcedInstants,
    gen: EventGenerator,
    floor: Callable[[int], int],
) -> Iterator[Instant | Message]:
    """The camera's rendered instants in time order, each rendered once the horizon
    reaches it, and a wait marker (``floor(last instant)``) whenever it must wait. The
    consumer runs ESIM on each instant before asking for the next (brightness sampling
    reads ESIM's state, ``gen``)."""
    clock = ctx.clock
    brightness = sensor.config.sampling == "brightness"
    prev_L: NDArray[np.float64] | None = None
    t_prev = 0
    t = 0
    while True:
        while not clock.ready(t):
            if clock.end_ns is not None:
                t = min(t, clock.end_ns)
                break
            yield wait(floor(t_prev))
            if clock.align and clock.end_ns is None and t_prev < clock.horizon_ns < t:
                t = clock.horizon_ns  # the new step's end is sampled
        sampler = forced.cover(t)
        inst, rate = sample_instant(sensor, ctx, t, t in forced.truth_set)
        if brightness:
            yield inst  # ESIM runs on it: the step reads its log intensity
            L = gen.lp.copy()
            rate = brightness_rate(L, prev_L, t, t_prev)
            prev_L = L
            nxt, capped = _next(sampler, t, rate)
            if capped:
                sensor.stats["capped"] = sensor.stats.get("capped", 0) + 1
        else:
            nxt, capped = _next(sampler, t, rate)
            yield inst._replace(capped=capped)
        t_prev = t
        if nxt is None or (clock.end_ns is not None and t >= clock.end_ns):
            return
        if clock.align and clock.end_ns is None and t < clock.horizon_ns < nxt:
            nxt = clock.horizon_ns  # the step's end is sampled
        t = nxt
