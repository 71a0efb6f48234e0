"""Touchdown, collision and the landing's outcome, step by step.

The rules are ``simulate``'s (:mod:`roslan.vehicle`, :mod:`roslan.scene.clearance`):

* **touchdown**: the contact point (feet's centroid at the lowest foot, or the grasp
  point on a perch) reaches the goal's surface plane, or a contact point (any foot, the
  grasp point) meets scene geometry: the first such instant, to the nanosecond;
* **collision**: a point of the body or any sensor's origin or near plane meets scene
  geometry (no tolerance; the contact points may touch), or lies inside a closed object
  at the step's start or end, as does a contact point more than 1 mm deep
  (:mod:`roslan.scene.containment`).

Inside each control step the vehicle's points are followed through ``SAMPLES`` instants
(straight segments between them, cast with Embree); the goal-plane crossing is then
bisected on the closed-form state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import NDArray

from roslan.scene.clearance import SegmentCaster, path_hit, vehicle_points
from roslan.scene.containment import vehicle_contacts, vehicle_inside
from roslan.vehicle import contact_point, resolve_contact

if TYPE_CHECKING:
    from roslan.config.closed_loop import ClosedLoopConfig
    from roslan.config.sim import SimConfig
    from roslan.env.dynamics import DynamicsTrajectory
    from roslan.scene.model import Scene

__all__ = ["ContactModel", "Outcome", "StepEvent", "is_success", "reward_terms"]

F64 = NDArray[np.float64]

SAMPLES = 9
"""Instants per control step at which the vehicle's paths are cast (ends included)."""

CONTACT_TOL = 1e-6
"""m: a contact point this close to the goal's plane touches it (a soft tau landing
closes the height gap with zero speed: the plane is reached tangentially)."""


@dataclass(frozen=True)
class StepEvent:
    """What ended the motion inside a step."""

    kind: Literal["touchdown", "collision"]
    t_ns: int
    what: str
    """``goal plane``, or the object touched / hit and by what."""


@dataclass(frozen=True)
class Outcome:
    """The contact's figures (episode.json; all None without a touchdown)."""

    touchdown_time: float | None = None
    touchdown_vertical_speed: float | None = None
    touchdown_horizontal_speed: float | None = None
    position_error: float | None = None
    heading_error: float | None = None

    def as_dict(self) -> dict[str, Any]:
        return {
            "touchdown_time": self.touchdown_time,
            "touchdown_vertical_speed": self.touchdown_vertical_speed,
            "touchdown_horizontal_speed": self.touchdown_horizontal_speed,
            "position_error": self.position_error,
            "heading_error": self.heading_error,
        }


