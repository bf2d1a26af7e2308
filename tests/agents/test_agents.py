"""The agents: none reads the true pose, the planners beat random where activity matters, and
the look-ahead planner escapes the one-step agent's dithering in the maze."""

from __future__ import annotations

import dataclasses
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import active_loc  # noqa: F401  (registers the ids)
from active_loc.agents import (
    GreedyInfoGainAgent,
    HorizonPlannerAgent,
    WallFollowerAgent,
    make_agent,
    targets,
)
from active_loc.agents.planning import entropy_of, expected_cost_after
from active_loc.agents.registry import split_top_level
from active_loc.agents.targets import PoseSet, TargetPlannerAgent
from active_loc.geometry import compose


def scramble_truth(env: gym.Env, rng: np.random.Generator) -> Any:
    """Move the true pose somewhere else; returns what to restore."""
    base = env.unwrapped
    if hasattr(base, "core"):
        saved = base.core.pose.copy()
        base.core.pose[:] = saved + rng.normal(0.0, 3.0, saved.shape)
        return saved
    saved = base.true_pose
    base._core.set_pose(0, (int(rng.integers(1, 6)), int(rng.integers(1, 6)), int(rng.integers(4))))
    return saved


def restore_truth(env: gym.Env, saved: Any) -> None:
    base = env.unwrapped
    if hasattr(base, "core"):
        base.core.pose[:] = saved
    else:
        base._core.set_pose(0, saved)


CASES = [
    ("ActiveLoc/Maze-v0", {}, "random"),
    ("ActiveLoc/Maze-v0", {}, "greedy"),
    ("ActiveLoc/Maze-v0", {}, "horizon"),
    ("ActiveLoc/LandmarkEKF-v0", {}, "greedy"),
    ("ActiveLoc/LandmarkEKF-v0", {"action_type": "discrete"}, "horizon"),
    ("ActiveLoc/LandmarkEKF-v0", {}, "wanderer"),
    ("ActiveLoc/Textbook-v0", {}, "passive"),
    ("ActiveLoc/GridMCL-v0", {"n_particles": 2000, "kld": False}, "greedy"),
    ("ActiveLoc/GridMCL-v0", {"n_particles": 2000, "kld": False}, "horizon"),
    ("ActiveLoc/GridMCL-v0", {"action_type": "discrete"}, "wall_follower"),
]


@pytest.mark.parametrize(("env_id", "kwargs", "name"), CASES)
def test_a_scrambled_truth_gives_the_same_actions(env_id, kwargs, name):
    """Two agents with the same seed, one shown the env as it is and one shown it with the true
    pose moved elsewhere: if any agent read the truth through the view, they would part."""
    env = gym.make(env_id, **kwargs)
    honest, fooled = make_agent(name, env, seed=5), make_agent(name, env, seed=5)
    obs, _ = env.reset(seed=11)
    rng = np.random.default_rng(0)
    for _ in range(6):
        action = honest.act(obs, env.unwrapped.planner_view())
        saved = scramble_truth(env, rng)
        other = fooled.act(obs, env.unwrapped.planner_view())
        restore_truth(env, saved)
        np.testing.assert_array_equal(action, other)
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            break


def maze_success(agent: Any, episodes: int) -> float:
    env = gym.make("ActiveLoc/Maze-v0", size=7, test_set=episodes)
    successes = 0
    for _ in range(episodes):
        obs, info = env.reset()
        done = False
        while not done:
            obs, _, terminated, truncated, info = env.step(
                agent.act(obs, env.unwrapped.planner_view()))
            done = terminated or truncated
        successes += info["is_success"]
    return successes / episodes


def test_planners_beat_random_in_the_maze_and_looking_ahead_beats_greedy():
    """The first 100 mazes of the 7 x 7, L = 15 test set."""
    rates = {
        "random": maze_success(make_agent("random", gym.make("ActiveLoc/Maze-v0"), 0), 100),
        "greedy": maze_success(GreedyInfoGainAgent(seed=0), 100),
        "horizon": maze_success(HorizonPlannerAgent(seed=0), 100),
    }
    print(f"Maze-v0 7x7 L=15, 100 test mazes: {rates}")
    assert rates["greedy"] > rates["random"] + 0.1
    assert rates["horizon"] > rates["greedy"] + 0.1


