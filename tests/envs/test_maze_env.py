"""Tests of ``ActiveLoc/Maze-v0`` (``active_loc.envs.maze_env``).

The env's belief is checked against brute-force Bayes written here in plain Python, fed only
with the actions and the depths the env reports; dynamics, depth, success, replay of test
sets, observations, rewards, the planner view and rendering are checked on hand-made mazes.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections import defaultdict
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import active_loc  # noqa: F401  (registers the ids)
from active_loc.envs.maze_env import (
    MOVE_FORWARD,
    PAPER_EPISODE_LENGTHS,
    TURN_LEFT,
    TURN_RIGHT,
    MazeEnv,
)
from active_loc.maps.map_image import MapFileError, MapFileNotFoundError
from active_loc.maps.maze import TEST_SET_SEED, MazeSet, eller_maze, maze_test_set
from active_loc.sensors.depth import depth_table

STEPS = [(1, 0), (0, 1), (-1, 0), (0, -1)]


def snake() -> np.ndarray:
    """7 x 7: three full rows joined at the right end (not rotation-symmetric)."""
    return eller_maze(7, np.random.default_rng(0), p_join=1.0, p_down=0.0)


def s_maze() -> np.ndarray:
    """7 x 7, equal to its own 180-degree rotation: no pose can ever be told from its twin."""
    walls = np.ones((7, 7), dtype=bool)
    walls[1::2, 1:6] = False
    walls[2, 1] = False
    walls[4, 5] = False
    return walls


def one_maze_env(walls: np.ndarray, start: tuple[int, int, int], **kwargs) -> MazeEnv:
    return MazeEnv(test_set=MazeSet(walls[None], np.array([start])), **kwargs)


def walk_depth(walls: np.ndarray, x: int, y: int, h: int) -> int:
    d = 0
    while not walls[y, x]:
        d += 1
        x, y = x + STEPS[h][0], y + STEPS[h][1]
    return d


def brute_move(walls: np.ndarray, pose: tuple, action: int) -> tuple:
    x, y, h = pose
    if action == TURN_LEFT:
        return (x, y, (h + 1) % 4)
    if action == TURN_RIGHT:
        return (x, y, (h + 3) % 4)
    nx, ny = x + STEPS[h][0], y + STEPS[h][1]
    return pose if walls[ny, nx] else (nx, ny, h)


def brute_belief(walls: np.ndarray, actions: list[int], depths: list[int]) -> dict:
    """Bayes over every free pose: uniform, then the first depth, then move + depth."""
    n = walls.shape[0]
    poses = [(x, y, h) for x in range(n) for y in range(n) for h in range(4) if not walls[y, x]]
    bel = {p: 1.0 / len(poses) for p in poses}

    def correct(bel: dict, z: int) -> dict:
        kept = {p: w for p, w in bel.items() if walk_depth(walls, *p) == z}
        total = sum(kept.values())
        return {p: w / total for p, w in kept.items()}

    bel = correct(bel, depths[0])
    for action, z in zip(actions, depths[1:], strict=True):
        moved: dict = defaultdict(float)
        for p, w in bel.items():
            moved[brute_move(walls, p, action)] += w
        bel = correct(dict(moved), z)
    return bel


# --- configuration ----------------------------------------------------------------------------


@pytest.mark.parametrize("size", [7, 15, 21])
def test_spaces_and_default_episode_length(size: int) -> None:
    env = MazeEnv(size=size)
    assert env.action_space == gym.spaces.Discrete(3)
    assert env.observation_space.shape == (5, size, size)
    assert env.observation_space.dtype == np.float32
    assert env.episode_length == PAPER_EPISODE_LENGTHS[size][0]
    flat = MazeEnv(size=size, observation="flat")
    assert flat.observation_space.shape == (5 * size * size + 2,)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"size": 9}, "size"),
        ({"size": 7.0}, "size"),
        ({"episode_length": 0}, "episode_length"),
        ({"episode_length": 2.5}, "episode_length"),
        ({"observation": "image"}, "observation"),
        ({"reward": "logdet"}, "reward"),
        ({"action_type": "continuous"}, "action_type"),
        ({"belief": "mcl"}, "belief"),
        ({"terminate_when_localized": "yes"}, "terminate_when_localized"),
        ({"collision_penalty": -0.1}, "collision_penalty"),
        ({"collision_penalty": float("nan")}, "collision_penalty"),
        ({"collision_penalty": "high"}, "collision_penalty"),
        ({"maze_index": -1}, "maze_index"),
        ({"maze_index": 5, "test_set": 5}, "maze_index"),
        ({"test_set": 0}, "test_set"),
        ({"size": 15, "test_set": maze_test_set(7, 3, 0)}, "test_set"),
    ],
)
def test_bad_configuration_names_the_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        MazeEnv(**kwargs)


def test_make_passes_kwargs_and_rejects_unknown_ones() -> None:
    env = gym.make("ActiveLoc/Maze-v0", size=15, episode_length=40, action_type="discrete")
    assert env.unwrapped.size == 15 and env.unwrapped.episode_length == 40
    assert env.spec is not None and env.spec.max_episode_steps is None
    with pytest.raises(ValueError, match="action_type"):
        gym.make("ActiveLoc/Maze-v0", action_type="continuous")
    with pytest.raises(TypeError, match="n_particles"):
        gym.make("ActiveLoc/Maze-v0", n_particles=10)


# --- dynamics, sensing, belief ----------------------------------------------------------------


def test_actions_move_the_robot_as_specified_and_walls_block() -> None:
    env = one_maze_env(snake(), (1, 1, 2))  # bottom-left corner, facing west (a wall)
    _, info = env.reset()
    assert env.true_pose == (1, 1, 2) and info["depth"] == 1
    _, _, _, _, info = env.step(MOVE_FORWARD)
    assert env.true_pose == (1, 1, 2) and info["collisions"] == 1
    assert info["reward_terms"]["collision"] == 0.0
    env.step(TURN_LEFT)  # west -> south
    assert env.true_pose == (1, 1, 3)
    env.step(TURN_LEFT)  # south -> east
    _, _, _, _, info = env.step(MOVE_FORWARD)
    assert env.true_pose == (2, 1, 0) and info["collisions"] == 1
    assert info["depth"] == 4  # (2, 1) to (5, 1)
    env.step(TURN_RIGHT)  # east -> south
    assert env.true_pose == (2, 1, 3)


def test_a_collision_penalty_is_charged_on_blocked_moves_only() -> None:
    """The reward of a forward move into a wall loses ``collision_penalty``; turns and free
    moves keep the paper's reward. The vector env's members are charged alike."""
    plain = one_maze_env(snake(), (1, 1, 2))
    charged = one_maze_env(snake(), (1, 1, 2), collision_penalty=0.25)
    plain.reset()
    charged.reset()
    bumps = 0
    for action in (MOVE_FORWARD, TURN_LEFT, TURN_LEFT, MOVE_FORWARD):  # a bump, then free
        _, r_plain, _, _, _ = plain.step(action)
        _, r_charged, _, _, info = charged.step(action)
        blocked = info["collisions"] > bumps
        bumps = info["collisions"]
        assert info["reward_terms"]["collision"] == (-0.25 if blocked else 0.0)
        assert r_charged == pytest.approx(r_plain + info["reward_terms"]["collision"])
    assert bumps == 1
    venv = gym.make_vec("ActiveLoc/Maze-v0", 2, vectorization_mode="vector_entry_point",
                        collision_penalty=0.25)
    single = gym.make("ActiveLoc/Maze-v0", collision_penalty=0.25)
    venv.reset(seed=4)
    single.reset(seed=4)
    for _ in range(10):
        _, rewards, _, _, infos = venv.step(np.array([MOVE_FORWARD, TURN_LEFT]))
        _, reward, _, _, info = single.step(MOVE_FORWARD)
        assert rewards[0] == reward and infos["reward_collision"][0] == (
            info["reward_terms"]["collision"])


def test_depth_is_cells_to_the_first_wall_counting_the_robot_cell() -> None:
    env = one_maze_env(snake(), (5, 1, 1))  # bottom-right, facing north up the right column
    _, info = env.reset()
    assert info["depth"] == 5  # (5, 1) .. (5, 5)
    env.step(TURN_LEFT)  # west along the bottom row
    _, _, _, _, info = env.step(TURN_LEFT)  # south: the border
    assert info["depth"] == 1


def test_belief_equals_brute_force_bayes_fed_with_the_reported_depths() -> None:
    test_set = maze_test_set(7, 5, seed=1)
    env = MazeEnv(test_set=test_set, episode_length=30)
    rng = np.random.default_rng(2)
    for k in range(5):
        obs, info = env.reset()
        walls = test_set.walls[k]
        actions, depths = [], [info["depth"]]
        for action in rng.integers(3, size=30).tolist():
            obs, _, _, _, info = env.step(action)
            actions.append(action)
            depths.append(info["depth"])
            assert info["depth"] == walk_depth(walls, *env.true_pose)
        bel = brute_belief(walls, actions, depths)
        prob = env.belief.prob[0]
        for x in range(7):
            for y in range(7):
                for h in range(4):
                    assert abs(prob[x, y, h] - bel.get((x, y, h), 0.0)) <= 1e-12
                    assert obs[h, x, y] == np.float32(prob[x, y, h])
        assert np.array_equal(obs[4], walls.T.astype(np.float32))


def test_reset_belief_is_uniform_then_the_first_depth() -> None:
    env = one_maze_env(snake(), (1, 1, 0))
    env.reset()
    table = depth_table(np.ascontiguousarray(~snake().T))
    consistent = table == 5
    assert np.array_equal(env.belief.prob[0] > 0, consistent)
    assert np.allclose(env.belief.prob[0][consistent], 1.0 / consistent.sum(), rtol=0, atol=1e-15)
    assert consistent.sum() == 8  # both ends of three rows and of the right column


# --- success, termination, rewards ------------------------------------------------------------


def test_success_is_belief_max_one_at_the_true_pose() -> None:
    env = MazeEnv(test_set=maze_test_set(7, 40, seed=3), episode_length=30)
    rng = np.random.default_rng(0)
    seen_success = seen_failure = False
    for _ in range(40):
        env.reset()
        for action in rng.integers(3, size=30).tolist():
            _, _, terminated, truncated, info = env.step(action)
            mode = tuple(int(v) for v in env.belief.mode()[0])
            localized = env.belief.max_prob()[0] == 1.0
            assert info["localized"] == localized
            assert info["is_success"] == (localized and mode == env.true_pose)
            if info["localized"]:
                assert info["is_success"]  # the exact filter never localizes wrongly
                assert info["pose_error"] == 0.0 and info["heading_error"] == 0.0
            assert not terminated
        assert truncated
        seen_success |= info["is_success"]
        seen_failure |= not info["is_success"]
    assert seen_success and seen_failure


def test_a_rotation_symmetric_maze_never_succeeds() -> None:
    env = one_maze_env(s_maze(), (1, 1, 0), episode_length=60)
    env.reset()
    rng = np.random.default_rng(0)
    for action in rng.integers(3, size=60).tolist():
        _, _, _, truncated, info = env.step(action)
        assert info["max_prob"] <= 0.5 + 1e-12
        assert not info["is_success"]
    assert truncated


def test_episode_runs_exactly_l_steps_and_terminate_when_localized_stops_early() -> None:
    env = gym.make("ActiveLoc/Maze-v0", episode_length=12)
    env.reset(seed=0)
    flags = [env.step(int(a))[2:4] for a in np.random.default_rng(0).integers(3, size=12)]
    assert flags[-1] == (False, True)
    assert all(f == (False, False) for f in flags[:-1])

    env = MazeEnv(test_set=maze_test_set(7, 30, seed=3), terminate_when_localized=True,
                  episode_length=40)
    rng = np.random.default_rng(1)
    terminated_once = False
    for _ in range(30):
        env.reset()
        for t in range(40):
            _, _, terminated, truncated, info = env.step(int(rng.integers(3)))
            assert terminated == info["localized"]
            if terminated:
                assert info["is_success"] and not truncated
                terminated_once = True
                break
            assert truncated == (t == 39)
    assert terminated_once


def test_info_keys_and_info_gain_telescopes() -> None:
    env = MazeEnv(size=15)
    _, info = env.reset(seed=4)
    assert set(info) >= {"pose_error", "heading_error", "entropy", "is_success", "localized",
                         "collisions", "reward_terms", "depth", "max_prob"}
    h0, total = info["entropy"], 0.0
    truncated = False
    while not truncated:
        _, reward, _, truncated, info = env.step(int(env.np_random.integers(3)))
        assert set(info["reward_terms"]) == {"info_gain", "step_cost", "collision"}
        assert reward == pytest.approx(sum(info["reward_terms"].values()), abs=1e-15)
        assert isinstance(reward, float) and math.isfinite(reward)
        total += reward
    assert total == pytest.approx(h0 - info["entropy"], abs=1e-9)


def test_entropy_uses_the_maze_cell_volume() -> None:
    env = one_maze_env(snake(), (1, 1, 0))
    _, info = env.reset()
    assert info["entropy"] == pytest.approx(math.log(8) + math.log(math.pi / 2), abs=1e-12)


@pytest.mark.parametrize("reward", ["neg_entropy", "max_prob"])
def test_other_rewards(reward: str) -> None:
    env = MazeEnv(reward=reward)
    env.reset(seed=0)
    for a in (2, 0, 2, 1, 2):
        _, r, _, _, info = env.step(a)
        expected = -info["entropy"] if reward == "neg_entropy" else info["max_prob"]
        assert r == expected and info["reward_terms"][reward] == expected


# --- replay of test sets ----------------------------------------------------------------------


def test_a_test_set_is_replayed_in_order_and_maze_index_pins_one_entry() -> None:
    test_set = maze_test_set(7, 4, seed=9)
    env = MazeEnv(test_set=test_set)
    for k in (0, 1, 2, 3, 0):
        obs, _ = env.reset(seed=123)
        assert env.maze_index == k
        assert np.array_equal(env.walls, test_set.walls[k])
        assert env.true_pose == tuple(test_set.starts[k].tolist())
        assert np.array_equal(obs[4], test_set.walls[k].T)
    env.reset(options={"maze_index": 2})
    assert env.maze_index == 2
    env.reset()
    assert env.maze_index == 3

    pinned = MazeEnv(test_set=test_set, maze_index=1)
    for seed in (0, 1):
        pinned.reset(seed=seed)
        assert pinned.maze_index == 1
        assert np.array_equal(pinned.walls, test_set.walls[1])


def test_maze_index_alone_uses_the_standard_test_set() -> None:
    standard = maze_test_set(15, 8, TEST_SET_SEED)
    env = MazeEnv(size=15, maze_index=7)
    env.reset()
    assert np.array_equal(env.walls, standard.walls[7])
    assert env.true_pose == tuple(standard.starts[7].tolist())
    counted = MazeEnv(size=15, test_set=8)
    counted.reset()
    assert np.array_equal(counted.walls, standard.walls[0])


def test_random_mazes_come_from_the_seed_and_are_not_symmetric() -> None:
    env = MazeEnv()
    env.reset(seed=5)
    first = (env.walls.copy(), env.true_pose)
    env.reset(seed=5)
    assert np.array_equal(env.walls, first[0]) and env.true_pose == first[1]
    mazes = set()
    for seed in range(30):
        env.reset(seed=seed)
        assert not np.array_equal(env.walls, np.rot90(env.walls, 2))
        assert not np.array_equal(env.walls, np.rot90(env.walls))
        mazes.add(env.walls.tobytes())
    assert len(mazes) > 20


def test_random_policy_success_rate_is_in_the_expected_band() -> None:
    """The random policy localizes in about a third of 7 x 7, L = 15 episodes (0.33 on the
    1000-maze set; an independent implementation of the protocol measured about 0.35)."""
    env = MazeEnv(size=7, episode_length=15, test_set=maze_test_set(7, 200, seed=0))
    rng = np.random.default_rng(0)
    successes = 0
    for _ in range(200):
        env.reset()
        for action in rng.integers(3, size=15).tolist():
            _, _, _, truncated, info = env.step(action)
        assert truncated
        successes += info["is_success"]
    assert 0.2 <= successes / 200 <= 0.5


# --- observations -----------------------------------------------------------------------------


def test_flat_observation_layout() -> None:
    image_env = MazeEnv(episode_length=15)
    flat_env = MazeEnv(episode_length=15, observation="flat")
    image, _ = image_env.reset(seed=1)
    flat, info = flat_env.reset(seed=1)
    n = 7
    assert np.array_equal(flat[: 5 * n * n], image.reshape(-1))
    assert flat[-2] == np.float32(info["depth"] / (n - 2)) and flat[-1] == 0.0
    for t in range(1, 4):
        image, *_ = image_env.step(2)
        flat, _, _, _, info = flat_env.step(2)
        assert np.array_equal(flat[: 5 * n * n], image.reshape(-1))
        assert flat[-1] == np.float32(t / 15)
        assert flat_env.observation_space.contains(flat)


def test_invalid_actions_raise_value_error() -> None:
    env = MazeEnv()
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0)
    env.reset(seed=0)
    for bad in (3, -1, 1.5, True, "a", np.array([1]), np.array(1.0)):
        with pytest.raises(ValueError, match="action"):
            env.step(bad)
    env.step(np.int64(2))
    env.step(np.array(1))


# --- planner view -----------------------------------------------------------------------------


def test_planner_view_holds_no_truth() -> None:
    env = MazeEnv(size=15)
    env.reset(seed=2)
    for a in (2, 0, 2, 2):
        env.step(a)
    names = {f.name for f in dataclasses.fields(env.planner_view())}
    assert not any("pose" in name or "true" in name for name in names)
    view = env.planner_view()
    free = np.argwhere(~env.walls)
    env._core.set_pose(0, (int(free[3, 1]), int(free[3, 0]), (env.true_pose[2] + 2) % 4))
    scrambled = env.planner_view()
    assert np.array_equal(view.belief.prob, scrambled.belief.prob)
    assert view.map == scrambled.map and np.array_equal(view.walls, scrambled.walls)
    assert np.array_equal(view.sensor.table, scrambled.sensor.table)
    assert (view.step, view.episode_length) == (scrambled.step, scrambled.episode_length)
    view.belief.predict(np.zeros((4, 2), dtype=int), 1)  # a copy: the env is untouched
    assert np.array_equal(env.belief.prob, scrambled.belief.prob)


def test_planner_outcomes_and_simulate_agree_with_the_env() -> None:
    env = MazeEnv(size=15)
    env.reset(seed=6)
    rng = np.random.default_rng(0)
    for action in rng.integers(3, size=15).tolist():
        view = env.planner_view()
        outcomes = view.outcomes(action, view.belief)
        assert sum(p for _, p, _ in outcomes) == pytest.approx(1.0, abs=1e-12)
        _, _, _, _, info = env.step(action)
        match = [post for z, _, post in outcomes if z == info["depth"]]
        assert len(match) == 1
        assert np.allclose(match[0].prob, env.belief.prob, rtol=0, atol=1e-15)
        simulated, z = view.simulate(action, view.belief, rng)
        assert z.shape == (1,) and z[0] in {zz for zz, _, _ in outcomes}
        expected = next(post for zz, _, post in outcomes if zz == z[0])
        assert np.allclose(simulated.prob, expected.prob, rtol=0, atol=1e-15)


# --- rendering --------------------------------------------------------------------------------


@pytest.mark.parametrize("size", [7, 21])
def test_rgb_array_frames(size: int) -> None:
    env = gym.make("ActiveLoc/Maze-v0", size=size, render_mode="rgb_array")
    env.reset(seed=0)
    frames = [env.render()]
    for a in (2, 0, 2, 1, 2):
        env.step(a)
        frames.append(env.render())
    cell = max(8, 336 // size)
    for frame in frames:
        assert frame.dtype == np.uint8 and frame.shape == (size * cell, size * cell, 3)
    x, y, _ = env.unwrapped.true_pose
    block = frames[-1][(size - 1 - y) * cell : (size - y) * cell, x * cell : (x + 1) * cell]
    assert np.any(np.all(block == [44, 160, 44], axis=-1))  # the green robot
    assert np.all(frames[-1][:cell, :cell] == [45, 45, 52])  # the top-left border wall


def test_render_without_mode_warns_and_unknown_modes_are_rejected() -> None:
    env = MazeEnv()
    env.reset(seed=0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert env.render() is None
    assert caught
    with pytest.raises(ValueError, match="render_mode"):
        MazeEnv(render_mode="ansi")


def test_human_mode_shows_the_rgb_frame_headless() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    assert MazeEnv.metadata["render_modes"] == ["human", "rgb_array"]
    human = gym.make("ActiveLoc/Maze-v0", size=15, render_mode="human")
    rgb = gym.make("ActiveLoc/Maze-v0", size=15, render_mode="rgb_array")
    human.reset(seed=3)
    rgb.reset(seed=3)
    window = human.unwrapped._window
    assert window is not None and plt.fignum_exists(window.figure.number)  # shown by reset
    for a in (2, 0, 2, 2, 1):
        human.step(a)
        rgb.step(a)
        shown = np.asarray(window.figure.axes[0].images[0].get_array())
        assert np.array_equal(shown, rgb.render())  # step showed this step's frame
    assert human.render() is None
    number = window.figure.number
    human.close()
    assert not plt.fignum_exists(number)
    human.close()  # idempotent
    rgb.close()


# --- maze files and the paper's coordinates ---------------------------------------------------

#: a 7 x 7 maze as the paper's files store it: row 0 at the TOP, "#" = 1 (wall), "." = 0
ANL_PICTURE = (
    "#######",
    "#.....#",
    "#.###.#",
    "#...#.#",
    "###.#.#",
    "#.....#",
    "#######",
)
#: the paper's (row, col) offset per orientation: 0 east, 1 north (row - 1), 2 west, 3 south
ANL_STEPS = {0: (0, 1), 1: (-1, 0), 2: (0, -1), 3: (1, 0)}


def anl_map() -> np.ndarray:
    return np.array([[1.0 if ch == "#" else 0.0 for ch in line] for line in ANL_PICTURE])


def anl_file(path: Path, starts: list[tuple[int, int, int]], m: np.ndarray | None = None) -> Path:
    """An .npy of the paper's layout: the map flattened, then row, col, orientation."""
    m = anl_map() if m is None else m
    rows = [np.concatenate([m.flatten(), np.array([r, c]), np.array([o])]) for r, c, o in starts]
    np.save(path, np.stack(rows))
    return path