class ContactModel:
    """The contact and collision rules of one episode (module docstring).

    Args:
        config: the episode's config (vehicle, sensors, the goal of the contact point).
        scene: the scene (None: only the goal plane).
        traj: the vehicle's trajectory (base_link's goal).
        caster: the scene's ray caster, the sensors' own (the episode's
            :class:`~roslan.render.backends.SceneBackends`); needed with a scene.
    """

    def __init__(
        self,
        config: SimConfig,
        scene: Scene | None,
        traj: DynamicsTrajectory,
        caster: SegmentCaster | None = None,
    ) -> None:
        goal = config.trajectory.goal
        if scene is not None and caster is None:
            msg = "ContactModel: a scene needs its ray caster (SceneBackends.caster())"
            raise ValueError(msg)
        self.scene = scene
        self.caster = caster
        self.traj = traj
        which = resolve_contact(config.vehicle, scene, goal)
        self.c_body = contact_point(config.vehicle, which)
        self.goal = np.asarray(goal.position, dtype=np.float64)
        self.normal = traj.R_world_goal[:, 2].copy()
        vp = vehicle_points(config.vehicle, config.sensors)
        self.body, self.labels = vp.points, vp.labels
        feet = np.asarray(config.vehicle.feet if which == "feet" else [config.vehicle.grasp])
        self.contacts = np.asarray(feet, dtype=np.float64).reshape(-1, 3)
        self.all_contacts = vehicle_contacts(config.vehicle)  # feet and grasp: inside tests

    def height(self, t: F64, st: Any = None) -> F64:
        """(n,) height of the contact point above the goal's plane at instants ``t`` (s)
        (``st``: the trajectory's state at ``t``, if read already)."""
        if st is None:
            st = self.traj.state(t)
        c = st.position + np.einsum("nij,j->ni", st.R_world_body, self.c_body)
        out: F64 = (c - self.goal) @ self.normal
        return out

    def _crossing(self, t0_ns: int, t1_ns: int, t: F64, st: Any) -> int | None:
        """First instant (ns) in [t0, t1] with the contact point on (within
        :data:`CONTACT_TOL`) or below the goal's plane; ``t``: the step's samples,
        ``st`` the state there."""
        h = self.height(t, st)
        below = np.flatnonzero(h <= CONTACT_TOL)
        if not below.size:
            return None
        i = int(below[0])
        if i == 0:
            return t0_ns
        lo = round(float(t[i - 1]) * 1e9)
        hi = min(round(float(t[i]) * 1e9), t1_ns)
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if self.height(np.array([mid * 1e-9]))[0] <= CONTACT_TOL:
                hi = mid
            else:
                lo = mid
        return hi

    def check_step(self, t0_ns: int, t1_ns: int) -> StepEvent | None:
        """The first touchdown or collision in the step ``(t0, t1]`` (ns), or None."""
        events: list[StepEvent] = []
        t = np.linspace(t0_ns, t1_ns, SAMPLES) * 1e-9
        st = self.traj.state(t)  # (read once: the plane crossing and the scene's tests)
        td = self._crossing(t0_ns, t1_ns, t, st)
        if td is not None:
            events.append(StepEvent("touchdown", td, "the goal plane"))
        if self.scene is not None:
            assert self.caster is not None
            hit = path_hit(self.scene, self.caster, self.body, t, st.position, st.R_world_body)
            if hit is not None:
                what = f"{self.labels[hit.point]} hit object {hit.obj!r}"
                events.append(StepEvent("collision", _ns(hit.time, t0_ns, t1_ns), what))
            ends = [0, -1]  # entering crosses a surface (above): inside without crossing
            held = vehicle_inside(
                self.scene, t[ends], st.position[ends], st.R_world_body[ends], self.body,
                self.labels, *self.all_contacts,
            )  # fmt: skip
            if held is not None:  # inside a closed object at the step's start or end
                what = f"{held[1]} inside object {held[2]!r}"
                events.append(StepEvent("collision", _ns(held[0], t0_ns, t1_ns), what))
            foot = path_hit(self.scene, self.caster, self.contacts, t, st.position, st.R_world_body)
            if foot is not None:
                what = f"object {foot.obj!r}"
                events.append(StepEvent("touchdown", _ns(foot.time, t0_ns, t1_ns), what))
        if not events:
            return None
        # the earliest; at a tie a touchdown wins (the contact points may touch)
        return min(events, key=lambda e: (e.t_ns, e.kind != "touchdown"))

    def outcome(self, t_ns: int) -> Outcome:
        """The contact figures at touchdown instant ``t_ns`` (readable on the trajectory)."""
        st = self.traj.state(np.array([t_ns * 1e-9]))
        R = st.R_world_body[0]
        omega_world = R @ st.omega_body[0]
        arm = R @ self.c_body
        v = st.velocity[0] + np.cross(omega_world, arm)
        vn = float(v @ self.normal)
        vh = float(np.linalg.norm(v - vn * self.normal))
        c = st.position[0] + arm
        yaw = float(st.gaps[0, 5])
        heading = math.atan2(math.sin(yaw), math.cos(yaw))
        return Outcome(
            touchdown_time=t_ns * 1e-9,
            touchdown_vertical_speed=abs(vn),
            touchdown_horizontal_speed=vh,
            position_error=float(np.linalg.norm(c - self.goal)),
            heading_error=abs(heading),
        )


def _ns(t: float, lo: int, hi: int) -> int:
    return min(max(round(t * 1e9), lo), hi)


def reward_terms(
    cl: ClosedLoopConfig, dt: float, outcome: Outcome | None, success: bool, collided: bool
) -> float:
    """One step's reward (docs/guide/closed-loop.md "Reward")."""
    w = cl.reward
    r = -w.time * dt
    if collided:
        r -= w.collision
    if outcome is not None and outcome.touchdown_time is not None:
        assert outcome.touchdown_vertical_speed is not None
        assert outcome.touchdown_horizontal_speed is not None
        assert outcome.position_error is not None
        assert outcome.heading_error is not None
        r -= w.contact_speed * (
            outcome.touchdown_vertical_speed + outcome.touchdown_horizontal_speed
        )
        r -= w.position * outcome.position_error + w.heading * outcome.heading_error
        if success:
            r += w.success
    return r


def is_success(cl: ClosedLoopConfig, outcome: Outcome) -> bool:
    """Whether a touchdown counts as a landing (``closed_loop.success``)."""
    s = cl.success
    return (
        outcome.touchdown_vertical_speed is not None
        and outcome.touchdown_vertical_speed <= s.max_vertical_speed
        and (outcome.touchdown_horizontal_speed or 0.0) <= s.max_horizontal_speed
        and (outcome.position_error or 0.0) <= s.max_position_error
    )
