"""Tau-theory landing trajectories: closed-form gaps in the goal frame F, mapped to the world."""

from __future__ import annotations

from roslan.trajectory.config import Approach, Flapping, Initial, Kappa, TrajectoryConfig
from roslan.trajectory.generator import COMPONENTS, GAPS, State, Trajectory, TrajectoryWarning
from roslan.trajectory.tau import Terminal

__all__ = [
    "COMPONENTS",
    "GAPS",
    "Approach",
    "Flapping",
    "Initial",
    "Kappa",
    "State",
    "Terminal",
    "Trajectory",
    "TrajectoryConfig",
    "TrajectoryWarning",
]