def test_greedy_is_exact_in_the_maze():
    """Its scores are the expected posterior entropies, enumerated by hand here."""
    env = gym.make("ActiveLoc/Maze-v0")
    env.reset(seed=3)
    view = env.unwrapped.planner_view()
    actions, scores = GreedyInfoGainAgent(seed=0).scores(view)
    for action, score in zip(actions, scores, strict=True):
        expected = 0.0
        for _, p, posterior in view.outcomes(action, view.belief):
            prob = posterior.prob[0]
            nz = prob[prob > 0]
            expected += p * (-(nz * np.log(nz)).sum() + np.log(np.pi / 2))
        assert score == pytest.approx(expected, abs=1e-12)


def test_greedy_lowers_the_entropy_more_than_random_on_landmark_maps():
    results = {}
    for name in ("random", "greedy"):
        env = gym.make("ActiveLoc/LandmarkEKF-v0", terminate_when_localized=False)
        agent = make_agent(name, env, seed=1)
        finals = []
        for seed in range(8):
            obs, info = env.reset(seed=seed)
            for _ in range(40):
                obs, _, _, _, info = env.step(agent.act(obs, env.unwrapped.planner_view()))
            finals.append(info["entropy"])
        results[name] = float(np.mean(finals))
    print(f"LandmarkEKF-v0, mean entropy after 40 steps: {results}")
    assert results["greedy"] < results["random"] - 0.5


def test_the_wall_follower_drives_without_hitting_walls():
    env = gym.make("ActiveLoc/GridMCL-v0", action_type="discrete", n_particles=500, kld=False,
                   terminate_when_localized=False)
    agent = WallFollowerAgent()
    for seed in range(3):
        obs, info = env.reset(seed=seed)
        start = env.unwrapped.core.pose[0, :2].copy()
        for _ in range(150):
            obs, _, _, _, info = env.step(agent.act(obs, env.unwrapped.planner_view()))
        assert info["collisions"] <= 3
        assert np.hypot(*(env.unwrapped.core.pose[0, :2] - start)) > 0.5


@pytest.mark.parametrize(
    ("env_id", "name", "match"),
    [("ActiveLoc/Maze-v0", "passive", "no passive agent"),
     ("ActiveLoc/Maze-v0", "wanderer", "unicycle"),
     ("ActiveLoc/LandmarkEKF-v0", "wall_follower", "lidar"),
     ("ActiveLoc/LandmarkEKF-v0", "clever", "unknown agent")],
)
def test_agents_that_cannot_drive_the_env_are_refused(env_id, name, match):
    with pytest.raises(ValueError, match=match):
        make_agent(name, gym.make(env_id))


def test_parameters_in_brackets_reach_the_agent_and_the_rest_keep_their_defaults():
    env = gym.make("ActiveLoc/GridMCL-v0", action_type="discrete")
    agent = make_agent("horizon[horizon=1, hold=4, travel_cost=0]", env, seed=7)
    assert (agent.horizon, agent.hold, agent.travel_cost) == (1, 4, 0.0)
    assert agent.n_rollouts == HorizonPlannerAgent().n_rollouts
    assert make_agent("passive[right_band=[0.3, 0.9]]", env).right_band == (0.3, 0.9)
    assert split_top_level("random, horizon[horizon=1,hold=5],sb3:a.zip") == [
        "random", "horizon[horizon=1,hold=5]", "sb3:a.zip"]
    # the seed is the evaluation's, as for an agent named without parameters
    obs, _ = env.reset(seed=3)
    view = env.unwrapped.planner_view()
    plain, bracketed = make_agent("greedy", env, seed=9), make_agent("greedy[]", env, seed=9)
    assert plain.act(obs, view) == bracketed.act(obs, view)


