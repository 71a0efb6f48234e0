"""A small event-camera run shared by the event-camera sensor tests: a 40x30 camera over a
checkered floor and a crate, along a short tau landing, straight through the sensor."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from roslan.scene.mesh import box, place, plane, pose_matrix
from roslan.scene.model import Material, Scene
from roslan.trajectory import TauTrajectory, TrajectoryConfig

START_NS = 1_700_000_000_000_000_000


def floor_and_crate() -> Scene:
    """A checkered 10 m floor and a 0.6 m crate in front of the landing."""
    from roslan.scene.textures import checker

    floor = place(
        "floor", plane((10.0, 10.0)), Material(texture=checker(1, 128, 8), texture_scale=0.5)
    )
    crate = place(
        "crate", box((0.6, 0.6, 0.6)), Material(color=(0.8, 0.3, 0.2)), pose_matrix((0.8, 0.5, 0.3))
    )
    return Scene("test", (floor, crate))


def event_camera_and_context(tmp: Path, seed: int, **over: Any) -> tuple[Any, Any]:
    """The sensor (25 Hz, 40x30, pitched 0.5 rad down unless ``over`` says otherwise;
    ``over`` replaces any config key) and its run context (files land in ``tmp``)."""
    from roslan.pipeline.context import Context
    from roslan.sensors.cameras import EventCamera, EventCameraConfig

    traj = TauTrajectory(
        TrajectoryConfig(
            initial={"position": (-1.2, 0.3, 0.6), "rpy": (0, 0, 0), "descent_rate": 1.5}
        ),
        warn=False,
    )
    cfg = EventCameraConfig.model_validate(
        {
            "type": "event_camera",
            "name": "dvs",
            "rate": 25,
            "topic": "/dvs",
            "resolution": (40, 30),
            "pose": {"rpy": (0.0, 0.5, 0.0)},
            "max_rate": 300,
            "min_rate": 50,
            **over,
        }
    )
    ctx = Context(
        traj, tmp, seed=seed, sensors=[cfg], scene=floor_and_crate(), start_time_ns=START_NS
    )
    return EventCamera(cfg), ctx


def run_event_camera(
    tmp: Path,
    seed: int,
    *,
    pipelined: bool = True,
    on_message: Callable[[Any], object] | None = None,
    **over: Any,
) -> tuple[Any, list[Any]]:
    """The sensor of :func:`event_camera_and_context` and its messages.
    ``pipelined=False``: ESIM and the messages on the calling thread; ``on_message`` is
    called with each message as it comes (as the pipeline builds them)."""
    sensor, ctx = event_camera_and_context(tmp, seed, **over)
    sensor.pipelined = pipelined
    msgs = []
    for m in sensor.messages(ctx):
        if on_message is not None:
            on_message(m)
        msgs.append(m)
    sensor.close(ctx)
    return sensor, msgs
