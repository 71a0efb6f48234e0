"""vision_msgs messages for both bag flavours: ``Detection2DArray`` of image boxes and
``Detection3DArray`` of oriented 3-D boxes (definitions in :mod:`roslan.io.vision_msgdefs`).

Each detection has one hypothesis: the class id (ROS 1 ``int64 id``; ROS 2 ``class_id``,
the id in decimal) with ``score`` 1 (ground truth). ROS 2's ``Detection2D.id`` /
``Detection3D.id`` is the instance id in decimal; ROS 1's vision_msgs have no such field,
so there the instance is known only by its place in the array (the same order as the ids
given). A 2-D box is axis-aligned (``theta`` 0), its centre and size in pixels; a 3-D box's
pose is its centre and orientation in the message's frame, its size in metres. The
hypothesis pose is the box centre, with a zero covariance. ROS 1's ``source_img`` /
``source_cloud`` stay empty.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from roslan.frames import matrix_to_quat_xyzw, rpy_to_matrix
from roslan.io.messages import MessageStore

__all__ = ["DETECTION2D_ARRAY", "DETECTION3D_ARRAY", "detection2d_array", "detection3d_array"]

DETECTION2D_ARRAY = "vision_msgs/msg/Detection2DArray"
DETECTION3D_ARRAY = "vision_msgs/msg/Detection3DArray"


def _column(values: ArrayLike, n: int, what: str, dtype: Any) -> Any:
    a = np.asarray(values, dtype=dtype).reshape(-1)
    if a.shape[0] != n:
        msg = f"{what}: {a.shape[0]} values for {n} boxes"
        raise ValueError(msg)
    return a


def _pose(store: MessageStore, center: Any, quat_xyzw: Any) -> Any:
    t = store.types
    return t["geometry_msgs/msg/Pose"](
        position=t["geometry_msgs/msg/Point"](
            x=float(center[0]), y=float(center[1]), z=float(center[2])
        ),
        orientation=t["geometry_msgs/msg/Quaternion"](
            x=float(quat_xyzw[0]),
            y=float(quat_xyzw[1]),
            z=float(quat_xyzw[2]),
            w=float(quat_xyzw[3]),
        ),
    )


def _hypothesis(store: MessageStore, class_id: int, score: float, pose: Any) -> Any:
    with_cov = store.new("geometry_msgs/msg/PoseWithCovariance", pose=pose, covariance=np.zeros(36))
    if store.is_ros1:
        return store.new(
            "vision_msgs/msg/ObjectHypothesisWithPose", id=class_id, score=score, pose=with_cov
        )
    hyp = store.new("vision_msgs/msg/ObjectHypothesis", class_id=str(class_id), score=score)
    return store.new("vision_msgs/msg/ObjectHypothesisWithPose", hypothesis=hyp, pose=with_cov)


def _array(
    store: MessageStore,
    msgtype: str,
    stamp_ns: int,
    frame_id: str,
    boxes: list[tuple[Any, Any]],
    class_ids: ArrayLike,
    instance_ids: ArrayLike,
    scores: ArrayLike | None,
) -> Any:
    """The shape both arrays share: per box (hypothesis pose, bounding box) one detection
    with one hypothesis (class, score), ROS 1's empty source data or ROS 2's instance id."""
    n = len(boxes)
    cls = _column(class_ids, n, "class_ids", np.int64)
    inst = _column(instance_ids, n, "instance_ids", np.int64)
    sc = np.ones(n) if scores is None else _column(scores, n, "scores", np.float64)
    header = store.header(stamp_ns, frame_id)
    detection = msgtype.removesuffix("Array")
    source = _ros1_source(store, detection) if store.is_ros1 else None
    dets = []
    for i, (pose, bbox) in enumerate(boxes):
        hyp = _hypothesis(store, int(cls[i]), float(sc[i]), pose)
        fields: dict[str, Any] = {"header": header, "results": [hyp], "bbox": bbox}
        if source is not None:
            fields.update(source)
        else:
            fields["id"] = str(int(inst[i]))
        dets.append(store.new(detection, **fields))
    return store.new(msgtype, header=header, detections=dets)


def _ros1_source(store: MessageStore, detection: str) -> dict[str, Any]:
    """ROS 1's empty ``source_img`` (Detection2D) or ``source_cloud`` (Detection3D)."""
    if detection == "vision_msgs/msg/Detection2D":
        img = store.new(
            "sensor_msgs/msg/Image",
            header=store.header(0, ""),
            height=0,
            width=0,
            encoding="",
            is_bigendian=0,
            step=0,
            data=np.zeros(0, np.uint8),
        )
        return {"source_img": img}
    cloud = store.new(
        "sensor_msgs/msg/PointCloud2",
        header=store.header(0, ""),
        height=0,
        width=0,
        fields=[],
        is_bigendian=False,
        point_step=0,
        row_step=0,
        data=np.zeros(0, np.uint8),
        is_dense=False,
    )
    return {"source_cloud": cloud}


