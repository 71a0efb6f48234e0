"""Documented physical and resource bounds (docs/guide/simulation.md, "Limits"), and the
pre-flight check that refuses a run that cannot fit before anything is written.

The schema uses the constants below as field ranges; :func:`preflight` adds what needs the
whole job (trajectory duration x rates, ROS 1 time range, frame sizes).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from roslan.errors import ConfigError

__all__ = [
    "MAX_COORD_M",
    "MAX_DURATION_S",
    "MAX_FLAP_HZ",
    "MAX_FRAME_PIXELS",
    "MAX_MESSAGES",
    "MAX_RATE_HZ",
    "MAX_SEED",
    "MAX_SIZE_M",
    "MAX_TRAJECTORY_SAMPLES",
    "MAX_WORKING_BYTES",
    "MIN_SAMPLE_DT_S",
    "MIN_SIZE_M",
    "ROS1_MAX_TIME_NS",
    "check_seed",
    "format_bytes",
    "preflight",
]

MAX_SEED = 2**63 - 1
"""Seeds are integers in [0, 2**63 - 1]."""
MAX_RATE_HZ = 10_000.0
"""Highest rate of any sensor or of the ground truth (Hz)."""
MIN_SAMPLE_DT_S = 1e-4
"""Smallest ``trajectory.sample_dt`` (s)."""
MAX_DURATION_S = 86_400.0
"""Longest trajectory, touchdown time plus hold (s): one day."""
MAX_TRAJECTORY_SAMPLES = 10_000_000
"""Most trajectory samples (duration / sample_dt)."""
MAX_FLAP_HZ = 1000.0
"""Highest flapping frequency (Hz)."""
MAX_COORD_M = 1e6
"""Largest absolute position coordinate of a pose, a goal or a mesh vertex (m)."""
MAX_SIZE_M = 1e5
"""Largest primitive size, radius, scale or texture scale in a scene."""
MIN_SIZE_M = 1e-4
"""Smallest dimension of a scene primitive (box/plane size, radius, height; perch length
and radius), m: thinner shapes collapse into zero-area triangles in float32."""
MAX_FRAME_PIXELS = 8192 * 8192
"""Largest camera or event-camera image (width x height)."""
MAX_MESSAGES = 50_000_000
"""Most messages of one run (every sensor's rate x duration, plus the ground truth)."""
MAX_WORKING_BYTES = 8 * 1024**3
"""Largest estimated working memory of one frame sensor (one frame and its render
buffers): 8 GiB."""
ROS1_MAX_TIME_NS = (2**32 - 1) * 10**9
"""ROS 1 stamps are unsigned 32-bit seconds: start_time + duration must stay below this."""

_BYTES_PER_PIXEL = 64
"""Working bytes per pixel of a frame sensor (float64 buffers of colour, depth, the event
model's state and supersampling), an upper estimate used by the pre-flight check."""

_SUPERSAMPLE_BYTES = 40
"""Working bytes per sample of a camera's ``supersampling`` render (RGBA + 1/z float32
targets, the read-back colour and depth)."""


def check_seed(seed: Any, where: str) -> int:
    """``seed`` as an int in [0, MAX_SEED]; ConfigError naming ``where`` otherwise."""
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= MAX_SEED:
        text = str(seed) if len(str(seed)) <= 40 else str(seed)[:37] + "..."
        msg = f"{where} = {text}: must be an integer in [0, 2**63 - 1]"
        raise ConfigError(msg)
    return seed


def format_bytes(n: float) -> str:
    """``1.2 GB``, ``350 MB``, ``12 kB`` (decimal units, 2 significant digits)."""
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            v = n / scale
            return f"{v:.1f} {unit}" if v < 10 else f"{v:.0f} {unit}"
    return f"{n:.0f} B"


def preflight(config: Any, duration_s: float, formats: Sequence[str], source: str) -> None:
    """Refuse a run whose stamps, sample count or frame memory cannot fit (ConfigError).

    ``source`` names the config file in the message."""
    out = config.output
    end_ns = out.start_time + math.ceil(duration_s * 1e9)
    if "ros1" in formats and end_ns > ROS1_MAX_TIME_NS:
        msg = (
            f"{source}: output.start_time = {out.start_time} ns + the trajectory's "
            f"{duration_s:.6g} s ends at {end_ns / 1e9:.6g} s: ROS 1 stamps are unsigned "
            f"32-bit seconds (at most {ROS1_MAX_TIME_NS // 10**9} s, year 2106); "
            "choose an earlier start_time or write only ros2"
        )
        raise ConfigError(msg)
    total = math.ceil(out.ground_truth_rate * duration_s) + 1
    for i, s in enumerate(config.sensors):
        n = math.ceil(float(s.rate) * duration_s) + 1
        total += n
        res = getattr(s, "resolution", None)
        w, h = res if isinstance(res, tuple) and len(res) == 2 else (0, 0)
        if w * h > MAX_FRAME_PIXELS:
            msg = (
                f"{source}: sensors[{i}] ({s.name}): resolution = {w}x{h}: at most "
                f"{MAX_FRAME_PIXELS} pixels (e.g. 8192x8192)"
            )
            raise ConfigError(msg)
        scale = float(getattr(s, "render_scale", None) or 1.0)
        ss = int(getattr(s, "supersampling", 1) or 1)  # the reference's N x N larger render
        need = w * h * scale * scale * (_BYTES_PER_PIXEL + _SUPERSAMPLE_BYTES * (ss * ss - 1))
        if need > MAX_WORKING_BYTES:
            msg = (
                f"{source}: sensors[{i}] ({s.name}): a {w}x{h} frame needs about "
                f"{format_bytes(need)} of working memory "
                f"(limit {format_bytes(MAX_WORKING_BYTES)}); "
                "lower resolution, render_scale or supersampling"
            )
            raise ConfigError(msg)
    if total > MAX_MESSAGES:
        msg = (
            f"{source}: the run would write about {total:.3g} messages "
            f"({duration_s:.6g} s of trajectory at the configured rates); the limit is "
            f"{MAX_MESSAGES:.3g}: lower the rates or shorten the trajectory"
        )
        raise ConfigError(msg)
