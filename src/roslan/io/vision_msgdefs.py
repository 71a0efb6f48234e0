# ruff: noqa: E501
"""vision_msgs definitions for both bag flavours (label topics: detections, objects).

``ROS1_VISION_MSG_TEXTS``: the ROS 1 Noetic texts of vision_msgs 1.x (and
geometry_msgs/Pose2D) as ROS 1 ships them, merged into
:data:`roslan.io.ros1_msgdefs.ROS1_MSG_TEXTS` (stored in ROS 1 bags; md5 sums computed by
rosbags from the fields). ``ROS2_VISION_MSGDEFS``: the fields of vision_msgs 4.x, the
version of ROS 2 Humble, Jazzy and later. Neither is in rosbags' stock typestores;
:class:`roslan.io.messages.MessageStore` registers the flavour's set.

The two differ: in ROS 1 ``BoundingBox2D.center`` is a ``geometry_msgs/Pose2D`` (x, y,
theta), ``ObjectHypothesisWithPose`` holds ``int64 id`` and ``float64 score`` itself, and
``Detection2D`` / ``Detection3D`` carry ``source_img`` / ``source_cloud`` and no ``id``; in
ROS 2 the centre is a ``vision_msgs/Pose2D`` (``position`` a ``vision_msgs/Point2D``,
``theta``), the hypothesis is an ``ObjectHypothesis`` (``string class_id``, ``score``)
beside the pose, and each detection has a ``string id``.
"""

from __future__ import annotations

__all__ = ["ROS1_VISION_MSG_TEXTS", "ROS2_VISION_MSGDEFS"]

ROS1_VISION_MSG_TEXTS: dict[str, str] = {
    "vision_msgs/Detection2DArray": (
        "# A list of 2D detections, for a multi-object 2D detector.\n"
        "\n"
        "Header header\n"
        "\n"
        "# A list of the detected proposals. A multi-proposal detector might generate\n"
        "#   this list with many candidate detections generated from a single input.\n"
        "Detection2D[] detections\n"
    ),
    "vision_msgs/Detection2D": (
        "# Defines a 2D detection result.\n"
        "#\n"
        "# This is similar to a 2D classification, but includes position information,\n"
        "#   allowing a classification result for a specific crop or image point to\n"
        "#   to be located in the larger image.\n"
        "\n"
        "Header header\n"
        "\n"
        "# Class probabilities\n"
        "ObjectHypothesisWithPose[] results\n"
        "\n"
        "# 2D bounding box surrounding the object.\n"
        "BoundingBox2D bbox\n"
        "\n"
        "# The 2D data that generated these results (i.e. region proposal cropped out of\n"
        "#   the image). Not required for all use cases, so it may be empty.\n"
        "sensor_msgs/Image source_img\n"
    ),
    "vision_msgs/ObjectHypothesisWithPose": (
        "# An object hypothesis that contains position information.\n"
        "\n"
        "# The unique numeric ID of the object class. To get additional information about\n"
        "#   this ID, such as its human-readable class name, listeners should perform a\n"
        "#   lookup in a metadata database. See vision_msgs/VisionInfo.msg for more detail.\n"
        "int64 id\n"
        "\n"
        "# The probability or confidence value of the detected object. By convention,\n"
        "#   this value should lie in the range [0-1].\n"
        "float64 score\n"
        "\n"
        "# The 6D pose of the object hypothesis. This pose should be\n"
        "#   defined as the pose of some fixed reference point on the object, such a\n"
        "#   the geometric center of the bounding box or the center of mass of the\n"
        "#   object.\n"
        "# Note that this pose is not stamped; frame information can be defined by\n"
        "#   parent messages.\n"
        "# Also note that different classes predicted for the same input data may have\n"
        "#   different predicted 6D poses.\n"
        "geometry_msgs/PoseWithCovariance pose\n"
    ),
    "vision_msgs/BoundingBox2D": (
        "# A 2D bounding box that can be rotated about its center.\n"
        "# All dimensions are in pixels, but represented using floating-point\n"
        "#   values to allow sub-pixel precision. If an exact pixel crop is required\n"
        "#   for a rotated bounding box, it can be calculated using Bresenham's line\n"
        "#   algorithm.\n"
        "\n"
        "# The 2D position (in pixels) and orientation of the bounding box center.\n"
        "geometry_msgs/Pose2D center\n"
        "\n"
        "# The size (in pixels) of the bounding box surrounding the object relative\n"
        "#   to the pose of its center.\n"
        "float64 size_x\n"
        "float64 size_y\n"
    ),
    "vision_msgs/Detection3DArray": (
        "# A list of 3D detections, for a multi-object 3D detector.\n"
        "\n"
        "Header header\n"
        "\n"
        "# A list of the detected proposals. A multi-proposal detector might generate\n"
        "#   this list with many candidate detections generated from a single input.\n"
        "Detection3D[] detections\n"
    ),
    "vision_msgs/Detection3D": (
        "# Defines a 3D detection result.\n"
        "#\n"
        "# This extends a basic 3D classification by including position information,\n"
        "#   allowing a classification result for a specific position in an image to\n"
        "#   to be located in the larger image.\n"
        "\n"
        "Header header\n"
        "\n"
        "# Class probabilities. Does not have to include hypotheses for all possible\n"
        "#   object ids, the scores for any ids not listed are assumed to be 0.\n"
        "ObjectHypothesisWithPose[] results\n"
        "\n"
        "# 3D bounding box surrounding the object.\n"
        "BoundingBox3D bbox\n"
        "\n"
        "# The 3D data that generated these results (i.e. region proposal cropped out of\n"
        "#   the image). This information is not required for all detectors, so it may\n"
        "#   be empty.\n"
        "sensor_msgs/PointCloud2 source_cloud\n"
    ),
    "vision_msgs/BoundingBox3D": (
        "# A 3D bounding box that can be positioned and rotated about its center (6 DOF)\n"
        "# Dimensions of this box are in meters, and as such, it may be migrated to\n"
        "#   another package, such as geometry_msgs, in the future.\n"
        "\n"
        "# The 3D position and orientation of the bounding box center\n"
        "geometry_msgs/Pose center\n"
        "\n"
        "# The size of the bounding box, in meters, surrounding the object's center\n"
        "#   pose.\n"
        "geometry_msgs/Vector3 size\n"
    ),
    "geometry_msgs/Pose2D": (
        "# Deprecated\n"
        "# Please use the full 3D pose.\n"
        "\n"
        "# In general our recommendation is to use a full 3D representation of everything and for 2D specific applications make the appropriate projections into the plane for their calculations but optimally will preserve the 3D information during processing.\n"
        "\n"
        "# If we have parallel copies of 2D datatypes every UI and other pipeline will end up needing to have dual interfaces to plot everything. And you will end up with not being able to use 3D tools for 2D use cases even if they're completely valid, as you'd have to reimplement it with different inputs and outputs. It's not particularly hard to plot the 2D pose or compute the yaw error for the Pose message and there are already tools and libraries that can do this for you.\n"
        "\n"
        "\n"
        "# This expresses a position and orientation on a 2D manifold.\n"
        "\n"
        "float64 x\n"
        "float64 y\n"
        "float64 theta\n"
    ),
}


