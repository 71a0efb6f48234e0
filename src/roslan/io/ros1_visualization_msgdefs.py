# ruff: noqa: E501
"""ROS 1 Noetic texts of the visualization_msgs the bags publish (``/scene``), as ROS 1 ships them.

Kept apart from :mod:`roslan.io.ros1_msgdefs` (which merges them) only for length.
"""

from __future__ import annotations

__all__ = ["VISUALIZATION_MSG_TEXTS"]

VISUALIZATION_MSG_TEXTS: dict[str, str] = {
    "visualization_msgs/MarkerArray": ("Marker[] markers\n"),
    "visualization_msgs/Marker": (
        "# See http://www.ros.org/wiki/rviz/DisplayTypes/Marker and http://www.ros.org/wiki/rviz/Tutorials/Markers%3A%20Basic%20Shapes for more information on using this message with rviz\n"
        "\n"
        "uint8 ARROW=0\n"
        "uint8 CUBE=1\n"
        "uint8 SPHERE=2\n"
        "uint8 CYLINDER=3\n"
        "uint8 LINE_STRIP=4\n"
        "uint8 LINE_LIST=5\n"
        "uint8 CUBE_LIST=6\n"
        "uint8 SPHERE_LIST=7\n"
        "uint8 POINTS=8\n"
        "uint8 TEXT_VIEW_FACING=9\n"
        "uint8 MESH_RESOURCE=10\n"
        "uint8 TRIANGLE_LIST=11\n"
        "\n"
        "uint8 ADD=0\n"
        "uint8 MODIFY=0\n"
        "uint8 DELETE=2\n"
        "uint8 DELETEALL=3\n"
        "\n"
        "Header header                        # header for time/frame information\n"
        "string ns                            # Namespace to place this object in... used in conjunction with id to create a unique name for the object\n"
        "int32 id \t\t                         # object ID useful in conjunction with the namespace for manipulating and deleting the object later\n"
        "int32 type \t\t                       # Type of object\n"
        "int32 action \t                       # 0 add/modify an object, 1 (deprecated), 2 deletes an object, 3 deletes all objects\n"
        "geometry_msgs/Pose pose                 # Pose of the object\n"
        "geometry_msgs/Vector3 scale             # Scale of the object 1,1,1 means default (usually 1 meter square)\n"
        "std_msgs/ColorRGBA color             # Color [0.0-1.0]\n"
        "duration lifetime                    # How long the object should last before being automatically deleted.  0 means forever\n"
        "bool frame_locked                    # If this marker should be frame-locked, i.e. retransformed into its frame every timestep\n"
        "\n"
        "#Only used if the type specified has some use for them (eg. POINTS, LINE_STRIP, ...)\n"
        "geometry_msgs/Point[] points\n"
        "#Only used if the type specified has some use for them (eg. POINTS, LINE_STRIP, ...)\n"
        "#number of colors must either be 0 or equal to the number of points\n"
        "#NOTE: alpha is not yet used\n"
        "std_msgs/ColorRGBA[] colors\n"
        "\n"
        "# NOTE: only used for text markers\n"
        "string text\n"
        "\n"
        "# NOTE: only used for MESH_RESOURCE markers\n"
        "string mesh_resource\n"
        "bool mesh_use_embedded_materials\n"
    ),
    "std_msgs/ColorRGBA": ("float32 r\nfloat32 g\nfloat32 b\nfloat32 a\n"),
}
