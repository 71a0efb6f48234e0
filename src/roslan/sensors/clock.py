"""The causal contract between the sensor engine and the sensors: how far they may read.

A sensor's ``messages(ctx)`` generator reads the trajectory at instants of its own
choosing. In closed loop the trajectory only exists up to the end of the current control
step, the **horizon** (:attr:`Clock.horizon_ns`, inclusive); the end of the run is only
known when the episode ends (:attr:`Clock.end_ns`). A sensor therefore

* takes its instants from :meth:`Clock.grid` (the fixed grids ``i / rate`` whose last
  instant depends on the end) or checks :meth:`Clock.ready` before reading any other
  instant;
* yields a **wait marker** (:func:`roslan.sensors.base.wait`, a
  :class:`~roslan.sensors.base.Message` on the empty topic) when it needs an instant past
  the horizon. The marker carries the smallest stamp the sensor may still yield (its
  *floor*): the engine releases the step's messages below every sensor's floor, in one
  stamp order, so that the concatenated steps equal one run over the whole trajectory;
* resumes, after the marker, with a larger horizon, or with the end known
  (:attr:`Clock.ended`), and then ends its stream.

``roslan simulate`` runs the same generators on a :meth:`Clock.fixed` clock: the horizon
is the end from the start, nothing ever waits, and look-ahead (render helpers, the
auto-exposure metering pass) is allowed there only (:attr:`Clock.lookahead`).

Taps: with :attr:`Clock.taps` set (closed loop), sensors also hand what they measured to
:meth:`Clock.tap`, typed: each kind's step output (:mod:`roslan.sensors.measurements`,
declared in its :class:`~roslan.sensors.registry.SensorSpec`; no copy). The engine hands
them to the caller once per step (:class:`~roslan.pipeline.engine.StepOutput`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from roslan.sensors.measurements import Measurement

__all__ = ["Clock", "Grid"]


class Clock:
    """How far the sensors may read the trajectory now.

    Args:
        horizon_ns: the last readable instant (ns, inclusive).
        end_ns: the end of the run when known (then ``horizon_ns == end_ns``), else None.
        lookahead: the whole trajectory is known in advance (``simulate``): sensors may
            read ahead (render helpers, the auto-exposure metering pass).
        align: closed loop: a sensor that chooses its own instants (the event camera's
            adaptive sampling) samples every horizon exactly, so that a step's output
            covers the step up to its end.
    """

    def __init__(
        self,
        horizon_ns: int,
        end_ns: int | None = None,
        *,
        lookahead: bool = False,
        align: bool = False,
    ) -> None:
        self.horizon_ns = int(horizon_ns)
        self.end_ns = None if end_ns is None else int(end_ns)
        self.lookahead = lookahead
        self.align = align
        self.taps: dict[str, list[Measurement]] | None = None
        """Per sensor name, the measurements handed to :meth:`tap` this step (None: taps
        off, :meth:`tap` does nothing)."""

    @classmethod
    def fixed(cls, end_ns: int) -> Clock:
        """The clock of a trajectory known in advance (``simulate``): horizon = end."""
        return cls(end_ns, end_ns, lookahead=True)

    @property
    def ended(self) -> bool:
        """Whether the end of the run is known (no instant past it will ever exist)."""
        return self.end_ns is not None

    def ready(self, t_ns: int) -> bool:
        """Whether the trajectory may be read at ``t_ns``."""
        return t_ns <= self.horizon_ns

    def advance(self, horizon_ns: int) -> None:
        """Move the horizon forward (the engine; never backwards)."""
        if self.end_ns is not None:
            msg = "the clock has ended"
            raise RuntimeError(msg)
        if horizon_ns < self.horizon_ns:
            msg = f"horizon {horizon_ns} ns is before the current one ({self.horizon_ns} ns)"
            raise ValueError(msg)
        self.horizon_ns = int(horizon_ns)

    def end(self, end_ns: int) -> None:
        """Fix the end of the run (the engine's ``finish``); the horizon becomes it."""
        if end_ns < self.horizon_ns:
            msg = f"end {end_ns} ns is before the horizon ({self.horizon_ns} ns)"
            raise ValueError(msg)
        self.horizon_ns = self.end_ns = int(end_ns)

    def tap(self, name: str, measurement: Measurement) -> None:
        """Hand one measurement of sensor ``name`` (its kind's step output, a
        :mod:`roslan.sensors.measurements` dataclass) to the engine (kept by reference:
        the caller must not modify its arrays afterwards)."""
        taps = self.taps
        if taps is not None:
            taps.setdefault(name, []).append(measurement)

    def grid(
        self,
        final: Callable[[int], NDArray[np.int64]],
        prefix: Callable[[int], NDArray[np.int64]] | None = None,
        lead_ns: int = 0,
    ) -> Grid:
        """A sensor's instants revealed as the horizon grows (:class:`Grid`)."""
        return Grid(self, final, prefix, lead_ns)


class Grid:
    """The instants of a sensor whose set depends on the run's end (``i / rate`` up to the
    end), revealed in order as the horizon grows.

    Args:
        clock: the engine's clock.
        final: the instants of a run ending at ``end_ns`` (the very array a one-shot run
            uses, e.g. ``lambda end: sample_times_ns(rate, end)``).
        prefix: the instants certainly in ``final(end)`` for every end ``>= h`` (default
            ``final``: true of ``sample_times_ns``); only those ``+ lead_ns <= h`` are
            revealed before the end is known.
        lead_ns: how far past an instant its measurement reads the trajectory (a scan's
            sweep, a shutter window's end).
    """

    def __init__(
        self,
        clock: Clock,
        final: Callable[[int], NDArray[np.int64]],
        prefix: Callable[[int], NDArray[np.int64]] | None = None,
        lead_ns: int = 0,
    ) -> None:
        self.clock = clock
        self.final = final
        self.prefix = prefix or final
        self.lead_ns = int(lead_ns)
        self.done = 0
        """Instants handed out so far."""
        self._known = np.zeros(0, np.int64)
        self.closed = False

    def _refresh(self) -> None:
        c = self.clock
        if c.end_ns is not None:
            if not self.closed:
                self._known = np.asarray(self.final(c.end_ns), dtype=np.int64)
                self.closed = True
            return
        h = c.horizon_ns
        known = np.asarray(self.prefix(h), dtype=np.int64)
        self._known = known[known + self.lead_ns <= h]

    @property
    def next_ns(self) -> int | None:
        """The next instant if already known (None: not yet, or none left)."""
        return int(self._known[self.done]) if self.done < self._known.size else None

    def take(self, block: int) -> tuple[int, NDArray[np.int64]] | None:
        """The index of the next instant revealed and the instants from it (at most up to
        the next multiple of ``block`` of the running index, so that chunks end where a
        one-shot run ends them); an empty array when the grid is exhausted (the end is
        known and all were taken); None when the sensor must wait for the horizon."""
        if self.done >= self._known.size:
            self._refresh()
        n = self._known.size
        i0 = self.done
        if i0 >= n:
            return (i0, np.zeros(0, np.int64)) if self.closed else None
        i1 = min(n, (i0 // block + 1) * block)
        self.done = i1
        return i0, self._known[i0:i1]
