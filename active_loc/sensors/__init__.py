"""Sensors: landmark sensors with known correspondences and a 2-D lidar."""

from active_loc.sensors.landmarks import (
    RANGE_BEARING,
    RELATIVE_POSITION,
    LandmarkSensor,
    RangeBearingSensor,
    RelativePositionSensor,
)
from active_loc.sensors.lidar import LidarSensor

__all__ = [
    "RANGE_BEARING",
    "RELATIVE_POSITION",
    "LandmarkSensor",
    "LidarSensor",
    "RangeBearingSensor",
    "RelativePositionSensor",
]