def anl_depth(m: np.ndarray, r: int, c: int, o: int) -> int:
    dr, dc = ANL_STEPS[o]
    d = 0
    while 0 <= r < m.shape[0] and 0 <= c < m.shape[1] and m[r, c] == 0:
        d, r, c = d + 1, r + dr, c + dc
    return d


def anl_episode(m: np.ndarray, start: tuple[int, int, int], actions: list[int]) -> tuple:
    """The paper's ``Maze2D`` in its own coordinates: its states ``(5, n, n)`` (posterior
    ``[o, r, c]`` then the map) and depths, after reset and after each action."""
    n = m.shape[0]
    lik = np.zeros((n - 2, 4, n, n))
    for o in range(4):
        for r in range(n):
            for c in range(n):
                d = anl_depth(m, r, c, o)
                if d > 0:
                    lik[d - 1, o, r, c] = 1.0
    r, c, o = start
    z = anl_depth(m, r, c, o)
    post = lik[z - 1] / lik[z - 1].sum()
    states, depths = [np.concatenate([post, m[None]])], [z]
    for a in actions:
        if a == TURN_LEFT:  # the paper's TURN_LEFT: orientation + 1
            prior, o = np.roll(post, 1, axis=0), (o + 1) % 4
        elif a == TURN_RIGHT:
            prior, o = np.roll(post, -1, axis=0), (o - 1) % 4
        else:
            prior = post.copy()
            if z != 1:  # every hypothesis reads z, so none is blocked
                prior = np.zeros_like(post)
                for oo, (dr, dc) in ANL_STEPS.items():
                    src = post[oo, max(0, -dr) : n - max(0, dr), max(0, -dc) : n - max(0, dc)]
                    prior[oo, max(0, dr) : n - max(0, -dr), max(0, dc) : n - max(0, -dc)] = src
            dr, dc = ANL_STEPS[o]
            if m[r + dr, c + dc] == 0:
                r, c = r + dr, c + dc
        z = anl_depth(m, r, c, o)
        post = lik[z - 1] * prior
        post /= post.sum()
        states.append(np.concatenate([post, m[None]]))
        depths.append(z)
    return states, depths