@pytest.mark.parametrize(
    ("spec", "match"),
    [("horizon[hrizon=1]", "no parameter 'hrizon' .*takes horizon, hold"),
     ("horizon[hold=2.5]", "hold must be an integer"),
     ("greedy[n_hypotheses=true]", "n_hypotheses must be an integer"),
     ("horizon[travel_cost=cheap]", "'cheap', is not a number"),
     ("passive[right_band=[1]]", r"'passive \(wall_follower here\)': right_band must be a "
                                 "list of 2 numbers"),
     ("horizon[hold=1", "one pair of brackets"),
     ("horizon[hold]", "not key=value"),
     ("horizon[hold=1,hold=2]", "given twice"),
     ("greedy[seed=3]", "seed comes from the evaluation"),
     ("random[n=1]", "takes no parameters"),
     ("horizon[hold=0]", "must be >= 1"),
     ("clever[x=1]", "unknown agent")],
)
def test_bad_agent_parameters_are_refused_by_name(spec, match):
    with pytest.raises(ValueError, match=match):
        make_agent(spec, gym.make("ActiveLoc/GridMCL-v0", action_type="discrete"))


def test_a_planned_move_into_a_wall_is_blocked_as_in_the_env():
    """The planner's hypothetical robot stops at walls, and the filter then predicts with
    V = 0, as the env's does: a bump must not look informative (particles dying in the wall
    would shrink the simulated belief)."""
    from active_loc.maps import OccupancyGrid

    grid = OccupancyGrid.from_ascii(
        ["##########", "#........#", "#........#", "#........#", "##########"], 0.5
    )
    env = gym.make("ActiveLoc/GridMCLKidnapped-v0", map=grid, kidnap=False, n_particles=300,
                   kld=False, augmented=False, action_type="discrete")
    env.reset(seed=0)
    view = env.unwrapped.planner_view()
    speed = view.limits.primitives()[1]  # forward
    facing_wall = np.array([4.45, 1.25, 0.0])  # 0.05 m from the east wall
    moved, blocked = view.move(facing_wall, speed)
    assert blocked and np.array_equal(moved[:2], facing_wall[:2])
    open_floor = np.array([2.0, 1.25, 0.0])
    moved, blocked = view.move(open_floor, speed)
    assert not blocked
    assert moved[0] == pytest.approx(2.0 + speed[0] * view.limits.dt)


def test_a_move_on_a_landmark_map_is_the_noise_free_unicycle():
    env = gym.make("ActiveLoc/LandmarkEKF-v0")
    env.reset(seed=0)
    view = env.unwrapped.planner_view()
    pose = np.array([1.0, 2.0, 0.5])
    control = np.array([0.8, -0.4])
    moved, blocked = view.move(pose, control)
    dt = view.limits.dt
    expected = [1.0 + 0.8 * np.cos(0.5) * dt, 2.0 + 0.8 * np.sin(0.5) * dt, 0.5 - 0.4 * dt]
    assert not blocked
    np.testing.assert_allclose(moved, expected)


@pytest.mark.parametrize(("env_id", "kwargs"), [
    ("ActiveLoc/LandmarkEKF-v0", {}),
    ("ActiveLoc/LandmarkEKFUnknown-v0", {}),
    ("ActiveLoc/LandmarkMCL-v0", {"n_particles": 500, "kld": False}),
    ("ActiveLoc/GridMCL-v0", {"n_particles": 500, "kld": False}),
    ("ActiveLoc/GridMarkov-v0", {}),
])
def test_hypothesize_is_its_pieces_in_order(env_id, kwargs):
    """A rollout made of draw_pose, move, predict and correct steps the belief exactly as
    hypothesize does, so that long rollouts and one-step scores speak of the same filter."""
    env = gym.make(env_id, **kwargs)
    env.reset(seed=2)
    view = env.unwrapped.planner_view()
    env.action_space.seed(3)
    action = env.action_space.sample()
    control = view.decode(action)
    one, z_one, _, blocked_one = view.hypothesize(action, view.belief, np.random.default_rng(7))
    two, rng = view.belief.copy(), np.random.default_rng(7)
    if hasattr(view.map, "kernel_arrays"):
        pose, blocked = view.move(view.draw_pose(two, rng), control)
        view.predict(two, control, blocked, rng)
    else:
        view.predict(two, control, False, rng)
        pose, blocked = view.draw_pose(two, rng), False
    z_two, _ = view.correct(two, pose, rng)
    assert blocked == blocked_one
    np.testing.assert_array_equal(z_one, z_two)
    assert float(np.ravel(one.entropy())[0]) == float(np.ravel(two.entropy())[0])


