"""The passive wanderer the grid-map tests drive with (it reads the scan, never the belief)."""

from __future__ import annotations

import numpy as np

#: lidar beams of the grid scenarios: the last BEAMS entries of an observation are the scan
BEAMS = 60
#: the discrete primitives it uses (active_loc.envs.actions.PRIMITIVES)
FORWARD, TURN_LEFT = 1, 4


def wander(observation: np.ndarray, max_range: float = 8.0) -> int:
    """Forward, or turn left when the scan shows a wall within 1 m ahead."""
    scan = observation[-BEAMS:]
    ahead = scan[BEAMS // 2 - 3 : BEAMS // 2 + 4].min() * max_range
    return FORWARD if ahead > 1.0 else TURN_LEFT
