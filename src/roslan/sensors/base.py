"""The one small interface every sensor implements.

A sensor is built from its validated config, gets a :class:`SimContext` (the
trajectory and its clock, the scene, its random stream, a place for its dataset files,
the shared renderer / ray caster) and yields :class:`Message` objects in non-decreasing
trajectory time, never reading the trajectory past the clock's horizon
(:mod:`roslan.sensors.clock`: it yields a wait marker instead). The pipeline merges all
sensors' streams by stamp and writes them to the bags; sensors write their own dataset files
(``imu.txt``, ``events.txt``...) through the run's file sink, ``ctx.files.path(...)``,
while they stream. A run that records no files (an unrecorded closed-loop episode) hands
them ``ctx.files = None``: a sensor then writes nothing (and skips the formatting).

Adding a sensor = one new module (a config model with ``type: Literal[...]`` and a
class satisfying :class:`Sensor`) + one :class:`~roslan.sensors.registry.SensorSpec` line in
:mod:`roslan.sensors.registry`.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import (
    TYPE_CHECKING,
    Annotated,
    Any,
    ClassVar,
    NamedTuple,
    Protocol,
    runtime_checkable,
)

import numpy as np
from numpy.typing import NDArray
from pydantic import (
    AfterValidator,
    Field,
    PrivateAttr,
    SerializerFunctionWrapHandler,
    model_serializer,
    model_validator,
)

from roslan.config.base import FiniteFloat, Pose, StrictModel
from roslan.limits import MAX_RATE_HZ
from roslan.trajectory.base import sample_times_ns

if TYPE_CHECKING:
    from roslan.io.files import DatasetFolder
    from roslan.io.messages import MessageStore
    from roslan.render.base import BeamCaster, FrameRenderer
    from roslan.scene.model import Scene
    from roslan.sensors.clock import Clock, Grid
    from roslan.trajectory.base import Trajectory

__all__ = [
    "WAIT_TOPIC",
    "LabelsKey",
    "Message",
    "Sensor",
    "SensorConfig",
    "SimContext",
    "StaticTransform",
    "TopicSpec",
    "is_wait",
    "paced",
    "sample_times_ns",
    "wait",
]

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
_TOPIC = re.compile(r"^/[A-Za-z][A-Za-z0-9_/]*$")


def _check_name(v: str) -> str:
    if not _NAME.match(v):
        msg = "must start with a letter and contain only letters, digits and '_'"
        raise ValueError(msg)
    return v


def _check_topic(v: str) -> str:
    if not _TOPIC.match(v) or v.endswith("/") or "//" in v:
        msg = "must be an absolute ROS topic name like '/imu' or '/dvs/events'"
        raise ValueError(msg)
    return v


SensorName = Annotated[str, AfterValidator(_check_name)]
TopicName = Annotated[str, AfterValidator(_check_topic)]


class SensorConfig(StrictModel):
    """Keys every sensor has. Subclasses add ``type: Literal['...']`` and their own keys.

    ``frame_id`` defaults to ``name`` (cameras publish in ``<frame_id>_optical``);
    ``topic`` defaults to ``/<name>`` unless the type has its own default (LiDAR:
    ``/velodyne_points``); ``pose`` is the sensor's extrinsics ``T_base_link_sensor``.
    """

    type: str
    name: SensorName
    rate: Annotated[FiniteFloat, Field(gt=0, le=MAX_RATE_HZ)]
    topic: TopicName
    frame_id: SensorName | None = None
    pose: Pose = Pose()

    needs_scene: ClassVar[bool] = True
    """Whether the sensor renders or ray casts the scene (checked before any work)."""

    @model_validator(mode="before")
    @classmethod
    def _default_topic(cls, data: Any) -> Any:
        if isinstance(data, Mapping) and "topic" not in data:
            field = cls.model_fields["topic"]
            if field.is_required():
                name = data.get("name")
                # an invalid name is reported on its own; the placeholder is never used
                topic = f"/{name}" if isinstance(name, str) and _NAME.match(name) else "/sensor"
                data = {**data, "topic": topic}
        return data

    @property
    def frame(self) -> str:
        return self.frame_id or self.name


class LabelsKey(StrictModel):
    """The ``labels`` key of every sensor that can write labels (cameras, the event
    camera, LiDARs, laser, sonar, altimeter): with ``output.labels: true`` such a sensor
    writes its label outputs unless it says ``labels: false`` (docs/guide/labels.md).

    Left out of the dump (run.json) at its default, so runs that do not use it stay
    byte-identical."""

    labels: Annotated[bool, Field(strict=True)] = True
    """False: this sensor writes no labels even when ``output.labels`` is true."""

    _run_labels: bool = PrivateAttr(default=False)
    """``output.labels`` of the run (set by :class:`~roslan.config.sim.SimConfig`)."""

    @property
    def writes_labels(self) -> bool:
        """Whether this sensor writes labels in its run: ``output.labels`` and ``labels``."""
        return self.labels and self._run_labels

    @model_serializer(mode="wrap")
    def _drop_default_labels(self, handler: SerializerFunctionWrapHandler) -> Any:
        data = handler(self)
        if isinstance(data, dict):
            if data.get("labels") is True:
                data.pop("labels")
            if "label_rate" in data and data["label_rate"] is None:
                data.pop("label_rate")  # (the event camera's key, when unset)
        return data


class TopicSpec(NamedTuple):
    """A topic a sensor publishes: name and message type (``'sensor_msgs/msg/Imu'``)."""

    topic: str
    msgtype: str


class StaticTransform(NamedTuple):
    """``T_parent_child`` (4x4) published once on /tf_static."""

    parent: str
    child: str
    T: NDArray[np.float64]


class Message(NamedTuple):
    """One message of a sensor's stream.

    ``t_ns`` is trajectory time (ns since trajectory start), the merge key. ``build``
    returns either a message object of ``store`` (serialized by the writer) or the
    finished wire bytes for ``store.flavor`` (for bulk messages packed with NumPy).
    The header stamp inside must be ``ctx.stamp(t_ns)``.
    """

    t_ns: int
    topic: str
    msgtype: str
    build: Callable[[MessageStore], Any]
    data: Any = None
    """Optional raw data of the message (a frame's image array, a scan's points...),
    read by closed-loop callers instead of decoding wire bytes; never written."""


class SimContext(Protocol):
    """What the pipeline hands every sensor."""

    trajectory: Trajectory
    clock: Clock
    """How far the trajectory may be read now (:mod:`roslan.sensors.clock`): a sensor
    never reads past ``clock.horizon_ns`` and yields a wait marker instead."""
    start_time_ns: int
    seed: int
    sensors: Sequence[SensorConfig]
    root_camera: str | None
    """The camera whose dataset files go to the OUTDIR root (Event Camera Dataset layout;
    :func:`roslan.rundir.calibration.root_camera`); every other camera writes into
    ``<camera>/``."""
    root_imu: str | None
    """The IMU whose readings are the OUTDIR root's ``imu.txt``
    (:func:`roslan.rundir.calibration.root_imu`); other IMUs write ``imu_<name>.txt``."""
    files: DatasetFolder | None
    """The run's dataset-file sink (``files.path(relpath)``: a path inside the output
    folder, its parent folders made), or None: this run records no files, write none."""
    sensor_threads: int
    """Threads a frame or scan sensor may use for its per-instant work after the render
    or cast (:class:`~roslan.io.ordered.OrderedPool`); outputs do not depend on it."""

    def stamp(self, t_ns: int) -> int:
        """Absolute header stamp (ns) of trajectory time ``t_ns``."""
        ...

    def rng(self, name: str) -> np.random.Generator:
        """The deterministic random stream of component ``name`` (independent per name)."""
        ...

    def path(self, relpath: str) -> Path:
        """``files.path(relpath)`` (RuntimeError in a run that records no files)."""
        ...

    @property
    def scene(self) -> Scene:
        """The scene (raises a clear ConfigError if the config has none)."""
        ...

    def renderer(self) -> FrameRenderer:
        """The process-wide OpenGL renderer of the scene (created on first use)."""
        ...

    def raycaster(self) -> BeamCaster:
        """The process-wide Embree ray caster of the scene (created on first use)."""
        ...

    def render_helpers(self, name: str) -> int:
        """Render helper processes sensor ``name`` may start for its time-parallel
        renders (:mod:`roslan.sensors.cameras.event_chains`); outputs do not depend on it."""
        ...

    def camera_folder(self, camera: str) -> str:
        """Where camera ``camera``'s dataset files go, relative to the OUTDIR: ``''`` for
        the root camera (:attr:`root_camera`), else ``'<camera>/'`` (the run folder's
        layout, :func:`roslan.rundir.calibration.camera_folder`)."""
        ...


@runtime_checkable
class Sensor(Protocol):
    """A simulated sensor. Construct with ``cls(config)``; the pipeline then calls
    ``topics``, ``static_transforms``, iterates ``messages(ctx)`` and finally ``close(ctx)``."""

    config: SensorConfig

    def topics(self) -> list[TopicSpec]: ...

    def static_transforms(self) -> list[StaticTransform]: ...

    def messages(self, ctx: SimContext) -> Iterator[Message]: ...

    def close(self, ctx: SimContext) -> None:
        """Finish dataset files (flush, close). Called after the stream ends."""
        ...


# ------------------------------------------------ the causal contract (sensors.clock)
WAIT_TOPIC = ""
"""The topic of a wait marker (no real topic is empty)."""


def _never(store: Any) -> Any:  # pragma: no cover - a wait marker is never written
    msg = "a wait marker is not a message"
    raise RuntimeError(msg)


def wait(floor_ns: int) -> Message:
    """The wait marker a sensor yields when it needs the trajectory past the horizon;
    ``floor_ns``: the smallest stamp it may still yield (its next message's at the
    earliest)."""
    return Message(int(floor_ns), WAIT_TOPIC, "", _never)


def is_wait(msg: Message) -> bool:
    """Whether ``msg`` is a wait marker."""
    return msg.topic == WAIT_TOPIC


def paced(
    grid: Grid, block: int, floor: Callable[[], int]
) -> Iterator[tuple[int, NDArray[np.int64]] | Message]:
    """The chunks ``(i0, instants)`` of ``grid`` (:meth:`Grid.take`), with a wait marker
    (floor ``floor()``) wherever the sensor must wait; ends when the grid is exhausted.
    The sensor yields the markers on (``isinstance(item, Message)``)."""
    while True:
        got = grid.take(block)
        if got is None:
            yield wait(floor())
        elif got[1].size == 0:
            return
        else:
            yield got
