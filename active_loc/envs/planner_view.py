"""What a planner may know: the belief, the map, the models and the actions; never the truth."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from active_loc.beliefs.ekf import EKFBelief
from active_loc.beliefs.ekf_filterpy import FilterpyEKFBelief
from active_loc.beliefs.mcl import MCLBelief
from active_loc.envs.actions import ControlLimits
from active_loc.maps import LandmarkMap, OccupancyGrid
from active_loc.motion import UnicycleModel
from active_loc.sensors.landmarks import LandmarkSensor
from active_loc.sensors.lidar import LidarSensor

AnyBelief = EKFBelief | FilterpyEKFBelief | MCLBelief


@dataclass(frozen=True)
class PlannerView:
    """A snapshot for planning.

    Attributes:
        belief: a copy of the env's belief (B = 1); planners may change it freely.
        map: the map of the episode (landmarks or an occupancy grid).
        motion, sensor: the models the filter uses.
        action_space: the env's action space.
        limits: how actions decode into controls (action type, dt, speed and turn limits).
        step: steps taken so far in the episode.
        known_correspondences: whether landmark measurements carry the landmark's identity.

    It holds no configuration beyond that: a fixed start pose, for one, is the truth.
    """

    belief: AnyBelief
    map: LandmarkMap | OccupancyGrid
    motion: UnicycleModel
    sensor: LandmarkSensor | LidarSensor
    action_space: spaces.Space
    limits: ControlLimits
    step: int
    known_correspondences: bool = True

    def decode(self, action: object) -> NDArray[np.float64]:
        """Physical control (V m/s, omega rad/s) of an env action, as the env decodes it."""
        return self.limits.decode(action)

    def simulate(
        self, action: object, belief: AnyBelief, rng: np.random.Generator
    ) -> tuple[AnyBelief, NDArray[np.float64], NDArray[np.bool_]]:
        """One hypothetical step from ``belief``: predict, then a measurement hypothesis.

        The pose that generates the hypothetical scan is drawn from the predicted belief
        (with ``rng``: a Gaussian draw, or a particle picked by weight), not taken from the true
        pose, which the view does not have.

        Returns:
            The updated copy of the belief, the scan (landmarks ``(N, 2)``, lidar ``(M,)``) and
            its visibility (``(N,)``; all True for the lidar).
        """
        out = belief.copy()
        control = self.decode(action)
        if not isinstance(out, MCLBelief):
            out.predict(control[None])
            root = np.linalg.cholesky(out.cov[0] + 1e-12 * np.eye(3))
            pose = out.mean[0] + root @ rng.standard_normal(3)
            z, visible = self.sensor.measure(pose, self.map.positions, rng)
            out.update(z[None], visible[None], self.map.positions)
            return out, z, visible
        out.predict(control, rng)
        cumulative = np.cumsum(out.weights)
        pick = int(np.searchsorted(cumulative, rng.random() * cumulative[-1], side="right"))
        pose = out.particles[min(pick, len(cumulative) - 1)].copy()
        if isinstance(self.map, OccupancyGrid):
            arrays = self.map.kernel_arrays()
            z = self.sensor.measure(pose, arrays, rng)
            log_lik = self.sensor.log_likelihood(
                z, out.particles, arrays, self.map.distance_field()
            )
            out.update(log_lik, rng)
            return out, z, np.ones(z.shape[0], dtype=np.bool_)
        z, visible = self.sensor.measure(pose, self.map.positions, rng)
        out.update_landmarks(
            z, visible, self.map.positions, self.sensor, rng,
            known_correspondence=self.known_correspondences,
        )
        return out, z, visible
