"""The optional ``trajectory.vibration:`` block: body vibration every sensor sees
(:class:`roslan.trajectory.vibration.VibratingTrajectory`; docs/realism.md)."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field, model_validator

from roslan.config.base import Angle, FiniteFloat, StrictModel

__all__ = ["Harmonic", "VibrationBand", "VibrationConfig"]

NonNegative = Annotated[FiniteFloat, Field(ge=0)]
Axes3 = tuple[NonNegative, NonNegative, NonNegative]
Frequency = Annotated[FiniteFloat, Field(gt=0, le=5000.0)]


class Harmonic(StrictModel):
    """A sinusoid at ``frequency`` (Hz): amplitudes of the body's acceleration (m/s^2) and
    angular rate (rad/s) along base_link x, y, z; ``phase`` (rad) shared by the axes."""

    frequency: Frequency
    accel: Axes3 = (0.0, 0.0, 0.0)
    gyro: Axes3 = (0.0, 0.0, 0.0)
    phase: Angle = 0.0


class VibrationBand(StrictModel):
    """Band-limited broadband vibration: ``components`` sinusoids per axis at frequencies
    spread over ``band`` (Hz; stratified, jittered per seed) with random phases, scaled
    to the RMS acceleration ``accel_rms`` (m/s^2) and angular rate ``gyro_rms`` (rad/s)
    along base_link x, y, z (a flat spectrum of those levels over the band)."""

    band: tuple[Frequency, Frequency]
    accel_rms: Axes3 = (0.0, 0.0, 0.0)
    gyro_rms: Axes3 = (0.0, 0.0, 0.0)
    components: Annotated[int, Field(ge=1, le=2000)] = 64

    @model_validator(mode="after")
    def _ordered(self) -> VibrationBand:
        lo, hi = self.band
        if not lo < hi:
            msg = f"band = [{lo}, {hi}] Hz: the low edge must be below the high edge"
            raise ValueError(msg)
        return self


class VibrationConfig(StrictModel):
    """Body vibration: ``harmonics`` (e.g. flapping or rotor harmonics) plus ``broadband``
    bands, as a small displacement and rotation of base_link about its motion. It fades
    out (C2) over the last ``fade`` seconds before touchdown and is off in the hold;
    ``seed`` draws the broadband frequencies and phases (same seed, same vibration)."""

    harmonics: tuple[Harmonic, ...] = ()
    broadband: tuple[VibrationBand, ...] = ()
    fade: Annotated[FiniteFloat, Field(gt=0, le=60.0)] = 0.2
    """s."""
    seed: Annotated[int, Field(ge=0, le=2**32 - 1)] = 0

    @model_validator(mode="after")
    def _something(self) -> VibrationConfig:
        if not self.harmonics and not self.broadband:
            msg = "vibration: give harmonics and/or broadband (or remove the block)"
            raise ValueError(msg)
        return self
