"""Event-camera simulation core (NumPy and numba kernels, no rendering): the ESIM pixel
model with v2e-style non-idealities, adaptive sampling, ROS packing and streaming event
files."""

from __future__ import annotations

from roslan.events.divergence import DivergenceEstimate, DivergenceEstimator, DivergenceParams
from roslan.events.files import EventH5Writer, EventTextWriter, format_events_txt
from roslan.events.model import (
    EVENT_PRESETS,
    EventBatch,
    EventGenerator,
    EventModelParams,
    log_intensity,
)
from roslan.events.reference import NumpyEventGenerator
from roslan.events.ros import EVENT_ARRAY, pack_event_array
from roslan.events.sampling import (
    AdaptiveSampler,
    camera_twist,
    max_flow_speed,
    motion_field,
    pixel_rays,
)

__all__ = [
    "EVENT_ARRAY",
    "EVENT_PRESETS",
    "AdaptiveSampler",
    "DivergenceEstimate",
    "DivergenceEstimator",
    "DivergenceParams",
    "EventBatch",
    "EventGenerator",
    "EventH5Writer",
    "EventModelParams",
    "EventTextWriter",
    "NumpyEventGenerator",
    "camera_twist",
    "format_events_txt",
    "log_intensity",
    "max_flow_speed",
    "motion_field",
    "pack_event_array",
    "pixel_rays",
]
