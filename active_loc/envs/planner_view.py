"""What a planner may know: the belief, the map, the models and the actions; never the truth."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from active_loc.beliefs.association import DEFAULT_GATE, update_with_association
from active_loc.beliefs.ekf import EKFBelief
from active_loc.beliefs.ekf_filterpy import FilterpyEKFBelief
from active_loc.beliefs.grid import GridBelief
from active_loc.beliefs.lidar_dual import LidarDualProposal, update_with_scan
from active_loc.beliefs.mcl import MCLBelief
from active_loc.envs.actions import ControlLimits
from active_loc.maps import LandmarkMap, OccupancyGrid
from active_loc.motion import UnicycleModel, move_on_grid, move_within_bounds
from active_loc.sensors.landmarks import LandmarkSensor
from active_loc.sensors.lidar import LidarSensor
from active_loc.sensors.lidar_lattice import (
    lattice_field_log_likelihood,
    off_map_log_probability,
    padded_table,
)
from active_loc.sensors.range_table import RangeTable

AnyBelief = EKFBelief | FilterpyEKFBelief | MCLBelief | GridBelief
_NO_NOISE = np.zeros(3)  # the hypothetical robot moves without noise
_NO_BOX = np.zeros(4)  # planners do not model a landmark map's border


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
        scan_dual: the map's scan lattice, when the env's filter is mixture MCL on a grid map.

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
    scan_dual: LidarDualProposal | None = None

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

        The pose that generates the hypothetical scan is drawn from the belief with ``rng``
        (:meth:`draw_pose`), not taken from the true pose, which the view does not have. On
        landmark maps it is drawn from the predicted belief. On grid maps it is drawn first and
        moved (:meth:`move`), so that a move into a wall is blocked: the env then predicts with
        V = 0, and the robot knows it, so bumping teaches the planner nothing. The scan then
        corrects the belief as the env's filter would (:meth:`correct`).

        Returns:
            The updated copy of the belief, the scan (landmarks ``(N, 2)``, lidar ``(M,)``),
            its visibility (``(N,)``; all True for the lidar) and whether the hypothetical
            robot's move was blocked by a wall (grid maps; False on landmark maps, whose
            planners do not model the border).
        """
        out, pose, blocked = self.predict_hypothesis(action, belief, rng)
        z, visible = self.correct(out, pose, rng)
        return out, z, visible, blocked > 0

    # --- the pieces of a hypothetical step (planners that roll out longer use them too) ------

    def predict_hypothesis(
        self, action: object, belief: AnyBelief, rng: np.random.Generator, steps: int = 1
    ) -> tuple[AnyBelief, NDArray[np.float64], int]:
        """The first half of :meth:`hypothesize`, with ``action`` held for ``steps`` steps: a
        predicted copy of ``belief``, the pose ``(3,)`` the hypothetical robot scans from,
        and on how many of the steps its move was blocked (grid maps; 0 on landmark maps)."""
        out = belief.copy()
        control = self.decode(action)
        if isinstance(self.map, OccupancyGrid):
            pose, blocked = self.drive(out, self.draw_pose(out, rng), control, steps, rng)
            return out, pose, sum(blocked)
        for _ in range(steps):
            self.predict(out, control, False, rng)
        return out, self.draw_pose(out, rng), 0

    def drive(self, belief: AnyBelief, pose: NDArray[np.float64], control: NDArray[np.float64],
              steps: int, rng: np.random.Generator) -> tuple[NDArray[np.float64], list[bool]]:
        """The hypothetical robot at ``pose`` ``(3,)`` driven ``steps`` times with ``control``
        (:meth:`move`), ``belief`` predicted in place after each step as the env would
        (:meth:`predict`). Returns the final pose and, per step, whether it was blocked."""
        blocked = []
        for _ in range(steps):
            pose, bumped = self.move(pose, control)
            self.predict(belief, control, bumped, rng)
            blocked.append(bumped)
        return pose, blocked

    def draw_pose(self, belief: AnyBelief, rng: np.random.Generator) -> NDArray[np.float64]:
        """A pose ``(3,)`` drawn from ``belief`` with one draw of ``rng``: a Gaussian draw
        (EKF), a particle picked by weight (MCL) or a grid cell's pose picked by its mass."""
        if isinstance(belief, GridBelief):
            mass = belief.prob[0].reshape(-1)
            return belief.cell_poses().reshape(-1, 3)[_pick(mass, rng)].copy()
        if isinstance(belief, MCLBelief):
            return belief.particles[_pick(belief.weights, rng)].copy()
        root = np.linalg.cholesky(belief.cov[0] + 1e-12 * np.eye(3))
        return belief.mean[0] + root @ rng.standard_normal(3)

    def move(
        self, pose: NDArray[np.float64], control: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], bool]:
        """A hypothetical robot at ``pose`` ``(3,)`` after ``control`` (V m/s, omega rad/s),
        noise-free. On a grid map it turns, and moves unless the straight move crosses a wall;
        on a landmark map nothing blocks it. Returns the new pose and whether the move was
        blocked."""
        out = np.array(pose, dtype=np.float64)
        v, omega = float(control[0]), float(control[1])
        if isinstance(self.map, OccupancyGrid):
            return out, move_on_grid(out, v, omega, self.motion.dt, _NO_NOISE, self.map)
        move_within_bounds(out, v, omega, self.motion.dt, _NO_NOISE, _NO_BOX, False)
        return out, False

    def predict(self, belief: AnyBelief, control: NDArray[np.float64], blocked: bool,
                rng: np.random.Generator) -> None:
        """The filter's motion update of ``belief`` (in place) with ``control``, as the env
        makes it: with V = 0 when the move was ``blocked``. MCL draws its noise from ``rng``."""
        v = 0.0 if blocked else float(control[0])
        omega = float(control[1])
        if isinstance(belief, GridBelief):
            noise_std = np.sqrt(np.diag(self.motion.noise_cov))
            belief.predict_unicycle(v, omega, self.motion.dt, noise_std)
        elif isinstance(belief, MCLBelief):
            belief.predict(np.array([v, omega]), rng)
        else:
            belief.predict(np.array([[v, omega]]))

    def correct(
        self, belief: AnyBelief, pose: NDArray[np.float64], rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Simulate the scan from ``pose`` ``(3,)`` (sensor noise from ``rng``) and correct
        ``belief`` with it in place, as the env's filter would. Without known correspondences
        an EKF associates the scan by maximum likelihood and MCL scores it per particle; the
        hypothetical scan has neither misses nor clutter. A grid belief is scored at its free
        cell poses, its likelihood raised to :attr:`likelihood_exponent` as the env's filter
        does. Returns the scan (landmarks ``(N, 2)``, lidar ``(M,)``) and its visibility
        (``(N,)``; all True for the lidar)."""
        if isinstance(self.map, OccupancyGrid):
            z = self.sensor.measure(pose, self.map.kernel_arrays(), rng)
            if isinstance(belief, GridBelief):
                self._correct_grid(belief, z)
            else:
                update_with_scan(belief, z, functools.partial(self.scan_log_likelihood, z),
                                 self.scan_dual, rng)
            return z, np.ones(z.shape[0], dtype=np.bool_)
        z, visible = self.sensor.measure(pose, self.map.positions, rng)
        if isinstance(belief, MCLBelief):
            belief.update_landmarks(
                z, visible, self.map.positions, self.sensor, rng,
                known_correspondence=self.known_correspondences,
            )
        elif self.known_correspondences:
            belief.update(z[None], visible[None], self.map.positions)
        else:
            assert isinstance(belief, EKFBelief)
            update_with_association(belief, z[visible], self.map.positions,
                                    self.association_gate)
        return z, visible

    def _correct_grid(self, belief: GridBelief, z: NDArray[np.float64]) -> None:
        """Correct a grid belief with the scan ``z`` ``(M,)`` (in place)."""
        assert isinstance(self.map, OccupancyGrid) and isinstance(self.sensor, LidarSensor)
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
                scale=self.likelihood_exponent,
            )
        else:
            free_poses = belief.cell_poses()[free]  # (F, H, 3)
            log_lik = self.sensor.log_likelihood(
                z, free_poses.reshape(-1, 3), self.map.kernel_arrays(),
                self.map.distance_field()
            )
            full = np.full((nx, ny, nh), -np.inf)
            full[free] = self.likelihood_exponent * log_lik.reshape(free_poses.shape[:2])
        belief.update_log(full)


def _pick(weights: NDArray[np.float64], rng: np.random.Generator) -> int:
    """An index into ``weights`` ``(K,)`` (not necessarily normalized) drawn by weight with
    one uniform of ``rng``."""
    cumulative = np.cumsum(weights)
    pick = int(np.searchsorted(cumulative, rng.random() * cumulative[-1], side="right"))
    return min(pick, cumulative.shape[0] - 1)