def test_a_paper_file_is_replayed_with_its_walls_and_start_cell_by_cell(tmp_path: Path) -> None:
    path = anl_file(tmp_path / "m7_n3.npy", [(1, 1, 0), (5, 1, 1), (3, 3, 3)])
    for test_set in (str(path), path):
        env = gym.make("ActiveLoc/Maze-v0", test_set=test_set)
        _, info = env.reset(seed=0)
        walls = env.unwrapped.walls
        for r, line in enumerate(ANL_PICTURE):
            for c, ch in enumerate(line):
                assert walls[6 - r, c] == (ch == "#"), (r, c)  # row 0 of the file is the top
        # (row 1, col 1, east) -> (ix 1, iy 5, heading 0): "#.....#" ahead, 5 cells
        assert env.unwrapped.true_pose == (1, 5, 0) and info["depth"] == 5
        _, info = env.reset()
        # (row 5, col 1, north) -> (1, 1, 1): north is toward row 0, up col 1: rows 5, then
        # the wall of row 4 ("###.#.#") -> 1 cell
        assert env.unwrapped.true_pose == (1, 1, 1) and info["depth"] == 1
        _, info = env.reset()
        # (row 3, col 3, south) -> (3, 3, 3): rows 3, 4, 5 of col 3 are free -> 3 cells
        assert env.unwrapped.true_pose == (3, 3, 3) and info["depth"] == 3
        assert env.unwrapped.maze_index == 2
        assert env.unwrapped.test_set.source == str(path)


