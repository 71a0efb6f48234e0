"""sensor_msgs/PointCloud2 packing of structured point arrays (no per-point Python)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from roslan.io.messages import MessageStore

__all__ = ["POINTCLOUD2", "XYZIRT", "XYZIRTL", "pointcloud2"]


XYZIRT = np.dtype(
    {
        "names": ["x", "y", "z", "intensity", "ring", "time"],
        "formats": ["<f4", "<f4", "<f4", "<f4", "<u2", "<f4"],
        "offsets": [0, 4, 8, 12, 16, 18],
        "itemsize": 22,
    }
)
"""velodyne_pointcloud's PointXYZIRT wire layout: packed, 22 bytes per point."""

XYZIRTL = np.dtype(
    {
        "names": ["x", "y", "z", "intensity", "ring", "time", "label"],
        "formats": ["<f4", "<f4", "<f4", "<f4", "<u2", "<f4", "<u4"],
        "offsets": [0, 4, 8, 12, 16, 18, 22],
        "itemsize": 26,
    }
)
""":data:`XYZIRT` and ``label`` (uint32 at byte 22, the SemanticKITTI encoding: class id in
the low 16 bits, instance id in the high 16; 0 for no return): the layout of a labelled
scan (``output.labels``), packed, 26 bytes per point."""


POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"

_POINTFIELD_TYPE = {
    np.dtype("<f4"): 7,  # FLOAT32
    np.dtype("<u2"): 4,  # UINT16
    np.dtype("<u4"): 6,  # UINT32
    np.dtype("<f8"): 8,  # FLOAT64
    np.dtype("u1"): 2,  # UINT8
}


def pointcloud2(
    store: MessageStore,
    stamp_ns: int,
    frame_id: str,
    points: NDArray[Any],
    *,
    height: int = 1,
    seq: int = 0,
    is_dense: bool = True,
) -> Any:
    """sensor_msgs/PointCloud2 of a structured array (fields and offsets from its dtype).

    ``points`` is (height * width,) of a little-endian structured dtype such as
    :data:`XYZIRT`; its bytes are the message data as they are (no per-point Python).
    """
    dt = points.dtype
    assert dt.names is not None
    assert dt.fields is not None
    PointField = store.types["sensor_msgs/msg/PointField"]
    fields = []
    for name in dt.names:
        fdt, off = dt.fields[name][0], dt.fields[name][1]
        fields.append(PointField(name=name, offset=off, datatype=_POINTFIELD_TYPE[fdt], count=1))
    width = points.shape[0] // max(height, 1) if height else 0
    data = np.ascontiguousarray(points).view(np.uint8).reshape(-1)  # no copy
    return store.new(
        "sensor_msgs/msg/PointCloud2",
        header=store.header(stamp_ns, frame_id, seq),
        height=height,
        width=width,
        fields=fields,
        is_bigendian=False,
        point_step=dt.itemsize,
        row_step=dt.itemsize * width,
        data=data,
        is_dense=is_dense,
    )