SHARP = {"initial_belief": "gaussian", "initial_error_std": (0.0, 0.0, 0.0),
         "initial_belief_std": (0.03, 0.03, 0.02), "n_particles": 2000, "kld": False}


def test_greedy_with_hold_scores_the_action_held_and_every_bump(monkeypatch):
    """``hold`` steps of the action before the one scan, and the collision penalty for each
    step that a wall blocks."""
    env = gym.make("ActiveLoc/GridMCL-v0", action_type="discrete", **SHARP)
    env.reset(seed=5)
    view = env.unwrapped.planner_view()
    seen = []

    def correct(self, belief, pose, rng):
        seen.append(pose)
        return None, None

    monkeypatch.setattr(type(view), "correct", correct)
    forward = 1
    monkeypatch.setattr(type(view), "move", lambda self, pose, control: (pose + 1.0, True))
    score = expected_cost_after(view, forward, view.belief, 1, seed=0, hold=4)
    assert len(seen) == 1 and score == pytest.approx(entropy_of(view.belief)
                                                       + 4 * view.collision_penalty)
    with pytest.raises(ValueError, match="hold"):
        make_agent("greedy[hold=0]", env)


@pytest.mark.parametrize(("env_id", "kwargs"), [
    ("ActiveLoc/GridMCL-v0", SHARP),
    ("ActiveLoc/LandmarkMCL-v0", SHARP),
    ("ActiveLoc/GridMarkov-v0", {}),
])
def test_a_scan_that_teaches_nothing_scores_the_current_entropy(env_id, kwargs, monkeypatch):
    """Particle and grid entropies are histograms, so moving a sharp belief across bin edges
    changes them with nothing learned. The one-step score counts only what the scan removes:
    with a scan that changes nothing, every action scores the entropy the belief has now,
    though the predicted beliefs' entropies differ from action to action."""
    env = gym.make(env_id, action_type="discrete", **kwargs)
    env.reset(seed=5)
    view = dataclasses.replace(env.unwrapped.planner_view(), collision_penalty=0.0)
    now = entropy_of(view.belief)
    predicted = [entropy_of(view.predict_hypothesis(a, view.belief, np.random.default_rng(1))[0])
                 for a in range(env.action_space.n)]
    monkeypatch.setattr(type(view), "correct", lambda self, belief, pose, rng: (None, None))
    scores = [expected_cost_after(view, a, view.belief, 4, seed=1)
              for a in range(env.action_space.n)]
    print(f"{env_id}: now {now:.3f}, predicted {np.round(predicted, 3)}")
    assert max(predicted) - min(predicted) > 0.01
    np.testing.assert_allclose(scores, now, rtol=0, atol=1e-9)


def test_plans_that_teach_nothing_cost_the_same(monkeypatch):
    """The horizon planner counts entropy as the one-step score does: with scans that change
    nothing, no travel cost and no collision penalty, every plan costs the same."""
    env = gym.make("ActiveLoc/GridMCL-v0", action_type="discrete", **SHARP)
    env.reset(seed=5)
    view = dataclasses.replace(env.unwrapped.planner_view(), collision_penalty=0.0)
    monkeypatch.setattr(type(view), "correct", lambda self, belief, pose, rng: (None, None))
    agent = HorizonPlannerAgent(horizon=2, hold=2, travel_cost=0.0, n_rollouts=2, seed=0)
    _, scores = agent.scores(view)
    assert np.ptp(scores) < 1e-9


