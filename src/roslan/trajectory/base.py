"""The interface every trajectory implements: one :class:`Trajectory` protocol, two sources.

:class:`~roslan.trajectory.generator.TauTrajectory` is the closed-form tau-theory landing
(the default and the reference); :class:`~roslan.trajectory.spline.FileTrajectory` flies a
recorded or planned pose file through smooth splines. Sensors, the pipeline, the clearance
check and the plots only use this protocol: the full :class:`State` (pose, twist,
accelerations, and the 18 gap components in the goal frame F) at any instants.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from roslan.errors import TrajectoryError
from roslan.trajectory.config import TrajectoryConfig

__all__ = [
    "COMPONENTS",
    "DEFAULT_GROUND_TRUTH_RATE",
    "GAPS",
    "GrowingTrajectory",
    "HorizonError",
    "HorizonGuard",
    "State",
    "Trajectory",
    "check_duration",
    "ground_truth_times_ns",
    "sample_times_ns",
]

F64 = NDArray[np.float64]

GAPS = ("x", "y", "z", "roll", "pitch", "yaw")
"""Order of the six gaps (frame F) in every (N, 6) array."""

COMPONENTS = (
    *GAPS,
    *(f"v{g}" for g in GAPS),
    *(f"a{g}" for g in GAPS),
)
"""The 18 components in trajectory.csv order: gaps, rates, accelerations."""

DEFAULT_GROUND_TRUTH_RATE = 200.0
"""Hz of the ground-truth record (``output.ground_truth_rate``'s default)."""


@dataclass(frozen=True, slots=True)
class State:
    """Trajectory state at N instants. Arrays are float64.

    Attributes:
        t: (N,) trajectory time, s.
        gaps, rates, accels: (N, 6) the 18 components in frame F, order :data:`GAPS`
            (m, rad; m/s, rad/s; m/s^2, rad/s^2).
        position, velocity, acceleration: (N, 3) of base_link in the world frame.
        R_world_body: (N, 3, 3) orientation of base_link in the world.
        quat_xyzw: (N, 4) the same orientation as a unit quaternion (w >= 0).
        omega_body, alpha_body: (N, 3) angular velocity (rad/s) and acceleration (rad/s^2)
            of base_link, in base_link.
    """

    t: F64
    gaps: F64
    rates: F64
    accels: F64
    position: F64
    velocity: F64
    acceleration: F64
    R_world_body: F64
    quat_xyzw: F64
    omega_body: F64
    alpha_body: F64

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def components(self) -> F64:
        """(N, 18) array in :data:`COMPONENTS` order."""
        return np.concatenate([self.gaps, self.rates, self.accels], axis=1)


def check_duration(duration: float, sample_dt: float, T: float) -> None:
    """Refuse a landing too long to simulate (README "Limits")."""
    from roslan.errors import TrajectoryError
    from roslan.limits import MAX_DURATION_S, MAX_TRAJECTORY_SAMPLES

    if not math.isfinite(duration) or duration > MAX_DURATION_S:
        msg = (
            f"trajectory: touchdown time z0 / (k * descent rate) = {T:.4g} s plus hold gives "
            f"{duration:.4g} s; at most {MAX_DURATION_S:g} s (raise k or the descent rate)"
        )
        raise TrajectoryError(msg)
    if duration / sample_dt > MAX_TRAJECTORY_SAMPLES:
        msg = (
            f"trajectory.sample_dt = {sample_dt:g}: {duration:.4g} s / sample_dt is more than "
            f"{MAX_TRAJECTORY_SAMPLES} samples; use a larger sample_dt"
        )
        raise TrajectoryError(msg)


def sample_times_ns(rate_hz: float, duration_ns: int, offset_ns: int = 0) -> NDArray[np.int64]:
    """Instants ``offset + i / rate`` (integer ns, no float drift) within [0, duration]."""
    if duration_ns < offset_ns:
        return np.zeros(0, dtype=np.int64)
    n = int(np.floor((duration_ns - offset_ns) * rate_hz / 1e9 + 1e-9)) + 1
    i = np.arange(n, dtype=np.float64)
    return offset_ns + np.round(i * (1e9 / rate_hz)).astype(np.int64)


def ground_truth_times_ns(rate_hz: float, duration_ns: int) -> NDArray[np.int64]:
    """Instants of the ground-truth record: every ``1 / rate`` from 0, plus the end of the
    run exactly (``duration_ns``) where that falls between two samples. The bag's
    ``/ground_truth/*`` topics and ``groundtruth.txt`` share them."""
    times = sample_times_ns(rate_hz, duration_ns)
    if times[-1] < duration_ns:
        times = np.append(times, np.int64(duration_ns))
    return times


class Trajectory(Protocol):
    """A path of base_link in the world, sampled at any instants.

    Motion ends at ``T`` (touchdown, or the last pose of a file); the robot then rests for
    ``hold`` seconds, so samples are defined on ``[0, duration]`` (clamped outside).
    Implementations may subclass this protocol to inherit the nanosecond helpers.
    """

    config: TrajectoryConfig
    T: float
    """End of the motion (touchdown), s."""
    hold: float
    """Rest after ``T``, s."""
    duration: float
    """``T + hold``, s."""
    p_world_goal: F64
    """(3,) origin of the goal frame F in the world."""
    R_world_goal: F64
    """(3, 3) orientation of F in the world."""

    def state(self, t: ArrayLike) -> State:
        """The full state at trajectory times ``t`` (s)."""
        ...

    def gaps_at(self, t: ArrayLike) -> tuple[F64, F64, F64, F64]:
        """The 18 components in F: (t, gaps, rates, accels), each (N,) / (N, 6)."""
        ...

    def table_times(self) -> F64:
        """Instants of the exported table (trajectory.csv), s."""
        ...

    def summary(self) -> dict[str, Any]:
        """JSON-ready description (summary.json): ``T``, ``duration``, peaks, and what
        defines the trajectory (tau parameters, or the file and its fit residual)."""
        ...

    def warnings(self) -> list[str]:
        """Human-readable notes on hard terminal behaviour (empty when none)."""
        ...

    def state_ns(self, t_ns: ArrayLike) -> State:
        """Full state at integer-nanosecond trajectory times."""
        return self.state(np.asarray(t_ns, dtype=np.int64).astype(np.float64) * 1e-9)

    def pose_twist_ns(self, t_ns: int) -> tuple[F64, F64, F64, F64]:
        """(3,) position, (3,) velocity, (3, 3) R_world_body and (3,) omega_body at one
        integer-nanosecond instant: :meth:`state_ns`'s values (an implementation may
        compute them more cheaply, bit for bit the same)."""
        st = self.state_ns(np.array([t_ns], dtype=np.int64))
        return st.position[0], st.velocity[0], st.R_world_body[0], st.omega_body[0]

    @property
    def duration_ns(self) -> int:
        """``duration`` in integer nanoseconds (rounded)."""
        return round(self.duration * 1e9)

    @property
    def touchdown_ns(self) -> int:
        """``T`` in integer nanoseconds (rounded)."""
        return round(self.T * 1e9)


_ANY_TIME_NS = 2**62
"""A horizon past every instant."""


class HorizonError(TrajectoryError):
    """A trajectory was read past its horizon: the instant it is defined up to so far
    (a closed-loop trajectory grows one control step at a time; a sensor that reads
    past the current step's end is not causal)."""


class GrowingTrajectory(Trajectory, Protocol):
    """A :class:`Trajectory` that grows step by step (closed loop: the vehicle's state
    is known up to the end of the last control step).

    Every method may be called for instants ``<= horizon_ns`` only (they raise
    :class:`HorizonError` past it). ``duration``, ``duration_ns``, ``T`` and
    ``table_times`` are only meaningful once ``finished`` (the end of the run is then
    known); until then a sensor learns how far it may read from the engine's clock
    (:class:`roslan.sensors.clock.Clock`), never from the trajectory's duration.
    """

    @property
    def horizon_ns(self) -> int:
        """Last instant (trajectory ns) the trajectory may be read at, inclusive."""
        ...

    @property
    def finished(self) -> bool:
        """True once the run's end is fixed (``duration`` is then final)."""
        ...


class HorizonGuard:
    """A :class:`Trajectory` wrapper that raises :class:`HorizonError` when read past a
    settable horizon: the causality check of every sensor type (tests) and a debugging
    aid. ``duration`` / ``duration_ns`` / ``T`` / ``table_times`` raise until
    :meth:`finish` (a causal sensor never asks them before the end is known).

    Args:
        trajectory: the wrapped trajectory (its values are returned unchanged).
        horizon_ns: the initial horizon (ns, inclusive).
    """

    def __init__(self, trajectory: Trajectory, horizon_ns: int = 0) -> None:
        self.inner = trajectory
        self.config = trajectory.config
        self.hold = trajectory.hold
        self.p_world_goal = trajectory.p_world_goal
        self.R_world_goal = trajectory.R_world_goal
        self.horizon_ns = int(horizon_ns)
        self.finished = False
        self.max_read_ns = -1
        """The latest instant read so far (ns)."""

    def set_horizon(self, horizon_ns: int) -> None:
        """Allow reads up to ``horizon_ns`` (never decreases)."""
        self.horizon_ns = max(self.horizon_ns, int(horizon_ns))

    def finish(self) -> None:
        """The end is known: ``duration`` etc. may be read, and any instant (a finished
        trajectory is defined everywhere: clamped past its end, as every trajectory)."""
        self.finished = True
        self.horizon_ns = _ANY_TIME_NS

    def _check_ns(self, t_ns: NDArray[np.int64]) -> None:
        if t_ns.size == 0:
            return
        top = int(t_ns.max())
        self.max_read_ns = max(self.max_read_ns, top)
        if top > self.horizon_ns:
            msg = f"trajectory read at t = {top} ns, past its horizon {self.horizon_ns} ns"
            raise HorizonError(msg)

    def _check_s(self, t: ArrayLike) -> None:
        # a time in seconds reads the trajectory at the nanosecond it rounds to
        ts = np.atleast_1d(np.asarray(t, dtype=np.float64))
        self._check_ns(np.round(ts * 1e9).astype(np.int64))

    def _need_end(self, what: str) -> None:
        if not self.finished:
            msg = f"trajectory.{what} read before the run's end is known"
            raise HorizonError(msg)

    @property
    def T(self) -> float:
        self._need_end("T")
        return self.inner.T

    @property
    def duration(self) -> float:
        self._need_end("duration")
        return self.inner.duration

    @property
    def duration_ns(self) -> int:
        self._need_end("duration_ns")
        return self.inner.duration_ns

    @property
    def touchdown_ns(self) -> int:
        self._need_end("touchdown_ns")
        return self.inner.touchdown_ns

    def state(self, t: ArrayLike) -> State:
        self._check_s(t)
        return self.inner.state(t)

    def state_ns(self, t_ns: ArrayLike) -> State:
        self._check_ns(np.atleast_1d(np.asarray(t_ns, dtype=np.int64)))
        return self.inner.state_ns(t_ns)

    def pose_twist_ns(self, t_ns: int) -> tuple[F64, F64, F64, F64]:
        self._check_ns(np.array([t_ns], dtype=np.int64))
        return self.inner.pose_twist_ns(t_ns)

    def gaps_at(self, t: ArrayLike) -> tuple[F64, F64, F64, F64]:
        self._check_s(t)
        return self.inner.gaps_at(t)

    def table_times(self) -> F64:
        self._need_end("table_times")
        return self.inner.table_times()

    def summary(self) -> dict[str, Any]:
        self._need_end("summary")
        return self.inner.summary()

    def warnings(self) -> list[str]:
        return self.inner.warnings()