ROS2_VISION_MSGDEFS: dict[str, str] = {
    "vision_msgs/msg/Point2D": "float64 x\nfloat64 y\n",
    "vision_msgs/msg/Pose2D": "vision_msgs/Point2D position\nfloat64 theta\n",
    "vision_msgs/msg/BoundingBox2D": (
        "vision_msgs/Pose2D center\nfloat64 size_x\nfloat64 size_y\n"
    ),
    "vision_msgs/msg/BoundingBox3D": "geometry_msgs/Pose center\ngeometry_msgs/Vector3 size\n",
    "vision_msgs/msg/ObjectHypothesis": "string class_id\nfloat64 score\n",
    "vision_msgs/msg/ObjectHypothesisWithPose": (
        "vision_msgs/ObjectHypothesis hypothesis\ngeometry_msgs/PoseWithCovariance pose\n"
    ),
    "vision_msgs/msg/Detection2D": (
        "std_msgs/Header header\nvision_msgs/ObjectHypothesisWithPose[] results\n"
        "vision_msgs/BoundingBox2D bbox\nstring id\n"
    ),
    "vision_msgs/msg/Detection2DArray": (
        "std_msgs/Header header\nvision_msgs/Detection2D[] detections\n"
    ),
    "vision_msgs/msg/Detection3D": (
        "std_msgs/Header header\nvision_msgs/ObjectHypothesisWithPose[] results\n"
        "vision_msgs/BoundingBox3D bbox\nstring id\n"
    ),
    "vision_msgs/msg/Detection3DArray": (
        "std_msgs/Header header\nvision_msgs/Detection3D[] detections\n"
    ),
}
"""vision_msgs 4.x fields (ROS 2 Humble and later), comments left out (same types)."""
