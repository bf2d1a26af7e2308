"""The target planner and its paths: shortest paths that keep clear of walls, and plans that
take a robot out of a room of identical rooms to where it can tell them apart."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import active_loc  # noqa: F401  (registers the ids)
from active_loc.agents import TargetPlannerAgent, make_agent
from active_loc.agents.paths import PathGraph, farthest_points, thin_path
from active_loc.maps import OccupancyGrid

# an L-shaped corridor, 1 m cells: free from (1, 1) along the bottom, then up the right side
L_CORRIDOR = """
#######
#....##
####.##
####.##
#######
"""


def l_corridor() -> OccupancyGrid:
    return OccupancyGrid.from_ascii(L_CORRIDOR.split(), resolution=1.0)


def test_shortest_paths_follow_the_corridor_with_diagonal_steps():
    graph = PathGraph.build(l_corridor(), clearance=0.0)
    start = graph.nearest_node(np.array([1.5, 3.5]), max_distance=0.1)
    end = graph.nearest_node(np.array([4.5, 1.5]), max_distance=0.1)
    lengths, predecessors = graph.shortest_paths(start)
    # two steps east, one diagonal into the bend, one south: 3 + sqrt(2), not 5
    assert lengths[end] == pytest.approx(3.0 + math.sqrt(2.0))
    path = graph.path_to(predecessors, end)
    np.testing.assert_allclose(path[0], [1.5, 3.5])
    np.testing.assert_allclose(path[-1], [4.5, 1.5])
    steps = np.hypot(*np.diff(path, axis=0).T)
    assert steps.sum() == pytest.approx(lengths[end])
    assert np.all(l_corridor().is_free(path))


def test_clearance_removes_the_cells_near_walls_and_unreachable_cells_are_inf():
    grid = l_corridor()
    assert PathGraph.build(grid, clearance=0.0).n_nodes == 6
    assert PathGraph.build(grid, clearance=1.01).n_nodes == 0
    two_rooms = OccupancyGrid.from_ascii(["#####", "#.#.#", "#####"], resolution=1.0)
    graph = PathGraph.build(two_rooms, clearance=0.0)
    lengths, _ = graph.shortest_paths(0)
    assert np.isinf(lengths).sum() == 1
    with pytest.raises(ValueError, match="clearance"):
        PathGraph.build(grid, clearance=-1.0)


def test_farthest_points_spread_out_and_thin_path_spaces_waypoints():
    points = np.array([[0.0, 0.0], [0.1, 0.0], [5.0, 0.0], [5.0, 5.0], [0.0, 5.0]])
    picks = farthest_points(points, 0, 3)
    assert picks[0] == 0 and picks[1] == 3 and 1 not in picks
    path = np.stack([np.linspace(0.0, 2.0, 21), np.zeros(21)], axis=1)
    waypoints = thin_path(path, 0.5)
    np.testing.assert_allclose(waypoints[:, 0], [0.5, 1.0, 1.5, 2.0])


@pytest.mark.parametrize("env_id", ["ActiveLoc/GridMCL-v0", "ActiveLoc/GridMarkov-v0"])
def test_a_scrambled_truth_gives_the_same_plans(env_id):
    """The planner reads the view only (a particle or a grid belief): moving the true pose
    does not change its actions."""
    env = gym.make(env_id, map="marked_rooms", action_type="discrete")
    honest, fooled = TargetPlannerAgent(seed=3), TargetPlannerAgent(seed=3)
    obs, _ = env.reset(seed=4)
    rng = np.random.default_rng(0)
    core = env.unwrapped.core
    for _ in range(4):
        action = honest.act(obs, env.unwrapped.planner_view())
        saved = core.pose.copy()
        core.pose[:] = saved + rng.normal(0.0, 3.0, saved.shape)
        other = fooled.act(obs, env.unwrapped.planner_view())
        core.pose[:] = saved
        assert action == other
        obs, *_ = env.step(action)


def test_from_a_room_of_identical_rooms_the_plan_leads_out_of_the_room():
    """A robot in the middle of one of the six identical rooms of ``marked_rooms`` whose
    belief has converged on the room's shape but not on which room: the best target is
    outside the room (in the corridor, where doors and the marked end tell the rooms
    apart), not a turn on the spot. Without a travel cost, so that the information decides:
    with tempered scans the best corridor target is expected to leave -2.18 nats and a turn on
    the spot -2.11, so the default cost of 0.05 nats per metre of a 4-6 m path tips the choice
    to the turn."""
    env = gym.make("ActiveLoc/GridMCL-v0", map="marked_rooms", action_type="discrete",
                   terminate_when_localized=False)
    env.reset(seed=2)
    base = env.unwrapped
    grid = base.core.maps[0]
    # the same pose in each room: rooms are copies along x (top row) and the bottom row is
    # the top row turned by 180 degrees about the map's centre
    ny, nx = grid.shape
    cx, cy = nx * grid.resolution / 2.0, ny * grid.resolution / 2.0
    width = nx * grid.resolution / 3.0
    top = [np.array([width * (i + 0.5), cy + 3.0, 0.3]) for i in range(3)]
    poses = top + [np.array([2 * cx - p[0], 2 * cy - p[1], p[2] + math.pi]) for p in top]
    assert all(grid.is_free(p[:2][None])[0] for p in poses)
    rng = np.random.default_rng(0)
    particles = np.concatenate([p + rng.normal(0.0, [0.05, 0.05, 0.02], (100, 3))
                                for p in poses])
    view = base.planner_view()
    view.belief.set_particles(particles)
    agent = TargetPlannerAgent(travel_cost=0.0, seed=0)
    plan = agent.plan(view)
    goal_in_reference = plan.waypoints[-1]
    assert np.hypot(*goal_in_reference) > 1.5, plan
    # the goal, put back on each hypothesis, is outside that hypothesis's room: y in the
    # corridor band around the map's centre line
    for pose in poses:
        c, s = math.cos(pose[2]), math.sin(pose[2])
        goal = pose[:2] + np.array([c * goal_in_reference[0] - s * goal_in_reference[1],
                                    s * goal_in_reference[0] + c * goal_in_reference[1]])
        assert abs(goal[1] - cy) < 1.5, (pose, goal)


def test_the_target_agent_needs_a_grid_env():
    with pytest.raises(ValueError, match="grid"):
        make_agent("targets", gym.make("ActiveLoc/LandmarkEKF-v0"))
