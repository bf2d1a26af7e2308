"""The maze's distinguishing search, and the horizon planner that falls back on it."""

from __future__ import annotations

import itertools

import gymnasium as gym
import numpy as np

import active_loc  # noqa: F401  (registers the ids)
from active_loc.agents.horizon import HorizonPlannerAgent
from active_loc.agents.maze_search import distinguishing_plan
from active_loc.envs.maze_core import MOVE_FORWARD


def _readings_after(view, poses: list[tuple[int, int, int]], plan: tuple[int, ...]) -> list[int]:
    """The depth each pose reads after the plan, moved by the env's own motion model."""
    free = view.belief.free[0]
    out = []
    for pose in poses:
        for action in plan:
            pose = view.motion.move(free, pose, action)[0]
        out.append(int(view.sensor.table[pose]))
    return out


def test_the_plan_is_the_shortest_that_tells_the_hypotheses_apart() -> None:
    """On ambiguous beliefs of test mazes, every shorter action sequence leaves all the
    hypotheses reading alike at each step, and the plan's last step reads them apart."""
    env = gym.make("ActiveLoc/Maze-v0", size=7, episode_length=30, test_set=40)
    checked = 0
    for index in range(40):
        env.reset(seed=index)
        for action in (0, 0, 0):  # a full turn: the hypotheses that read the same around
            env.step(action)
        view = env.unwrapped.planner_view()
        poses = [tuple(int(v) for v in p) for p in np.argwhere(view.belief.prob[0] > 0)]
        if not 2 <= len(poses) <= 12:
            continue
        plan = distinguishing_plan(view, 8)
        if plan is None:
            continue
        checked += 1
        assert len(set(_readings_after(view, poses, tuple(plan)))) > 1
        for length in range(1, len(plan)):
            for shorter in itertools.product(range(3), repeat=length):
                assert len(set(_readings_after(view, poses, shorter))) == 1, (index, shorter)
    assert checked >= 10


def test_a_localized_belief_needs_no_plan() -> None:
    env = gym.make("ActiveLoc/Maze-v0", size=7, episode_length=30, test_set=1)
    env.reset(seed=0)
    view = env.unwrapped.planner_view()
    assert distinguishing_plan(view, 0) is None  # no steps left to plan
    for _ in range(30):  # until localized
        env.step(int(HorizonPlannerAgent(seed=0).act(None, env.unwrapped.planner_view())))
        view = env.unwrapped.planner_view()
        if np.count_nonzero(view.belief.prob[0]) == 1:
            break
    assert np.count_nonzero(view.belief.prob[0]) == 1
    assert distinguishing_plan(view, 10) is None


def test_the_horizon_planner_never_turns_in_place_while_the_belief_is_ambiguous() -> None:
    """7 x 7 mazes with L = 30: before the search, the planner's failures turned the same way
    to the end once no 3-step plan was informative. Now, while the belief holds two poses or
    more, never more than five turns in a row (three see every heading, two more face any
    of them),
    and every episode ends localized at the true pose."""
    env = gym.make("ActiveLoc/Maze-v0", size=7, episode_length=30, test_set=60)
    agent = HorizonPlannerAgent(seed=0)
    for index in range(60):
        obs, _ = env.reset(seed=index)
        turns = 0  # the turns in a row while ambiguous
        for _ in range(30):
            view = env.unwrapped.planner_view()
            ambiguous = int(np.count_nonzero(view.belief.prob[0])) > 1
            action = int(agent.act(obs, view))
            turns = turns + 1 if ambiguous and action != MOVE_FORWARD else 0
            assert turns <= 5, index
            obs, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
        assert info["is_success"], index
