"""Landing trajectories: the :class:`Trajectory` protocol and its two sources, the
closed-form tau landing (:class:`TauTrajectory`) and a pose file fitted with splines
(:class:`FileTrajectory`); :func:`make_trajectory` picks one from a ``trajectory:`` block."""

from __future__ import annotations

from roslan.trajectory.base import COMPONENTS, GAPS, State, Trajectory
from roslan.trajectory.config import Approach, Flapping, Initial, Kappa, TrajectoryConfig
from roslan.trajectory.generator import TauTrajectory, TrajectoryWarning
from roslan.trajectory.spline import FileTrajectory, make_trajectory
from roslan.trajectory.tau import Terminal
from roslan.trajectory.vibration import VibratingTrajectory
from roslan.trajectory.vibration_config import Harmonic, VibrationBand, VibrationConfig

__all__ = [
    "COMPONENTS",
    "GAPS",
    "Approach",
    "FileTrajectory",
    "Flapping",
    "Harmonic",
    "Initial",
    "Kappa",
    "State",
    "TauTrajectory",
    "Terminal",
    "Trajectory",
    "TrajectoryConfig",
    "TrajectoryWarning",
    "VibratingTrajectory",
    "VibrationBand",
    "VibrationConfig",
    "make_trajectory",
]