def detection2d_array(
    store: MessageStore,
    stamp_ns: int,
    frame_id: str,
    boxes_xywh: ArrayLike,
    class_ids: ArrayLike,
    instance_ids: ArrayLike,
    scores: ArrayLike | None = None,
) -> Any:
    """A ``vision_msgs/Detection2DArray`` of axis-aligned image boxes.

    Args:
        boxes_xywh: (N, 4) left, top, width, height in pixels (COCO's ``bbox``).
        class_ids, instance_ids: (N,) integers.
        scores: (N,) confidences; default 1 (ground truth).
    """
    b = np.asarray(boxes_xywh, dtype=np.float64).reshape(-1, 4)
    boxes = []
    for x, y, w, h in b.tolist():
        cx, cy = x + w / 2.0, y + h / 2.0
        pose = _pose(store, (cx, cy, 0.0), (0.0, 0.0, 0.0, 1.0))
        if store.is_ros1:
            center = store.new("geometry_msgs/msg/Pose2D", x=cx, y=cy, theta=0.0)
        else:
            center = store.new(
                "vision_msgs/msg/Pose2D",
                position=store.new("vision_msgs/msg/Point2D", x=cx, y=cy),
                theta=0.0,
            )
        bbox = store.new("vision_msgs/msg/BoundingBox2D", center=center, size_x=w, size_y=h)
        boxes.append((pose, bbox))
    return _array(
        store, DETECTION2D_ARRAY, stamp_ns, frame_id, boxes, class_ids, instance_ids, scores
    )


def detection3d_array(
    store: MessageStore,
    stamp_ns: int,
    frame_id: str,
    centers: ArrayLike,
    sizes: ArrayLike,
    rpys: ArrayLike,
    class_ids: ArrayLike,
    instance_ids: ArrayLike,
    scores: ArrayLike | None = None,
) -> Any:
    """A ``vision_msgs/Detection3DArray`` of oriented 3-D boxes (e.g. a scene's instances,
    :func:`roslan.scene.instances.scene_labels`, in the world frame).

    Args:
        centers, sizes, rpys: (N, 3) box centres (m), sizes along the box axes (m) and
            orientations (roll, pitch, yaw; rad) in ``frame_id``.
        class_ids, instance_ids: (N,) integers.
        scores: (N,) confidences; default 1 (ground truth).
    """
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    n = c.shape[0]
    s = np.asarray(sizes, dtype=np.float64).reshape(n, 3)
    r = np.asarray(rpys, dtype=np.float64).reshape(n, 3)
    vec = store.types["geometry_msgs/msg/Vector3"]
    boxes = []
    for i in range(n):
        pose = _pose(store, c[i], matrix_to_quat_xyzw(rpy_to_matrix(r[i])))
        size = vec(x=float(s[i, 0]), y=float(s[i, 1]), z=float(s[i, 2]))
        boxes.append((pose, store.new("vision_msgs/msg/BoundingBox3D", center=pose, size=size)))
    return _array(
        store, DETECTION3D_ARRAY, stamp_ns, frame_id, boxes, class_ids, instance_ids, scores
    )
