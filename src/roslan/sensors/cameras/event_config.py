"""Keys of the event camera (``type: event_camera``) and the commercial sensors it
models (:data:`SENSOR_PRESETS`); the sensor is :class:`roslan.sensors.cameras.event.EventCamera`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any, Literal

from pydantic import Field, model_validator

from roslan.config.base import FiniteFloat
from roslan.events.model import EVENT_PRESETS, EventModelParams
from roslan.limits import MAX_RATE_HZ
from roslan.sensors.base import LabelsKey, SensorConfig
from roslan.sensors.cameras.config import CameraIntrinsics, intrinsics_model
from roslan.sensors.cameras.model import CameraModel

__all__ = ["SENSOR_PRESETS", "EventCameraConfig", "SensorPreset"]

Positive = Annotated[FiniteFloat, Field(gt=0)]
NonNegative = Annotated[FiniteFloat, Field(ge=0)]


@dataclass(frozen=True)
class SensorPreset:
    """A commercial sensor: resolution, a typical lens and its ``realistic`` pixel parameters.

    ``timestamp_resolution`` (s) is the tick of the sensor's event timestamp counter
    (iniVation DAVIS346 / DVXplorer and Prophesee's EVT formats: 1 us).
    """

    width: int
    height: int
    focal_px: float
    aps: bool
    realistic: dict[str, float]
    timestamp_resolution: float = 1e-6


SENSOR_PRESETS: dict[str, SensorPreset] = {
    # iniVation DAVIS346: 18.5 um pixels, 4 mm lens; APS frames. Noise: `roslan fit-noise` of
    # a real DAVIS346 in daylight (docs/realism.md, docs/event-model.md)
    "davis346": SensorPreset(
        346, 260, 216.0, True,
        {"threshold_pos": 0.25, "threshold_neg": 0.25, "threshold_sigma": 0.03, "refractory": 5e-4,
         "cutoff_hz": 300.0, "leak_rate": 0.0026, "shot_noise_rate": 0.015,
         "shot_noise_knee": 0.0022},
    ),
    # iniVation DVXplorer: 9 um pixels, 4 mm lens; events only
    "dvxplorer": SensorPreset(
        640, 480, 444.0, False,
        {"threshold_pos": 0.2, "threshold_neg": 0.2, "threshold_sigma": 0.03, "refractory": 2e-4,
         "cutoff_hz": 500.0, "leak_rate": 0.05, "shot_noise_rate": 0.1},
    ),
    # Prophesee Gen4 (IMX636): 4.86 um pixels, 4 mm lens; events only
    "gen4": SensorPreset(
        1280, 720, 823.0, False,
        {"threshold_pos": 0.2, "threshold_neg": 0.2, "threshold_sigma": 0.02, "refractory": 1e-4,
         "cutoff_hz": 1000.0, "leak_rate": 0.02, "shot_noise_rate": 0.1},
    ),
}  # fmt: skip


class EventCameraConfig(SensorConfig, LabelsKey, CameraIntrinsics):
    """``type: event_camera``. ``rate`` is the APS frame / camera_info rate (Hz).

    Unset pixel parameters come from ``preset`` (``clean``: ideal ESIM pixel;
    ``realistic``: the sensor's typical non-idealities); unset geometry from ``sensor``.
    """

    type: Literal["event_camera"] = "event_camera"
    sensor: Literal["davis346", "dvxplorer", "gen4"] = "davis346"
    preset: Literal["clean", "realistic"] = "realistic"
    # pixel model overrides
    threshold_pos: Positive | None = None
    threshold_neg: Positive | None = None
    threshold_sigma: NonNegative | None = None
    refractory_period: NonNegative | None = None
    """s."""
    cutoff_hz: NonNegative | None = None
    """Photoreceptor low-pass cutoff, Hz (0: off)."""
    intensity_dependent_lowpass: bool | None = None
    leak_rate: NonNegative | None = None
    """Leak events per pixel, Hz."""
    shot_noise_rate: NonNegative | None = None
    """Shot-noise events per pixel, Hz, of a dark pixel at nominal thresholds (v2e: the
    rate falls linearly to a quarter at intensity 1, and scales with nominal / actual
    threshold)."""
    shot_noise_intensity_factor: Annotated[FiniteFloat, Field(ge=0, le=1)] | None = None
    """Shot-noise rate at intensity 1 relative to intensity 0 (v2e's linear form: 0.25)."""
    shot_noise_knee: Annotated[FiniteFloat, Field(ge=0, le=1)] | None = None
    """0: v2e's linear intensity dependence; > 0: the rate is ``shot_noise_rate / (1 + I /
    shot_noise_knee)`` (halved at ``I = shot_noise_knee``; fitted to a real DAVIS346 by
    ``roslan fit-noise``, docs/realism.md)."""
    leak_phase: Literal["steady", "zero"] | None = None
    """Initial phase of the leak: ``steady`` (default; as if the sensor had been running)
    or ``zero`` (every pixel reset at the start: no leak event before ``1 / leak_rate``)."""
    log_eps: Positive | None = None
    label_rate: Annotated[FiniteFloat, Field(gt=0, le=MAX_RATE_HZ)] | None = None
    """With ``output.labels``: the rate (Hz) of the ``tracks.npy`` boxes (default: at the
    APS frame instants, every ``1 / rate``); left out of run.json when unset."""
    timestamp_resolution: Annotated[FiniteFloat, Field(ge=0, le=1e-3)] | None = None
    """Tick of the event timestamps, s: event times are floored to multiples of it, as a
    sensor's timestamp counter does (a whole number of ns, or 0 for exact ns times).
    Default: the sensor's (1 us) with ``preset: realistic``, 0 with ``clean``."""
    # adaptive sampling
    sampling: Literal["optical_flow", "brightness", "fixed"] = "optical_flow"
    adaptive_lambda: Positive = 0.5
    """px for optical_flow, log intensity for brightness."""
    min_rate: Annotated[FiniteFloat, Field(gt=0, le=MAX_RATE_HZ)] = 100.0
    """Lowest render rate, Hz."""
    max_rate: Annotated[FiniteFloat, Field(gt=0, le=MAX_RATE_HZ)] = 500.0
    """Highest render rate, Hz (``fixed``: always this rate). It caps ESIM's step: where
    ``lambda / max rate of change`` is shorter, the run is faster but interpolates over
    more than ``adaptive_lambda`` (``stats['capped']`` counts such steps)."""
    # outputs
    packet_duration: Positive = 0.001
    """s of events per EventArray."""
    packet_events: Annotated[int, Field(gt=0)] | None = None
    """Events per EventArray instead of a duration."""
    aps: bool | None = None
    """APS frames on ``<topic>/image_raw`` at ``rate`` (default: the sensor has them)."""
    event_image: bool = True
    """rgb8 event frames on ``<topic>/event_image`` at ``rate`` (bag viewers cannot draw
    EventArray): the events of the last ``event_image_window``, ON blue, OFF red."""
    event_image_window: Annotated[FiniteFloat, Field(gt=0, le=1.0)] = 0.01
    """s of events in each event_image frame."""
    optic_flow: bool = False
    """Optical-flow ground truth: ``<topic>/optic_flow`` (32FC2, the instantaneous motion
    field, px/s) at ``ground_truth_rate`` and DSEC flow maps in ``flow/`` (the true
    displacement over ``flow_interval``, :mod:`roslan.sensors.cameras.flow_truth`)."""
    flow_interval: Annotated[FiniteFloat, Field(gt=0, le=60.0)] = 0.1
    """s from ``from_timestamp_us`` to ``to_timestamp_us`` of each DSEC flow map (DSEC's
    benchmark interval, 0.1 s, by default)."""
    flow_sky: Literal["valid", "invalid"] = "invalid"
    """DSEC flow of pixels where nothing is hit: ``invalid`` (as DSEC, no ground truth) or
    ``valid`` (the flow of the point at infinity: the rotation alone)."""
    depthmap: bool = False
    ground_truth_rate: Annotated[FiniteFloat, Field(gt=0, le=MAX_RATE_HZ)] | None = None
    """Rate of optic_flow / depthmap, Hz (default ``rate``)."""
    write_txt: bool = True
    write_h5: bool = True

    @model_validator(mode="after")
    def _check(self) -> EventCameraConfig:
        if self.min_rate > self.max_rate:
            msg = f"min_rate = {self.min_rate} must be <= max_rate = {self.max_rate}"
            raise ValueError(msg)
        us = self.flow_interval * 1e6
        if us < 1 or abs(us - round(us)) > 1e-6 * us:
            msg = (
                f"flow_interval = {self.flow_interval} s: use a whole number of microseconds, "
                "at least 1e-6 (forward_timestamps.txt is in microseconds; DSEC: 0.1)"
            )
            raise ValueError(msg)
        r = self.timestamp_resolution
        if r:  # (None or 0: the default or exact times)
            ns = r * 1e9
            if ns < 1 or abs(ns - round(ns)) > 1e-6 * ns:
                msg = (
                    f"timestamp_resolution = {r} s: use 0 (exact ns times) or a whole "
                    "number of nanoseconds, at least 1e-9 (e.g. 1e-6 for 1 us)"
                )
                raise ValueError(msg)
        return self

    # -------------------------------------------------------------- derived
    @property
    def preset_info(self) -> SensorPreset:
        return SENSOR_PRESETS[self.sensor]

    def camera_model(self) -> CameraModel:
        """Intrinsics: the calibration file or inline keys; unset resolution / focal
        length from the sensor preset (its typical lens; scaled with the resolution)."""
        if self.calibration is not None:
            return super().camera_model()
        sp = self.preset_info
        w, h = self.resolution or (sp.width, sp.height)
        update: dict[str, Any] = {"resolution": (w, h)}
        if self.fx is None and self.fy is None:
            update["fx"] = update["fy"] = sp.focal_px * w / sp.width
        filled = self.model_copy(update=update)
        return intrinsics_model(filled, name=self.name, source=f"sensor {self.name!r}")

    @property
    def timestamp_resolution_ns(self) -> int:
        """The event timestamp tick in ns (1: exact)."""
        r = self.timestamp_resolution
        if r is None:
            r = self.preset_info.timestamp_resolution if self.preset == "realistic" else 0.0
        return max(1, round(r * 1e9))

    @property
    def sub_microsecond_times(self) -> bool:
        """Event times carry digits below 1 us (``events.h5`` then adds ``events/t_ns``)."""
        return self.timestamp_resolution_ns % 1000 != 0

    @property
    def flow_interval_ns(self) -> int:
        """``flow_interval`` in whole ns."""
        return round(self.flow_interval * 1e9)

    @property
    def has_aps(self) -> bool:
        return self.preset_info.aps if self.aps is None else self.aps

    def model_params(self) -> EventModelParams:
        base = EVENT_PRESETS[self.preset]
        if self.preset == "realistic":
            base = base.with_overrides(**self.preset_info.realistic)
        return base.with_overrides(
            threshold_pos=self.threshold_pos,
            threshold_neg=self.threshold_neg,
            threshold_sigma=self.threshold_sigma,
            refractory=self.refractory_period,
            cutoff_hz=self.cutoff_hz,
            intensity_dependent=self.intensity_dependent_lowpass,
            leak_rate=self.leak_rate,
            shot_noise_rate=self.shot_noise_rate,
            shot_noise_intensity_factor=self.shot_noise_intensity_factor,
            shot_noise_knee=self.shot_noise_knee,
            leak_phase=self.leak_phase,
            log_eps=self.log_eps,
        )