def test_the_env_plays_a_paper_file_exactly_as_the_papers_maze2d(tmp_path: Path) -> None:
    """Same actions, same depths, and the paper's state is ``np.rot90(obs, axes=(1, 2))``."""
    generated = maze_test_set(7, 3, seed=5).to_anl()
    starts = [(1, 1, 0), (3, 5, 2), (5, 5, 1)]
    path = anl_file(tmp_path / "m7.npy", starts)
    rng = np.random.default_rng(0)
    sets = [(path, [anl_map()] * 3, starts)]
    generated_path = tmp_path / "generated.npy"
    np.save(generated_path, generated)
    sets.append((generated_path, [row[:49].reshape(7, 7) for row in generated],
                 [tuple(int(v) for v in row[49:]) for row in generated]))
    for file, maps, anl_starts in sets:
        env = MazeEnv(test_set=file, episode_length=30)
        for m, start in zip(maps, anl_starts, strict=True):
            actions = rng.integers(3, size=30).tolist()
            states, depths = anl_episode(m, start, actions)
            obs, info = env.reset()
            assert info["depth"] == depths[0]
            assert np.allclose(np.rot90(obs, axes=(1, 2)), states[0], rtol=0, atol=1e-6)
            for t, a in enumerate(actions, start=1):
                obs, _, _, _, info = env.step(a)
                assert info["depth"] == depths[t]
                assert np.allclose(np.rot90(obs, axes=(1, 2)), states[t], rtol=0, atol=1e-6)


