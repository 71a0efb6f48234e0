"""Exact ground truth, always recorded: TF tree, pose, odometry, acceleration, tau state.

Topics (rate ``output.ground_truth_rate``, default 200 Hz, plus one /tf_static at t = 0):

==========================  ==============================  =====================================
topic                       type                            content
==========================  ==============================  =====================================
``/tf``                     tf2_msgs/TFMessage              ``world -> base_link``
``/tf_static`` (latched)    tf2_msgs/TFMessage              ``base_link -> <sensor frame>`` (from
                                                            each sensor's ``pose``) and each
                                                            sensor's own extra transforms
``/scene`` (latched)        visualization_msgs/MarkerArray  the scene's triangles in ``world``
                                                            (one message at t = 0, runs with a
                                                            scene; :mod:`roslan.scene.markers`)
``/objects`` (latched)      vision_msgs/Detection3DArray    with ``output.labels``: every instance's
                                                            oriented box in ``world``, its class
                                                            id as the hypothesis (one message at
                                                            t = 0, see below)
``/ground_truth/pose``      geometry_msgs/PoseStamped       base_link pose in ``world``
``/ground_truth/odometry``  nav_msgs/Odometry               pose in ``world``, twist in
                                                            ``base_link`` (child frame)
``/ground_truth/accel``     geometry_msgs/AccelStamped      in ``base_link``: linear = R_wb^T a_w
                                                            (kinematic, no gravity), angular =
                                                            body angular acceleration
``/tau/state``              std_msgs/Float64MultiArray      the 18 components of trajectory.csv
                                                            (gaps, rates, accels in frame F),
                                                            layout dims ``derivative`` (3) x
                                                            ``axis`` (6)
==========================  ==============================  =====================================

``/objects`` holds one detection per instance of the scene
(:func:`roslan.scene.instances.scene_labels`, the rows of ``instances.json``) in instance-id
order: the box pose and size, one hypothesis with the class id and score 1, and (ROS 2) the
instance id as ``id``. It is published once, latched, at t = 0: every scene object is static
today, so each box is the same at every instant, and one message of the warehouse's 799
instances is about 400 kB (at the 200 Hz ground-truth rate that would be 80 MB/s of bag).
Once objects can move it is to be published at the label instants instead.

Static transforms: the pipeline publishes ``base_link -> config.frame`` for every sensor
from its extrinsics, then whatever ``Sensor.static_transforms()`` returns (cameras add
``<frame> -> <frame>_optical``); a transform a sensor returns for a child frame replaces
the extrinsics-derived one for that child.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from roslan.frames import matrix_to_quat_xyzw
from roslan.io.messages import MessageStore
from roslan.io.packing import FixedLayout, Leaf, PackedBatch
from roslan.io.vision import DETECTION3D_ARRAY, detection3d_array
from roslan.scene.instances import scene_labels
from roslan.scene.markers import (
    SCENE_MSGTYPE,
    SCENE_TOPIC,
    SceneMesh,
    scene_marker_bytes,
    scene_mesh,
)
from roslan.sensors.base import Message, SimContext, StaticTransform, TopicSpec, paced
from roslan.trajectory.base import (
    COMPONENTS,
    DEFAULT_GROUND_TRUTH_RATE,
    GAPS,
    ground_truth_times_ns,
    sample_times_ns,
)

if TYPE_CHECKING:
    from roslan.scene.model import Scene

__all__ = [
    "BASE_FRAME",
    "OBJECTS_TOPIC",
    "TAU_LAYOUT",
    "WORLD_FRAME",
    "GroundTruth",
    "objects_message",
    "static_transform_message",
]

WORLD_FRAME = "world"
OBJECTS_TOPIC = "/objects"
BASE_FRAME = "base_link"
CHUNK_S = 1.0
"""Trajectory seconds evaluated per vectorized step."""

TAU_LAYOUT = (("derivative(gap,rate,accel)", 3, 18), ("axis(" + ",".join(GAPS) + ")", 6, 6))
"""``/tau/state`` layout: (label, size, stride) per dimension;
data[6 i + j] = COMPONENTS[6 i + j]."""

assert len(COMPONENTS) == 18

F64 = NDArray[np.float64]


def _vec(store: MessageStore, v: Sequence[float] | F64 = (0.0, 0.0, 0.0)) -> Any:
    return store.new("geometry_msgs/msg/Vector3", x=float(v[0]), y=float(v[1]), z=float(v[2]))


def _point(store: MessageStore) -> Any:
    return store.new("geometry_msgs/msg/Point", x=0.0, y=0.0, z=0.0)


def _quat(store: MessageStore, q: Sequence[float] | F64 = (0.0, 0.0, 0.0, 1.0)) -> Any:
    return store.new(
        "geometry_msgs/msg/Quaternion", x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])
    )


def _transform_stamped(store: MessageStore, stamp_ns: int, parent: str, child: str, T: F64) -> Any:
    q = matrix_to_quat_xyzw(np.asarray(T)[:3, :3])
    return store.new(
        "geometry_msgs/msg/TransformStamped",
        header=store.header(stamp_ns, parent),
        child_frame_id=child,
        transform=store.new(
            "geometry_msgs/msg/Transform",
            translation=_vec(store, np.asarray(T)[:3, 3]),
            rotation=_quat(store, q),
        ),
    )


def objects_message(store: MessageStore, stamp_ns: int, scene: Scene) -> Any:
    """``/objects``: every instance of ``scene`` as a world-frame oriented 3-D box, in
    instance-id order (the module docstring)."""
    inst = scene_labels(scene).instances
    return detection3d_array(
        store,
        stamp_ns,
        WORLD_FRAME,
        np.array([i.center for i in inst]).reshape(-1, 3),
        np.array([i.size for i in inst]).reshape(-1, 3),
        np.array([i.rpy for i in inst]).reshape(-1, 3),
        [i.class_id for i in inst],
        [i.id for i in inst],
    )


def static_transform_message(
    store: MessageStore, stamp_ns: int, transforms: Sequence[StaticTransform]
) -> Any:
    """One tf2_msgs/TFMessage holding every static transform, stamped ``stamp_ns``."""
    return store.new(
        "tf2_msgs/msg/TFMessage",
        transforms=[
            _transform_stamped(store, stamp_ns, t.parent, t.child, t.T) for t in transforms
        ],
    )


_STAMP: list[Leaf] = [("header.stamp.sec", "<u4", 1), ("header.stamp.nanosec", "<u4", 1)]


def _pose_leaves(prefix: str) -> list[Leaf]:
    return [(f"{prefix}.position.{a}", "<f8", 1) for a in "xyz"] + [
        (f"{prefix}.orientation.{a}", "<f8", 1) for a in "xyzw"
    ]


def _vec_leaves(prefix: str) -> list[Leaf]:
    return [(f"{prefix}.{a}", "<f8", 1) for a in "xyz"]


class _Layouts:
    """FixedLayouts of the five periodic ground-truth messages for one flavour."""

    def __init__(self, store: MessageStore) -> None:
        seq: list[Leaf] = [("header.seq", "<u4", 1)] if store.is_ros1 else []
        hdr = _STAMP + seq
        pose = store.new("geometry_msgs/msg/Pose", position=_point(store), orientation=_quat(store))
        tf = store.new(
            "tf2_msgs/msg/TFMessage",
            transforms=[_transform_stamped(store, 0, WORLD_FRAME, BASE_FRAME, np.eye(4))],
        )
        tf_leaves = [("transforms.0." + p, d, c) for p, d, c in hdr]
        tf_leaves += [(f"transforms.0.transform.translation.{a}", "<f8", 1) for a in "xyz"]
        tf_leaves += [(f"transforms.0.transform.rotation.{a}", "<f8", 1) for a in "xyzw"]
        self.tf = FixedLayout(store, "tf2_msgs/msg/TFMessage", tf, tf_leaves)
        self.pose = FixedLayout(
            store,
            "geometry_msgs/msg/PoseStamped",
            store.new(
                "geometry_msgs/msg/PoseStamped", header=store.header(0, WORLD_FRAME), pose=pose
            ),
            hdr + _pose_leaves("pose"),
        )
        odom = store.new(
            "nav_msgs/msg/Odometry",
            header=store.header(0, WORLD_FRAME),
            child_frame_id=BASE_FRAME,
            pose=store.new(
                "geometry_msgs/msg/PoseWithCovariance", pose=pose, covariance=np.zeros(36)
            ),
            twist=store.new(
                "geometry_msgs/msg/TwistWithCovariance",
                twist=store.new("geometry_msgs/msg/Twist", linear=_vec(store), angular=_vec(store)),
                covariance=np.zeros(36),
            ),
        )
        self.odom = FixedLayout(
            store,
            "nav_msgs/msg/Odometry",
            odom,
            hdr
            + _pose_leaves("pose.pose")
            + _vec_leaves("twist.twist.linear")
            + _vec_leaves("twist.twist.angular"),
        )
        accel = store.new(
            "geometry_msgs/msg/AccelStamped",
            header=store.header(0, BASE_FRAME),
            accel=store.new("geometry_msgs/msg/Accel", linear=_vec(store), angular=_vec(store)),
        )
        self.accel = FixedLayout(
            store,
            "geometry_msgs/msg/AccelStamped",
            accel,
            hdr + _vec_leaves("accel.linear") + _vec_leaves("accel.angular"),
        )
        dims = [
            store.new("std_msgs/msg/MultiArrayDimension", label=label, size=size, stride=stride)
            for label, size, stride in TAU_LAYOUT
        ]
        tau = store.new(
            "std_msgs/msg/Float64MultiArray",
            layout=store.new("std_msgs/msg/MultiArrayLayout", dim=dims, data_offset=0),
            data=np.zeros(18),
        )
        self.tau = FixedLayout(store, "std_msgs/msg/Float64MultiArray", tau, [("data", "<f8", 18)])


class GroundTruth:
    """The always-on ground-truth publisher (not a configurable sensor type).

    Args:
        rate: Hz of the periodic topics.
        static: transforms for /tf_static (one latched message at t = 0).
        scene: publish the scene as /scene (one latched message at t = 0; the run has a scene).
        objects: publish the scene's instances as /objects (one latched message at t = 0;
            ``output.labels`` on a run with a scene).
    """

    TOPICS = (
        TopicSpec("/tf_static", "tf2_msgs/msg/TFMessage"),
        TopicSpec("/tf", "tf2_msgs/msg/TFMessage"),
        TopicSpec("/ground_truth/pose", "geometry_msgs/msg/PoseStamped"),
        TopicSpec("/ground_truth/odometry", "nav_msgs/msg/Odometry"),
        TopicSpec("/ground_truth/accel", "geometry_msgs/msg/AccelStamped"),
        TopicSpec("/tau/state", "std_msgs/msg/Float64MultiArray"),
    )
    LATCHED = frozenset({"/tf_static", SCENE_TOPIC, OBJECTS_TOPIC})

    def __init__(
        self,
        rate: float = DEFAULT_GROUND_TRUTH_RATE,
        static: Sequence[StaticTransform] = (),
        *,
        scene: bool = False,
        objects: bool = False,
    ) -> None:
        self.rate = float(rate)
        self.static = list(static)
        self.scene = scene
        self.objects = objects
        self._layouts: dict[str, _Layouts] = {}
        self.name = "ground_truth"

    def topics(self) -> list[TopicSpec]:
        scene = [TopicSpec(SCENE_TOPIC, SCENE_MSGTYPE)] if self.scene else []
        objects = [TopicSpec(OBJECTS_TOPIC, DETECTION3D_ARRAY)] if self.objects else []
        return [self.TOPICS[0], *scene, *objects, *self.TOPICS[1:]]

    def static_transforms(self) -> list[StaticTransform]:
        return list(self.static)

    def _lay(self, store: MessageStore) -> _Layouts:
        key = store.flavor.value
        if key not in self._layouts:
            self._layouts[key] = _Layouts(store)
        return self._layouts[key]

    def messages(self, ctx: SimContext) -> Iterator[Message]:
        """/tf_static (and /scene) at 0, then per instant: /tf, pose, odometry, accel, tau
        state."""
        static = self.static
        start = ctx.stamp(0)
        yield Message(
            0,
            "/tf_static",
            "tf2_msgs/msg/TFMessage",
            lambda store: static_transform_message(store, start, static),
        )
        if self.scene:
            mesh: list[SceneMesh] = []  # simplified once, serialized per flavour

            def scene_msg(store: MessageStore) -> bytes:
                if not mesh:
                    mesh.append(scene_mesh(ctx.scene))
                return scene_marker_bytes(store, start, mesh[0], WORLD_FRAME)

            yield Message(0, SCENE_TOPIC, SCENE_MSGTYPE, scene_msg)
        if self.objects:
            yield Message(
                0,
                OBJECTS_TOPIC,
                DETECTION3D_ARRAY,
                lambda store: objects_message(store, start, ctx.scene),
            )
        # the record ends exactly at the end of the run; groundtruth.txt has the same rows
        rate = self.rate
        # before the end is known, the grid's instants up to the horizon (the end itself
        # joins when it is known)
        grid = ctx.clock.grid(
            lambda end: ground_truth_times_ns(rate, end), lambda h: sample_times_ns(rate, h)
        )
        per_chunk = max(1, round(self.rate * CHUNK_S))
        last = [0]
        for item in paced(grid, per_chunk, lambda: last[0] + 1):
            if isinstance(item, Message):
                yield item  # wait for the horizon
                continue
            i0, t = item
            last[0] = int(t[-1])
            yield from self._chunk(ctx, t, i0)

    def _chunk(self, ctx: SimContext, t: NDArray[np.int64], i0: int) -> Iterator[Message]:
        n = t.size
        st = ctx.trajectory.state_ns(t)
        stamps = ctx.start_time_ns + t
        sec, nsec = np.divmod(stamps, 1_000_000_000)
        seq = np.arange(i0, i0 + n)
        R_T = np.swapaxes(st.R_world_body, 1, 2)
        v_body = np.einsum("nij,nj->ni", R_T, st.velocity)
        a_body = np.einsum("nij,nj->ni", R_T, st.acceleration)
        pos, q = st.position, st.quat_xyzw
        comps = st.components()

        def header(store: MessageStore, prefix: str = "") -> dict[str, Any]:
            cols: dict[str, Any] = {
                prefix + "header.stamp.sec": sec,
                prefix + "header.stamp.nanosec": nsec,
            }
            if store.is_ros1:
                cols[prefix + "header.seq"] = seq
            return cols

        def pose_cols(prefix: str) -> dict[str, Any]:
            cols = {f"{prefix}.position.{a}": pos[:, i] for i, a in enumerate("xyz")}
            cols.update({f"{prefix}.orientation.{a}": q[:, i] for i, a in enumerate("xyzw")})
            return cols

        def vec_cols(prefix: str, v: F64) -> dict[str, Any]:
            return {f"{prefix}.{a}": v[:, i] for i, a in enumerate("xyz")}

        def tf(store: MessageStore) -> NDArray[np.uint8]:
            cols = header(store, "transforms.0.")
            cols.update(vec_cols("transforms.0.transform.translation", pos))
            cols.update(
                {f"transforms.0.transform.rotation.{a}": q[:, i] for i, a in enumerate("xyzw")}
            )
            return self._lay(store).tf.pack(cols, n)

        def pose(store: MessageStore) -> NDArray[np.uint8]:
            return self._lay(store).pose.pack({**header(store), **pose_cols("pose")}, n)

        def odom(store: MessageStore) -> NDArray[np.uint8]:
            cols = {**header(store), **pose_cols("pose.pose")}
            cols.update(vec_cols("twist.twist.linear", v_body))
            cols.update(vec_cols("twist.twist.angular", st.omega_body))
            return self._lay(store).odom.pack(cols, n)

        def accel(store: MessageStore) -> NDArray[np.uint8]:
            cols = {**header(store), **vec_cols("accel.linear", a_body)}
            cols.update(vec_cols("accel.angular", st.alpha_body))
            return self._lay(store).accel.pack(cols, n)

        def tau(store: MessageStore) -> NDArray[np.uint8]:
            return self._lay(store).tau.pack({"data": comps}, n)

        batches = [
            ("/tf", "tf2_msgs/msg/TFMessage", PackedBatch(tf)),
            ("/ground_truth/pose", "geometry_msgs/msg/PoseStamped", PackedBatch(pose)),
            ("/ground_truth/odometry", "nav_msgs/msg/Odometry", PackedBatch(odom)),
            ("/ground_truth/accel", "geometry_msgs/msg/AccelStamped", PackedBatch(accel)),
            ("/tau/state", "std_msgs/msg/Float64MultiArray", PackedBatch(tau)),
        ]
        for i, ti in enumerate(t.tolist()):
            for topic, msgtype, batch in batches:
                yield Message(ti, topic, msgtype, batch.build(i))

    def close(self, ctx: SimContext) -> None:
        """Nothing to finish: ground-truth files come from the trajectory export."""
