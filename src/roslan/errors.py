"""Exception hierarchy: one root, one subclass per concern.

Every error a *user* can cause (bad config, bad file, existing output) derives
from :class:`RoslanError`; the CLI prints its message and exits with status 2
instead of a traceback.
"""

from __future__ import annotations

__all__ = [
    "ActionError",
    "ConfigError",
    "Note",
    "OutputError",
    "PlotError",
    "RecordingError",
    "RenderError",
    "RoslanError",
    "SceneError",
    "SensorError",
    "TrajectoryError",
]


class RoslanError(Exception):
    """Root of every error roslan raises on purpose."""


class ConfigError(RoslanError):
    """A configuration file or value is invalid.

    The message names the file, the key path, the offending value and what is
    allowed, e.g. ``sim.yaml: trajectory.k = 1.5: must satisfy 0 < k <= 1``.
    """


class TrajectoryError(ConfigError):
    """Trajectory parameters that describe no valid landing."""


class SceneError(ConfigError):
    """A scene file, mesh or texture that cannot be loaded."""


class SensorError(ConfigError):
    """A sensor configuration or calibration file that is invalid."""


class OutputError(RoslanError):
    """An output directory that cannot be written (exists, not writable...)."""


class RenderError(RoslanError):
    """The OpenGL renderer could not be created or used."""


class PlotError(RoslanError):
    """A plot cannot be drawn: an input it needs is missing or unreadable."""


class RecordingError(RoslanError):
    """An event recording that cannot be read, or whose noise cannot be fitted."""


class Note(UserWarning):
    """Not a problem, a line worth knowing (a default roslan chose for the user): the
    command line prints it as ``note: ...`` instead of ``warning: ...``."""


class ActionError(RoslanError, ValueError):
    """An action given to :class:`roslan.env.LandingEnv` that cannot be flown (NaN, wrong
    shape)."""