def test_observation_is_x_first_the_transpose_of_walls_iy_ix() -> None:
    env = MazeEnv(size=15)
    obs, _ = env.reset(seed=4)
    for a in (2, 0, 2, 2):
        obs, *_ = env.step(a)
    n = 15
    walls = env.walls
    assert np.array_equal(obs[4], walls.T.astype(np.float32))  # obs[4, ix, iy] = walls[iy, ix]
    assert np.array_equal(obs[:4], np.moveaxis(env.belief.prob[0], 2, 0).astype(np.float32))
    # a wall cell (ix, iy) off the diagonal reads 1.0 at obs[4, ix, iy]
    iy, ix = next((y, x) for y, x in np.argwhere(walls) if walls[y, x] != walls[x, y])
    assert obs[4, ix, iy] == 1.0 and obs[4, iy, ix] == 0.0
    # the paper's state puts row 0 at the top: S[c] = obs[c].T[::-1]
    paper = np.rot90(obs, axes=(1, 2))
    assert np.array_equal(paper[4], walls[::-1].astype(np.float32))
    assert np.array_equal(paper, obs.transpose(0, 2, 1)[:, ::-1])
    assert paper.shape == (5, n, n)


def test_an_npz_of_maze_set_save_is_a_test_set(tmp_path: Path) -> None:
    original = maze_test_set(15, 3, seed=8)
    original.save(tmp_path / "set.npz")
    env = MazeEnv(size=15, test_set=tmp_path / "set.npz", maze_index=2)
    env.reset(seed=0)
    assert np.array_equal(env.walls, original.walls[2])
    assert env.true_pose == tuple(original.starts[2].tolist())


