"""Maps the robot localizes in: point-landmark maps (occupancy grids follow)."""

from active_loc.maps.landmarks import LandmarkMap, random_landmark_map

__all__ = ["LandmarkMap", "random_landmark_map"]
