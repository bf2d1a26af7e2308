"""People walking through a grid map: moving obstacles that the map does not hold.

The chapter's static-versus-dynamic axis: in a dynamic environment the scan sees things that
are not in the map. Each person is a disc that walks at a constant speed in a straight line to
a goal it can see (a random free point with a clear line of sight), then picks the next one.
People stop rather than walk into the robot, and the robot is blocked by them. The scan of the
true robot is occluded by them (:func:`active_loc.sensors.lidar.occlude_ranges`); the filter
only knows the map.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from active_loc.maps import OccupancyGrid
from active_loc.sensors.lidar import cast_ray

#: radius of the robot (m) that people keep clear of
ROBOT_RADIUS = 0.2
#: candidate goals drawn when a person picks a new one; with none in sight it waits a step
GOAL_CANDIDATES = 8
#: a goal closer than this (m) is not worth walking to
MIN_GOAL_DISTANCE = 1.0


@dataclass
class Crowd:
    """The people of one episode.

    Attributes:
        discs: ``(P, 3)`` centre x, y (m) and radius (m) of each person.
        goals: ``(P, 2)`` where each person walks to (m).
        speed: walking speed (m/s).
    """

    discs: NDArray[np.float64]
    goals: NDArray[np.float64]
    speed: float

    @classmethod
    def spawn(
        cls,
        grid: OccupancyGrid,
        count: int,
        speed: float,
        radius: float,
        robot_xy: NDArray[np.float64],
        rng: np.random.Generator,
    ) -> Crowd:
        """``count`` people at random free points at least 1 m clear of the robot, each with a
        goal in sight. Draws ``4 count`` free points, then goals."""
        points = grid.sample_free(rng, 4 * count)
        clear = np.hypot(*(points - robot_xy).T) >= 1.0 + radius + ROBOT_RADIUS
        # the clear points first; if there are too few, the nearest ones fill up
        order = np.argsort(~clear, kind="stable")[:count]
        discs = np.column_stack([points[order], np.full(count, float(radius))])
        crowd = cls(discs, discs[:, :2].copy(), float(speed))
        for p in range(count):
            crowd._new_goal(p, grid, rng)
        return crowd

    def _new_goal(self, p: int, grid: OccupancyGrid, rng: np.random.Generator) -> None:
        """A random free point that person ``p`` sees (a clear straight walk), else stay."""
        values, res, ox, oy, c, s = grid.kernel_arrays()
        x, y = self.discs[p, 0], self.discs[p, 1]
        for gx, gy in grid.sample_free(rng, GOAL_CANDIDATES):
            distance = math.hypot(gx - x, gy - y)
            if distance < MIN_GOAL_DISTANCE:
                continue
            run = cast_ray(values, res, ox, oy, c, s, x, y, math.atan2(gy - y, gx - x),
                           distance, True)
            if run >= distance:
                self.goals[p] = (gx, gy)
                return
        self.goals[p] = (x, y)

    def step(
        self, grid: OccupancyGrid, dt: float, robot_xy: NDArray[np.float64],
        rng: np.random.Generator,
    ) -> None:
        """Everyone walks ``speed dt`` towards their goal (waiting instead of touching the
        robot); who arrives picks the next goal."""
        reach = self.speed * dt
        for p in range(self.discs.shape[0]):
            offset = self.goals[p] - self.discs[p, :2]
            distance = float(np.hypot(*offset))
            if distance <= reach:
                target = self.goals[p].copy()
            else:
                target = self.discs[p, :2] + offset * (reach / distance)
            if np.hypot(*(target - robot_xy)) < self.discs[p, 2] + ROBOT_RADIUS:
                continue
            self.discs[p, :2] = target
            if distance <= reach:
                self._new_goal(p, grid, rng)

    def blocks(self, xy: NDArray[np.float64]) -> bool:
        """Whether a robot at ``xy`` ``(2,)`` would overlap a person."""
        gaps = np.hypot(*(self.discs[:, :2] - xy).T)
        return bool(np.any(gaps < self.discs[:, 2] + ROBOT_RADIUS))
