"""Ray-cast (beam) sensors: spinning and solid-state LiDAR, 2-D laser scanner, sonar and
altimeter, on shared machinery: rays from the pose at each firing instant (:mod:`.rays`),
the range model and scan files (:mod:`.base`), PointCloud2 packing (:mod:`.pointcloud`),
and with ``output.labels`` the label of every return (:mod:`.labels`)."""

from __future__ import annotations

from roslan.sensors.beams.base import (
    Measurement,
    PointCloudSensor,
    ScanWriter,
    measure,
)
from roslan.sensors.beams.laser import (
    Laser,
    LaserConfig,
)
from roslan.sensors.beams.lidar import (
    HDL32E_ELEVATIONS_DEG,
    LIDAR_PRESETS,
    Lidar,
    LidarConfig,
    LidarPreset,
    LidarSpec,
)
from roslan.sensors.beams.pointcloud import (
    POINTCLOUD2,
    XYZIRT,
    XYZIRTL,
    pointcloud2,
)
from roslan.sensors.beams.range import (
    Altimeter,
    AltimeterConfig,
    RangeSensor,
    Sonar,
    SonarConfig,
    align_x_to,
    cone_directions,
)
from roslan.sensors.beams.rays import (
    rays_in_world,
)
from roslan.sensors.beams.solid_state import (
    SOLID_STATE_PRESETS,
    SolidStateLidar,
    SolidStateLidarConfig,
    SolidStatePreset,
)

__all__ = [
    "HDL32E_ELEVATIONS_DEG",
    "LIDAR_PRESETS",
    "POINTCLOUD2",
    "SOLID_STATE_PRESETS",
    "XYZIRT",
    "XYZIRTL",
    "Altimeter",
    "AltimeterConfig",
    "Laser",
    "LaserConfig",
    "Lidar",
    "LidarConfig",
    "LidarPreset",
    "LidarSpec",
    "Measurement",
    "PointCloudSensor",
    "RangeSensor",
    "ScanWriter",
    "SolidStateLidar",
    "SolidStateLidarConfig",
    "SolidStatePreset",
    "Sonar",
    "SonarConfig",
    "align_x_to",
    "cone_directions",
    "measure",
    "pointcloud2",
    "rays_in_world",
]
