"""Maps the robot localizes in: point-landmark maps, occupancy grids (with ROS map_server file
IO) and the generators of random occupancy maps."""

from active_loc.maps.generators import GENERATORS, maze_map, rooms_map, symmetric_arena
from active_loc.maps.landmarks import LandmarkMap, random_landmark_map
from active_loc.maps.map_image import MapFileError, MapFileNotFoundError
from active_loc.maps.maze import MazeSet, maze_test_set
from active_loc.maps.occupancy import (
    FREE,
    OCCUPIED,
    OFF_MAP,
    UNKNOWN,
    OccupancyGrid,
    cell_value,
    world_to_grid,
)

__all__ = [
    "FREE",
    "GENERATORS",
    "OCCUPIED",
    "OFF_MAP",
    "UNKNOWN",
    "LandmarkMap",
    "MapFileError",
    "MapFileNotFoundError",
    "MazeSet",
    "OccupancyGrid",
    "cell_value",
    "maze_map",
    "maze_test_set",
    "random_landmark_map",
    "rooms_map",
    "symmetric_arena",
    "world_to_grid",
]
