"""Sensors: landmark sensors with known correspondences (lidar follows)."""

from active_loc.sensors.landmarks import (
    RANGE_BEARING,
    RELATIVE_POSITION,
    LandmarkSensor,
    RangeBearingSensor,
    RelativePositionSensor,
)

__all__ = [
    "RANGE_BEARING",
    "RELATIVE_POSITION",
    "LandmarkSensor",
    "RangeBearingSensor",
    "RelativePositionSensor",
]