def test_a_target_whose_scan_teaches_nothing_scores_the_current_entropy(monkeypatch):
    """The target planner too: turning the whole pose set on the spot moves it across heading
    bin edges, but with a scan that tells nothing every turn scores the entropy of now."""
    env = gym.make("ActiveLoc/GridMCL-v0", action_type="discrete", **SHARP)
    env.reset(seed=5)
    view = env.unwrapped.planner_view()
    rng = np.random.default_rng(0)
    pose_set = PoseSet.from_view(view, 500, rng)
    hypotheses = pose_set.draw(3, rng)
    h0 = pose_set.entropy()
    turns = [np.array([0.0, 0.0, a]) for a in (0.1, 0.2, 0.3, 0.4, 0.5)]
    turned = [pose_set.entropy(compose(pose_set.poses, d[None, :])) for d in turns]
    monkeypatch.setattr(targets, "scan_scorer",
                        lambda view: lambda z, poses: np.zeros(poses.shape[0]))
    agent = TargetPlannerAgent(seed=0)
    scores = [agent._expected_entropy(view, pose_set, hypotheses, np.ones(3, dtype=bool), d,
                                      h0, seed=1) for d in turns]
    assert max(turned) - min(turned) > 0.01
    np.testing.assert_allclose(scores, h0, rtol=0, atol=1e-9)


def test_the_ekf_score_is_the_expected_posterior_entropy():
    """An EKF's entropy is the Gaussian's closed form, which no bin edge cuts: its score stays
    the mean posterior entropy over the hypotheses (plus the collision penalty)."""
    env = gym.make("ActiveLoc/LandmarkEKF-v0")
    env.reset(seed=2)
    view = env.unwrapped.planner_view()
    action = np.array([0.5, 0.3], dtype=np.float32)
    rng = np.random.default_rng(11)
    expected = np.mean([
        entropy_of(after) + (view.collision_penalty if blocked else 0.0)
        for after, _, _, blocked in (view.hypothesize(action, view.belief, rng) for _ in range(5))
    ])
    assert expected_cost_after(view, action, view.belief, 5, seed=11) == pytest.approx(
        expected, abs=1e-12)


@pytest.mark.parametrize("agent", [
    HorizonPlannerAgent(horizon=1, hold=3, n_rollouts=1, seed=0),
    GreedyInfoGainAgent(hold=3, seed=0),
])
def test_a_planner_with_hold_holds_each_action_then_plans_again(agent):
    env = gym.make("ActiveLoc/GridMCL-v0", n_particles=500, kld=False, action_type="discrete")
    obs, _ = env.reset(seed=4)
    calls = []
    scores = agent.scores
    agent.scores = lambda view: calls.append(view.step) or scores(view)
    actions = []
    for _ in range(7):
        action = agent.act(obs, env.unwrapped.planner_view())
        actions.append(action)
        obs, *_ = env.step(action)
    assert calls == [0, 3, 6]
    assert actions[0] == actions[1] == actions[2] and actions[3] == actions[4] == actions[5]


def test_the_horizon_planner_scores_every_plan_of_macro_actions():
    """Plans are sequences of the five moving primitives: 5 ** horizon of them, each with a
    finite cost; a plan's first macro-action scores as its best continuation."""
    from active_loc.agents.horizon import MACRO_PRIMITIVES

    env = gym.make("ActiveLoc/GridMCL-v0", n_particles=500, kld=False, action_type="discrete")
    env.reset(seed=1)
    view = env.unwrapped.planner_view()
    agent = HorizonPlannerAgent(horizon=2, hold=2, n_rollouts=2, seed=0)
    pose = view.draw_pose(view.belief, np.random.default_rng(0))
    costs = agent._plan_costs(view, view.belief, entropy_of(view.belief), pose, 2, [0, 0])
    assert costs.shape == (len(MACRO_PRIMITIVES) ** 2,) and np.all(np.isfinite(costs))
    actions, values = agent.scores(view)
    assert actions == list(MACRO_PRIMITIVES) and values.shape == (len(MACRO_PRIMITIVES),)
    # each first macro-action scores as its best continuation, averaged over the rollouts
    by_rollout = {0: np.random.default_rng(1).random(25), 1: np.random.default_rng(2).random(25)}
    agent._plan_costs = lambda view, belief, entropy, pose, depth, seed: by_rollout[seed[1]]
    _, values = agent.scores(view)
    expected = (0.5 * (by_rollout[0] + by_rollout[1])).reshape(5, 5).min(axis=1)
    np.testing.assert_allclose(values, expected)
    with pytest.raises(ValueError, match="hold"):
        HorizonPlannerAgent(hold=0)