def test_a_file_of_another_size_or_a_bad_file_is_refused_at_construction(tmp_path: Path) -> None:
    path = anl_file(tmp_path / "m7.npy", [(1, 1, 0)])
    with pytest.raises(ValueError, match=r"test_set .*m7\.npy holds 7 x 7 mazes but size=15; "
                                         r"pass size=7"):
        MazeEnv(size=15, test_set=str(path))
    with pytest.raises(ValueError, match=r"maze_index must be in \[0, 1\), got 1"):
        MazeEnv(test_set=path, maze_index=1)
    bad = anl_file(tmp_path / "bad.npy", [(0, 0, 0)])  # a start on the border wall
    with pytest.raises(MapFileError, match=r"test_set: .*bad\.npy: maze 0 .* starts on a wall"):
        gym.make("ActiveLoc/Maze-v0", test_set=str(bad))
    with pytest.raises(MapFileNotFoundError, match=r"test_set: .*missing\.npy: no such maze"):
        MazeEnv(test_set=tmp_path / "missing.npy")
    with pytest.raises(ValueError, match=r"test_set: .*maze\.csv: a maze file must end in"):
        MazeEnv(test_set=str(tmp_path / "maze.csv"))
    with pytest.raises(ValueError, match=r"test_set must be a MazeSet, the path of a maze file"):
        MazeEnv(test_set=b"m7.npy")  # type: ignore[arg-type]


