"""What a planner may know: the belief, the map, the models and the actions; never the truth."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from active_loc.beliefs.association import DEFAULT_GATE, update_with_association
from active_loc.beliefs.ekf import EKFBelief
from active_loc.beliefs.ekf_filterpy import FilterpyEKFBelief
from active_loc.beliefs.grid import GridBelief
from active_loc.beliefs.mcl import MCLBelief
from active_loc.envs.actions import ControlLimits
from active_loc.geometry import wrap_angle
from active_loc.maps import LandmarkMap, OccupancyGrid
from active_loc.motion import UnicycleModel
from active_loc.sensors.landmarks import LandmarkSensor
from active_loc.sensors.lidar import LidarSensor, cast_ray
from active_loc.sensors.lidar_lattice import (
    lattice_field_log_likelihood,
    off_map_log_probability,
    padded_table,
)
from active_loc.sensors.range_table import RangeTable

AnyBelief = EKFBelief | FilterpyEKFBelief | MCLBelief | GridBelief


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
        known_correspondences: whether landmark measurements carry the landmark's identity;
            without them the EKF associates by maximum likelihood (Algorithm 3).
        association_gate: the probability of that association's validation gate (None: no
            gate).
        likelihood_exponent: the power a grid belief's filter raises a scan's likelihood to
            (an MCL belief carries its own).
        collision_penalty: what the env's reward subtracts on a blocked move (nats), so that
            planners can weigh a bump against the information a step gains.
        range_table: the beam model's casts precomputed for this map, when the env's filter
            uses them (``lidar_range_bins > 0``); :meth:`scan_log_likelihood` scores with it.

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
    association_gate: float | None = DEFAULT_GATE
    likelihood_exponent: float = 1.0
    collision_penalty: float = 0.0
    range_table: RangeTable | None = None

    def decode(self, action: object) -> NDArray[np.float64]:
        """Physical control (V m/s, omega rad/s) of an env action, as the env decodes it."""
        return self.limits.decode(action)

    def scan_log_likelihood(
        self, z: NDArray[np.float64], poses: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """The filter's lidar log-likelihoods ``(K,)`` (nats, not tempered) of a scan ``(M,)``
        at poses ``(K, 3)``, as the env's particle filter scores it: from the range table when
        there is one, else with the sensor's model (the likelihood field, or the beam model
        ray-casting every pose and beam)."""
        if not isinstance(self.map, OccupancyGrid) or not isinstance(self.sensor, LidarSensor):
            raise ValueError("scan_log_likelihood needs a grid map with a lidar")
        if self.range_table is not None:
            return self.range_table.log_likelihood(np.asarray(z, dtype=np.float64),
                                                   np.ascontiguousarray(poses, dtype=np.float64))
        return self.sensor.log_likelihood(z, poses, self.map.kernel_arrays(),
                                          self.map.distance_field())

    def simulate(
        self, action: object, belief: AnyBelief, rng: np.random.Generator
    ) -> tuple[AnyBelief, NDArray[np.float64], NDArray[np.bool_]]:
        """One hypothetical step from ``belief``: the updated copy of the belief, the scan and
        its visibility (:meth:`hypothesize` without whether the move was blocked)."""
        out, z, visible, _ = self.hypothesize(action, belief, rng)
        return out, z, visible

    def hypothesize(
        self, action: object, belief: AnyBelief, rng: np.random.Generator
    ) -> tuple[AnyBelief, NDArray[np.float64], NDArray[np.bool_], bool]:
        """One hypothetical step from ``belief``: predict, then a measurement hypothesis.

        The pose that generates the hypothetical scan is drawn from the predicted belief
        (with ``rng``: a Gaussian draw, a particle picked by weight, or a grid cell's pose
        picked by its mass), not taken from the true pose, which the view does not have.
        Without known correspondences the filter treats the hypothetical scan as the env's
        filter does (an EKF associates it by maximum likelihood, MCL per particle); the
        hypothesis has neither misses nor clutter. A grid belief is scored at its free cell
        poses, its likelihood raised to :attr:`likelihood_exponent` as the env's filter does.

        Returns:
            The updated copy of the belief, the scan (landmarks ``(N, 2)``, lidar ``(M,)``),
            its visibility (``(N,)``; all True for the lidar) and whether the hypothetical
            robot's move was blocked by a wall (grid maps; False on landmark maps, whose
            planners do not model the border).
        """
        out = belief.copy()
        control = self.decode(action)
        if isinstance(out, GridBelief):
            z, blocked = self._simulate_grid(out, control, rng)
            return out, z, np.ones(z.shape[0], dtype=np.bool_), blocked
        if not isinstance(out, MCLBelief):
            out.predict(control[None])
            root = np.linalg.cholesky(out.cov[0] + 1e-12 * np.eye(3))
            pose = out.mean[0] + root @ rng.standard_normal(3)
            z, visible = self.sensor.measure(pose, self.map.positions, rng)
            if self.known_correspondences:
                out.update(z[None], visible[None], self.map.positions)
            else:
                assert isinstance(out, EKFBelief)
                update_with_association(out, z[visible], self.map.positions,
                                        self.association_gate)
            return out, z, visible, False
        if isinstance(self.map, OccupancyGrid):
            # the robot's pose first: a move into a wall is blocked, and the robot knows it
            # (the env then predicts with V = 0), so bumping teaches the planner nothing
            cumulative = np.cumsum(out.weights)
            pick = int(np.searchsorted(cumulative, rng.random() * cumulative[-1], side="right"))
            pose, blocked = self._move(out.particles[min(pick, len(cumulative) - 1)], control)
            out.predict(np.array([0.0 if blocked else control[0], control[1]]), rng)
            arrays = self.map.kernel_arrays()
            z = self.sensor.measure(pose, arrays, rng)
            out.update(self.scan_log_likelihood(z, out.particles), rng)
            return out, z, np.ones(z.shape[0], dtype=np.bool_), blocked
        out.predict(control, rng)
        cumulative = np.cumsum(out.weights)
        pick = int(np.searchsorted(cumulative, rng.random() * cumulative[-1], side="right"))
        pose = out.particles[min(pick, len(cumulative) - 1)].copy()
        z, visible = self.sensor.measure(pose, self.map.positions, rng)
        out.update_landmarks(
            z, visible, self.map.positions, self.sensor, rng,
            known_correspondence=self.known_correspondences,
        )
        return out, z, visible, False

    def _move(
        self, pose: NDArray[np.float64], control: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], bool]:
        """A hypothetical robot at ``pose`` ``(3,)`` after ``control`` on the grid map,
        noise-free: turned, and moved unless the straight move crosses a wall. Returns the
        new pose and whether the move was blocked."""
        assert isinstance(self.map, OccupancyGrid)
        dt = self.motion.dt
        step = float(control[0]) * dt
        heading = float(pose[2])
        out = np.array([pose[0], pose[1], wrap_angle(heading + float(control[1]) * dt)])
        if step == 0.0:
            return out, False
        direction = heading if step > 0.0 else heading + np.pi
        values, res, ox, oy, c, s = self.map.kernel_arrays()
        run = cast_ray(values, res, ox, oy, c, s, float(pose[0]), float(pose[1]), direction,
                       abs(step), True)
        target = pose[:2] + step * np.array([np.cos(heading), np.sin(heading)])
        if run < abs(step) or not self.map.is_free(target):
            return out, True
        out[:2] = target
        return out, False

    def _simulate_grid(
        self, belief: GridBelief, control: NDArray[np.float64], rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], bool]:
        """Predict a grid belief with ``control``, scan from a cell pose drawn by its mass,
        correct (in place); returns the scan ``(M,)`` and whether the move was blocked."""
        assert isinstance(self.map, OccupancyGrid) and isinstance(self.sensor, LidarSensor)
        noise_std = np.sqrt(np.diag(self.motion.noise_cov))
        poses = belief.cell_poses()  # (X, Y, H, 3)
        cumulative = np.cumsum(belief.prob[0].reshape(-1))
        pick = int(np.searchsorted(cumulative, rng.random() * cumulative[-1], side="right"))
        # the robot's pose first, moved (a wall blocks it: the env then predicts with V = 0)
        pose, blocked = self._move(poses.reshape(-1, 3)[min(pick, cumulative.shape[0] - 1)],
                                   control)
        belief.predict_unicycle(0.0 if blocked else float(control[0]), float(control[1]),
                                self.motion.dt, noise_std)
        arrays = self.map.kernel_arrays()
        z = self.sensor.measure(pose, arrays, rng)
        free = belief.free[0]
        _, nx, ny, nh = belief.shape
        if self.sensor.model == "likelihood_field" and belief.origin == self.map.origin:
            # the env's scoring: the field on the lattice of cells laid over the map
            ratio = belief.cell_size / self.map.resolution
            table = padded_table(self.sensor.log_table(self.map.distance_field()),
                                 off_map_log_probability(self.sensor))
            full = lattice_field_log_likelihood(
                self.sensor, z, 2.0 * np.pi * np.arange(nh) / nh, (np.arange(nx) + 0.5) * ratio,
                (np.arange(ny) + 0.5) * ratio, free, self.map.resolution, table,
            )
        else:
            free_poses = poses[free]  # (F, H, 3)
            log_lik = self.sensor.log_likelihood(
                z, free_poses.reshape(-1, 3), arrays, self.map.distance_field()
            )
            full = np.full((nx, ny, nh), -np.inf)
            full[free] = log_lik.reshape(free_poses.shape[:2])
        belief.update_log(self.likelihood_exponent * full)
        return z, blocked
