"""Passive agents: they move without looking at the belief (the chapter's passive
localization), so whatever they learn about the pose comes by chance."""

from __future__ import annotations

from typing import Any

import numpy as np

from active_loc.agents.planning import primitive_action
from active_loc.envs.actions import PRIMITIVE_NAMES
from active_loc.envs.belief_image import observation_vector
from active_loc.sensors.lidar import LidarSensor

_FORWARD = PRIMITIVE_NAMES.index("forward")
_FORWARD_LEFT = PRIMITIVE_NAMES.index("forward_left")
_FORWARD_RIGHT = PRIMITIVE_NAMES.index("forward_right")
_TURN_LEFT = PRIMITIVE_NAMES.index("turn_left")


class WandererAgent:
    """Drives a circle of constant curvature: forward-left forever (the "forward_left"
    primitive, or its control with continuous actions)."""

    def act(self, observation: Any, view: Any) -> Any:
        return primitive_action(view, _FORWARD_LEFT)


class WallFollowerAgent:
    """Keeps a wall on its right, reading only the lidar scan (the last ``n_beams`` entries of
    the observation vector, ranges over the maximum range): turn left when something is closer than
    ``front_clearance`` ahead, bear right when the wall on the right is farther than
    ``right_band[1]``, left when nearer than ``right_band[0]``, else forward. For grid maps
    with a lidar."""

    def __init__(self, front_clearance: float = 0.8,
                 right_band: tuple[float, float] = (0.4, 1.0)) -> None:
        self.front_clearance = float(front_clearance)
        self.right_band = (float(right_band[0]), float(right_band[1]))

    def act(self, observation: Any, view: Any) -> Any:
        sensor = view.sensor
        if not isinstance(sensor, LidarSensor):
            raise ValueError("WallFollowerAgent needs a lidar (a grid env)")
        scan = np.asarray(observation_vector(observation), dtype=np.float64)[-sensor.n_beams:]
        ranges = scan * sensor.max_range
        angles = sensor.beam_angles
        ahead = ranges[np.abs(angles) <= np.deg2rad(15.0)]
        right = ranges[np.abs(angles + np.pi / 2) <= np.deg2rad(20.0)]
        if ahead.size and ahead.min() < self.front_clearance:
            return primitive_action(view, _TURN_LEFT)
        if right.size == 0 or right.min() > self.right_band[1]:
            return primitive_action(view, _FORWARD_RIGHT)
        if right.min() < self.right_band[0]:
            return primitive_action(view, _FORWARD_LEFT)
        return primitive_action(view, _FORWARD)