def test_a_maze_index_option_is_bounded_by_the_files_length(tmp_path: Path) -> None:
    env = MazeEnv(test_set=anl_file(tmp_path / "m7.npy", [(1, 1, 0), (5, 1, 1)]))
    env.reset(options={"maze_index": 1})
    assert env.maze_index == 1 and env.true_pose == (1, 1, 1)
    with pytest.raises(ValueError, match=r"must be an integer in \[0, 2\) \(the test set's "
                                         r"length\), got 2"):
        env.reset(options={"maze_index": 2})


def test_a_file_test_set_survives_the_vector_env_and_pickling(tmp_path: Path) -> None:
    import pickle

    path = anl_file(tmp_path / "m7.npy", [(1, 1, 0), (5, 1, 1), (3, 3, 3)])
    envs = gym.make_vec("ActiveLoc/Maze-v0", 2, vectorization_mode="vector_entry_point",
                        test_set=str(path))
    obs, _ = envs.reset(seed=0)
    assert obs.shape == (2, 5, 7, 7)
    assert np.array_equal(obs[0, 4], anl_map()[::-1].T.astype(np.float32))
    envs.close()
    env = MazeEnv(test_set=path)
    env.reset()
    clone = pickle.loads(pickle.dumps(env))
    assert clone.test_set.source == str(path) and not clone.test_set.walls.flags.writeable
    assert clone.step(2)[4]["depth"] == env.step(2)[4]["depth"]


# --- the planner view's depth -----------------------------------------------------------------


@pytest.mark.parametrize("observation", ["belief", "flat"])
def test_planner_view_depth_is_the_reading_the_env_just_made(observation: str) -> None:
    env = MazeEnv(size=15, observation=observation, episode_length=20)
    rng = np.random.default_rng(1)
    obs, info = env.reset(seed=9)
    for t in range(21):
        view = env.planner_view()
        assert isinstance(view.depth, int)
        assert view.depth == info["depth"]
        x, y, h = env.true_pose
        assert view.depth == int(view.sensor.table[x, y, h]) == walk_depth(env.walls, x, y, h)
        assert 1 <= view.depth <= 15 - 2
        if observation == "flat":
            assert obs[-2] == np.float32(view.depth / (15 - 2))
        if t < 20:
            obs, _, _, _, info = env.step(int(rng.integers(3)))
