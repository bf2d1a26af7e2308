"""What a planner may know: the belief, the map, the models and the actions; never the truth."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from active_loc.beliefs.ekf import EKFBelief
from active_loc.beliefs.ekf_filterpy import FilterpyEKFBelief
from active_loc.envs.actions import ControlLimits
from active_loc.maps import LandmarkMap
from active_loc.motion import UnicycleModel
from active_loc.sensors.landmarks import LandmarkSensor


@dataclass(frozen=True)
class PlannerView:
    """A snapshot for planning.

    Attributes:
        belief: a copy of the env's belief (B = 1); planners may change it freely.
        map: the landmark map of the episode.
        motion, sensor: the models the filter uses.
        action_space: the env's action space.
        limits: how actions decode into controls (action type, dt, speed and turn limits).
        step: steps taken so far in the episode.

    It holds no configuration beyond that: a fixed start pose, for one, is the truth.
    """

    belief: EKFBelief | FilterpyEKFBelief
    map: LandmarkMap
    motion: UnicycleModel
    sensor: LandmarkSensor
    action_space: spaces.Space
    limits: ControlLimits
    step: int

    def decode(self, action: object) -> NDArray[np.float64]:
        """Physical control (V m/s, omega rad/s) of an env action, as the env decodes it."""
        return self.limits.decode(action)

    def simulate(
        self,
        action: object,
        belief: EKFBelief | FilterpyEKFBelief,
        rng: np.random.Generator,
    ) -> tuple[EKFBelief | FilterpyEKFBelief, NDArray[np.float64], NDArray[np.bool_]]:
        """One hypothetical step from ``belief``: predict, then a measurement hypothesis.

        The pose that generates the hypothetical scan is drawn from the predicted belief
        (with ``rng``), not taken from the true pose, which the view does not have.

        Returns:
            The updated copy of the belief, the scan ``(N, 2)`` and its visibility ``(N,)``.
        """
        out = belief.copy()
        out.predict(self.decode(action)[None])
        mean = out.mean[0]
        root = np.linalg.cholesky(out.cov[0] + 1e-12 * np.eye(3))
        pose = mean + root @ rng.standard_normal(3)
        z, visible = self.sensor.measure(pose, self.map.positions, rng)
        out.update(z[None], visible[None], self.map.positions)
        return out, z, visible
