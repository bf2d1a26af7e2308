"""Active Markov localization with targets: choose where to go and which way to look.

Fox, Burgard and Thrun ("Active Markov localization for mobile robots", Robotics and
Autonomous Systems 25, 1998) plan over *relative* motions: "go 3 m ahead and 2 m left, then
face right" means the same thing under every hypothesis of the belief, wherever it puts the
robot. A motion is scored by the entropy the belief is expected to have after the scan at its
end, plus the cost of the trip (and of bumping into a wall under hypotheses where the motion
is blocked). On grid maps with a lidar that is what finds the corridor in an arena of
identical rooms: one- or three-step lookahead cannot see that far.

Each plan (:meth:`TargetPlannerAgent.plan`):

1. The belief becomes a weighted pose set (MCL particles resampled down to ``max_particles``,
   or a grid belief's heaviest cell poses), and its *reference* pose is the weighted mean of
   the heaviest pose bin (0.5 m x 0.5 m x 30 degrees): the most likely hypothesis.
2. Candidate targets are ``n_targets`` cells spread out by farthest-point sampling over the
   cells reachable from the reference pose (shortest paths keeping ``clearance`` from walls,
   :mod:`active_loc.agents.paths`), each with ``n_headings`` headings to face at the end.
3. For each target the relative motion ``delta = reference^-1 (+) target`` is applied to every
   pose of the set, and for each of ``n_hypotheses`` poses drawn by weight (the same draws for
   every target) a scan is simulated from where that hypothesis ends up; the posterior
   entropy of the moved set after that scan, averaged over the draws, is the expected
   entropy. (Counted in two shares, so that where histogram bin edges cut the moved set does
   not count: the poses the move drops into walls in the bins they start in, what the scan
   removes in the bins they end in.) A draw whose path runs into a wall scores the current
   entropy plus the env's collision penalty.
4. The best target's path becomes waypoints in the robot's frame, followed with the motion
   primitives and carried along by dead reckoning of the agent's own controls; the agent
   re-plans when it gets there, or after ``replan_every`` steps.

Nothing here reads the true pose: plans come from the planner view alone.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from active_loc.agents.paths import PathGraph, farthest_points, thin_path
from active_loc.agents.planning import (
    collision_penalty_of,
    planning_belief,
    primitive_action,
    systematic_picks,
)
from active_loc.beliefs.grid import GridBelief
from active_loc.beliefs.mcl import MCLBelief
from active_loc.beliefs.particle_stats import histogram_entropy
from active_loc.envs.actions import PRIMITIVE_NAMES
from active_loc.geometry import circular_mean, compose, relative, to_robot_frame, wrap_angle
from active_loc.maps import OccupancyGrid
from active_loc.sensors.lidar import LidarSensor

#: the bins (m, m, rad) in which the reference pose is the heaviest
_MODE_BINS = (0.5, 0.5, math.pi / 6)


@dataclass
class PoseSet:
    """A belief as weighted poses: ``poses`` ``(K, 3)``, ``log_weights`` ``(K,)`` (normalized),
    the entropy ``bins`` (dx m, dy m, dtheta rad) and the power the filter raises a scan's
    likelihood to."""

    poses: NDArray[np.float64]
    log_weights: NDArray[np.float64]
    bins: tuple[float, float, float]
    likelihood_exponent: float

    @classmethod
    def from_view(cls, view: Any, max_poses: int, rng: np.random.Generator) -> PoseSet:
        """The view's belief (MCL or grid) as at most ``max_poses`` weighted poses."""
        belief = view.belief
        if isinstance(belief, MCLBelief):
            small = planning_belief(belief, max_poses, rng)
            n = small.n_active
            return cls(small.particles[:n].copy(), small.log_weights[:n].copy(),
                       tuple(small.entropy_bins), float(small.likelihood_exponent))
        if isinstance(belief, GridBelief):
            mass = belief.prob[0].reshape(-1)
            keep = np.argsort(mass)[::-1][:max_poses]
            keep = keep[mass[keep] > 0.0]
            _, _, _, nh = belief.shape
            log_w = np.log(mass[keep])
            log_w -= np.logaddexp.reduce(log_w)
            return cls(belief.cell_poses().reshape(-1, 3)[keep], log_w,
                       (belief.cell_size, belief.cell_size, 2.0 * math.pi / nh),
                       float(view.likelihood_exponent))
        raise ValueError(f"TargetPlannerAgent needs an MCL or grid belief, got "
                         f"{type(belief).__name__}")

    def entropy(self, poses: NDArray | None = None, log_weights: NDArray | None = None) -> float:
        """Histogram entropy (nats) of these poses, or of ``poses`` with ``log_weights``."""
        poses = self.poses if poses is None else poses
        log_weights = self.log_weights if log_weights is None else log_weights
        return float(histogram_entropy(poses, log_weights, *self.bins))

    def reference(self) -> NDArray[np.float64]:
        """``(3,)`` the weighted mean pose of the heaviest bin of :data:`_MODE_BINS`."""
        w = np.exp(self.log_weights - self.log_weights.max())
        keys = np.floor(self.poses / np.array(_MODE_BINS)).astype(np.int64)
        _, inverse = np.unique(keys, axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        heaviest = np.argmax(np.bincount(inverse, weights=w))
        members = inverse == heaviest
        wm = w[members]
        xy = np.average(self.poses[members, :2], axis=0, weights=wm)
        return np.array([xy[0], xy[1], float(circular_mean(self.poses[members, 2], wm))])

    def draw(self, count: int, rng: np.random.Generator) -> NDArray[np.float64]:
        """``count`` poses ``(count, 3)`` drawn by weight (systematic)."""
        weights = np.exp(self.log_weights - self.log_weights.max())
        return self.poses[systematic_picks(weights, count, rng)]


def scan_scorer(view: Any) -> Callable[[NDArray, NDArray], NDArray]:
    """How plans score a scan ``(M,)`` at poses ``(K, 3)`` (log-likelihoods, not tempered):
    as the env's filter does (:meth:`PlannerView.scan_log_likelihood`), except that a beam
    model without a range table is replaced by the likelihood field: ray-casting every pose and
    beam, thousands of times per plan, would take minutes."""
    sensor = view.sensor
    if view.range_table is not None or sensor.model == "likelihood_field":
        return view.scan_log_likelihood
    field = dataclasses.replace(sensor, model="likelihood_field")
    grid = view.map
    return lambda z, poses: field.log_likelihood(z, poses, grid.kernel_arrays(),
                                                 grid.distance_field())


@dataclass
class Plan:
    """Where the agent is going, in its own frame as of now: ``waypoints`` ``(W, 2)`` (m) and
    the ``heading`` (rad) to face at the end; ``value`` is what the planner expected (nats)."""

    waypoints: NDArray[np.float64]
    heading: float
    value: float


class TargetPlannerAgent:
    """Active Markov localization over relative targets (see the module docstring).

    Args:
        n_targets: candidate target cells per plan (the reference cell among them).
        n_headings: headings to face at each target, evenly spaced.
        n_hypotheses: poses drawn by weight to simulate the scan at the target.
        travel_cost: nats per metre of path.
        clearance: least distance (m) from a path's cells to a wall.
        replan_every: steps after which the agent re-plans even if not there yet.
        max_particles: particle beliefs are resampled down to this many (grid beliefs keep
            their heaviest this many cell poses).
        seed: the agent's own Generator (pose draws, simulated scans).
    """

    def __init__(self, n_targets: int = 24, n_headings: int = 8, n_hypotheses: int = 6,
                 travel_cost: float = 0.05, clearance: float = 0.3, replan_every: int = 15,
                 max_particles: int = 300, seed: int | None = None) -> None:
        counts = (n_targets, n_headings, n_hypotheses, replan_every, max_particles)
        if min(counts) < 1 or not travel_cost >= 0 or not clearance >= 0:
            raise ValueError("TargetPlannerAgent: n_targets, n_headings, n_hypotheses, "
                             "replan_every and max_particles must be >= 1, travel_cost and "
                             "clearance >= 0")
        self.n_targets = int(n_targets)
        self.n_headings = int(n_headings)
        self.n_hypotheses = int(n_hypotheses)
        self.travel_cost = float(travel_cost)
        self.clearance = float(clearance)
        self.replan_every = int(replan_every)
        self.max_particles = int(max_particles)
        self.rng = np.random.default_rng(seed)
        self._graph: PathGraph | None = None
        self._plan: Plan | None = None
        self._since_plan = 0

    # --- planning ------------------------------------------------------------------------------

    def _graph_for(self, grid: OccupancyGrid) -> PathGraph:
        if self._graph is None or self._graph.grid is not grid:
            self._graph = PathGraph.build(grid, self.clearance)
        return self._graph

    def plan(self, view: Any) -> Plan:
        """The best relative target from the view's belief (see the module docstring)."""
        grid, sensor = view.map, view.sensor
        if not isinstance(grid, OccupancyGrid) or not isinstance(sensor, LidarSensor):
            raise ValueError("TargetPlannerAgent needs a grid map with a lidar")
        pose_set = PoseSet.from_view(view, self.max_particles, self.rng)
        reference = pose_set.reference()
        graph = self._graph_for(grid)
        start = graph.nearest_node(reference[:2], max_distance=1.0)
        headings = 2.0 * math.pi * np.arange(self.n_headings) / self.n_headings
        if start < 0:  # no room to move near the reference: only turn on the spot
            paths = [reference[None, :2]]
            lengths = [0.0]
        else:
            distance, predecessors = graph.shortest_paths(start)
            reachable = np.flatnonzero(np.isfinite(distance))
            first = int(np.flatnonzero(reachable == start)[0])
            targets = reachable[farthest_points(graph.centres[reachable], first,
                                                self.n_targets)]
            paths = [graph.path_to(predecessors, int(t)) for t in targets]
            lengths = [float(distance[t]) for t in targets]
        hypotheses = pose_set.draw(self.n_hypotheses, self.rng)
        seed = int(self.rng.integers(2**63))  # common random numbers across the targets
        best: Plan | None = None
        h0 = pose_set.entropy()
        for path, length in zip(paths, lengths, strict=True):
            in_reference = to_robot_frame(thin_path(path, 0.2), reference)
            feasible = self._feasible(grid, hypotheses, in_reference)
            for heading in headings:
                goal = np.array([path[-1, 0], path[-1, 1], heading])
                delta = relative(reference, goal)
                value = self._expected_entropy(view, pose_set, hypotheses, feasible, delta, h0,
                                               seed) + self.travel_cost * length
                if best is None or value < best.value - 1e-9:
                    waypoints = to_robot_frame(thin_path(path, 0.4), reference)
                    best = Plan(waypoints, float(delta[2]), value)
        assert best is not None
        return best

    def _feasible(self, grid: OccupancyGrid, hypotheses: NDArray, in_reference: NDArray
                  ) -> NDArray[np.bool_]:
        """Whether each hypothesis ``(J, 3)`` can drive the path given in the reference
        frame ``(P, 2)``: every point of it at least half the clearance from a wall."""
        points = np.concatenate([in_reference, np.zeros((in_reference.shape[0], 1))], axis=1)
        world = compose(hypotheses[:, None, :], points[None, :, :])[..., :2]  # (J, P, 2)
        cells = grid.world_to_cell(world)
        inside = grid.in_grid(cells)
        ny, nx = grid.shape
        ix = np.clip(cells[..., 0], 0, nx - 1)
        iy = np.clip(cells[..., 1], 0, ny - 1)
        clear = grid.distance_field()[iy, ix] >= 0.5 * self.clearance
        return np.all(inside & clear, axis=1)

    def _expected_entropy(self, view: Any, pose_set: PoseSet, hypotheses: NDArray,
                          feasible: NDArray, delta: NDArray, h0: float, seed: int) -> float:
        """Mean over the hypotheses of the entropy after moving every pose by ``delta`` and
        scanning from where the hypothesis ends up (``h0`` plus the collision penalty for a
        hypothesis that cannot get there).

        The move's share (poses that would end in a wall drop out) is counted in the bins the
        poses start in, and the scan's share in the bins they end in: a rigid move of a sharp
        set across bin edges changes its histogram entropy with nothing learned (see
        :func:`~active_loc.agents.planning.expected_cost_after`)."""
        grid, sensor, score = view.map, view.sensor, scan_scorer(view)
        arrays = grid.kernel_arrays()
        rng = np.random.default_rng(seed)
        moved = compose(pose_set.poses, delta[None, :])
        prior = pose_set.log_weights + np.where(grid.is_free(moved[:, :2]), 0.0, -np.inf)
        penalty = collision_penalty_of(view)
        arrivable = np.isfinite(prior).any()
        if arrivable:
            h_arrived = pose_set.entropy(pose_set.poses, prior)  # in the starting bins
            h_moved = pose_set.entropy(moved, prior)
        total = 0.0
        for hypothesis, ok in zip(hypotheses, feasible, strict=True):
            if not ok or not arrivable:
                total += h0 + penalty
                continue
            scan = sensor.measure(compose(hypothesis, delta), arrays, rng)
            log_lik = score(scan, moved)
            h_scanned = pose_set.entropy(moved, prior + pose_set.likelihood_exponent * log_lik)
            total += h_arrived - (h_moved - h_scanned)
        return total / hypotheses.shape[0]

    # --- following the plan ----------------------------------------------------------------

    def _steer(self, view: Any) -> int | None:
        """The primitive that heads for the plan's next waypoint (or turns to its final
        heading); None when the plan is done."""
        plan = self._plan
        assert plan is not None
        while plan.waypoints.shape[0] and np.hypot(*plan.waypoints[0]) < 0.25:
            plan.waypoints = plan.waypoints[1:]
        if plan.waypoints.shape[0]:
            bearing = math.atan2(plan.waypoints[0, 1], plan.waypoints[0, 0])
            if abs(bearing) > 0.5:
                return PRIMITIVE_NAMES.index("turn_left" if bearing > 0 else "turn_right")
            if abs(bearing) > 0.12:
                return PRIMITIVE_NAMES.index("forward_left" if bearing > 0 else "forward_right")
            return PRIMITIVE_NAMES.index("forward")
        error = float(wrap_angle(plan.heading))
        if abs(error) > 0.2:
            return PRIMITIVE_NAMES.index("turn_left" if error > 0 else "turn_right")
        return None

    def _dead_reckon(self, view: Any, action: Any) -> None:
        """Carry the plan into the robot's frame after ``action`` (noise-free unicycle)."""
        plan = self._plan
        assert plan is not None
        v, omega = (float(c) for c in view.decode(action))
        dt = view.limits.dt
        moved = np.array([v * dt, 0.0, omega * dt])
        if plan.waypoints.shape[0]:
            plan.waypoints = to_robot_frame(plan.waypoints, moved)
        plan.heading = float(wrap_angle(plan.heading - moved[2]))

    def act(self, observation: Any, view: Any) -> Any:
        if view.step == 0:
            self._plan = None
        if self._plan is None or self._since_plan >= self.replan_every:
            self._plan, self._since_plan = self.plan(view), 0
        index = self._steer(view)
        if index is None:  # arrived: plan again from here
            self._plan, self._since_plan = self.plan(view), 0
            index = self._steer(view)
            if index is None:  # the best plan is to stay: look around instead
                index = PRIMITIVE_NAMES.index("turn_left")
        action = primitive_action(view, index)
        self._dead_reckon(view, action)
        self._since_plan += 1
        return action
