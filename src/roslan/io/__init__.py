"""Writers and readers of the files a run produces: bags (ROS 1 and ROS 2), messages,
atomic files, PNG images, text tables, ordered thread pools for per-frame work, and the
bounded, safe reading of user files.

Names are imported on first use (PEP 562), so importing one light module of the
package does not load the heavy ones.
"""

from __future__ import annotations

from roslan.lazy import lazy_getattr

_WHERE = {
    "BAG_NAMES": "bag",
    "BackgroundSink": "background",
    "BagTopic": "bag",
    "BagWriter": "bag",
    "CHUNK_ROWS": "text",
    "DETECTION2D_ARRAY": "vision",
    "DETECTION3D_ARRAY": "vision",
    "EXTRA_MSGDEFS": "messages",
    "FixedLayout": "packing",
    "Flavor": "messages",
    "Leaf": "packing",
    "MAX_IMAGE_BYTES": "safe_read",
    "MAX_IMAGE_PIXELS": "safe_read",
    "MAX_MESH_BYTES": "safe_read",
    "MAX_YAML_ALIASES": "safe_read",
    "MAX_YAML_BYTES": "safe_read",
    "MAX_YAML_DEPTH": "safe_read",
    "MAX_YAML_NODES": "safe_read",
    "MessageStore": "messages",
    "MultiBagWriter": "bag",
    "OrderedPool": "ordered",
    "PackedBatch": "packing",
    "PoolClosedError": "ordered",
    "ROS1_MSG_TEXTS": "ros1_msgdefs",
    "ROS1_VISION_MSG_TEXTS": "vision_msgdefs",
    "ROS2_VISION_MSGDEFS": "vision_msgdefs",
    "Ros1BagWriter": "bag",
    "Ros2BagWriter": "bag",
    "Turn": "ordered",
    "atomic_write": "files",
    "atomic_write_bytes": "files",
    "atomic_write_text": "files",
    "check_image_header": "safe_read",
    "check_regular_file": "safe_read",
    "current_umask": "files",
    "detection2d_array": "vision",
    "detection3d_array": "vision",
    "format_columns": "text",
    "format_seconds": "text",
    "os_error_text": "safe_read",
    "parse_yaml": "safe_read",
    "read_text": "safe_read",
    "ros1_full_text": "ros1_msgdefs",
    "set_path": "packing",
    "write_columns": "text",
    "write_png": "images",
}

__all__ = sorted(_WHERE)

__getattr__ = lazy_getattr(__name__, _WHERE)
