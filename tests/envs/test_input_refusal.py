"""Inputs a user brings: each works, or is refused before any work with a ValueError naming
the field and what it allows (never a crash deep in numpy, a hang or a silent acceptance)."""

from __future__ import annotations

import time

import gymnasium as gym
import numpy as np
import pytest

import active_loc  # noqa: F401  (registers the ids)
from active_loc.envs.multi_robot import parallel_env
from active_loc.maps.generators import maze_map
from active_loc.maps.maze import MAX_TEST_SET_COUNT, max_test_set_count
from active_loc.maps.occupancy import OccupancyGrid

LANDMARK = "ActiveLoc/LandmarkMCL-v0"
GRID = "ActiveLoc/GridMCL-v0"


@pytest.mark.parametrize(
    "env_id", ["ActiveLoc/GridMCL-v0", "ActiveLoc/GridMarkov-v0", "ActiveLoc/GridMCLKidnapped-v0"]
)
def test_the_documented_maze_map_resets_and_steps_on_every_grid_id(env_id: str) -> None:
    env = gym.make(env_id, map="maze", n_particles=500)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    _, reward, _, _, info = env.step(env.action_space.sample())
    assert np.isfinite(reward) and np.isfinite(info["pose_error"])
    env.close()


def test_maze_map_fills_the_requested_size_with_whole_pitch_cells() -> None:
    grid = maze_map(np.random.default_rng(0), size_m=(20.0, 14.0), cell_size_m=2.0)
    width, height = grid.size_m
    assert 14.0 < width <= 20.0 and 10.0 < height <= 14.0


@pytest.mark.parametrize(
    "field",
    ["terminate_when_localized", "known_correspondences", "augmented", "kld", "kidnap",
     "unknown_reflects"],
)
@pytest.mark.parametrize("value", ["False", 0, 1.0, None])
def test_bool_fields_refuse_what_is_only_truthy(field: str, value: object) -> None:
    env_id = GRID if field in ("unknown_reflects", "kidnap") else LANDMARK
    with pytest.raises(ValueError, match=f"{field} must be True or False, got {value!r}"):
        gym.make(env_id, **{field: value})


@pytest.mark.parametrize("value", ["False", 0, None])
def test_multi_robot_team_reward_refuses_what_is_only_truthy(value: object) -> None:
    with pytest.raises(ValueError, match="team_reward must be True or False"):
        parallel_env(2, team_reward=value)


@pytest.mark.parametrize(
    ("env_id", "kwargs", "match"),
    [
        (LANDMARK, {"map_size": (float("nan"), 20.0)}, r"map_size \(width m, height m\) must be"),
        (LANDMARK, {"map_size": (float("inf"), 20.0)}, r"map_size \(width m, height m\) must be"),
        (LANDMARK, {"map_size": (1e6, 1e6)}, r"map_size must be \(width, height\) in \(2, "),
        (GRID, {"map_size": (1e6, 1e6)}, r"map_size must be \(width, height\) in \(2, "),
        (LANDMARK, {"map_size": "ab"}, r"map_size \(width m, height m\) must be 2 finite"),
        (LANDMARK, {"n_landmarks": (1,)}, r"n_landmarks \(low, high\) must be 2 integers"),
        (LANDMARK, {"n_landmarks": (1.5, 3.5)}, r"n_landmarks \(low, high\) must be 2 integers"),
        (GRID, {"kidnap": True, "kidnap_window": 0.5}, r"kidnap_window \(low, high\) must be"),
        (GRID, {"lidar_mixture": ("a", "b", "c", "d")}, r"lidar_mixture \(hit, short, max"),
        (GRID, {"lidar_mixture": (float("nan"), 0.1, 0.0, 0.0)}, r"lidar_mixture \(hit, short"),
        (LANDMARK, {"motion_noise_std": (1e300, 0.1, 0.1)}, r"motion_noise_std must be 0 or in"),
        (LANDMARK, {"range_std": 1e-300}, r"range_std must be in \[1e-06, 1e\+06\]"),
        (LANDMARK, {"range_std": 1e300}, r"range_std must be in \[1e-06, 1e\+06\]"),
        (LANDMARK, {"initial_belief_std": (1e-300, 1.0, 1.0)}, r"initial_belief_std must be in"),
        (GRID, {"grid_cell_size": 1e300}, r"grid_cell_size must be in \[0.01, 100.0\] m"),
        (GRID, {"grid_cell_size": 1e-300}, r"grid_cell_size must be in \[0.01, 100.0\] m"),
        (LANDMARK, {"n_particles": 10**12}, r"the largest: n_particles, .* over the bound"),
        (GRID, {"n_beams": 10**12}, "n_beams must be an integer in"),
        (GRID, {"grid_headings": 10**12}, "grid_headings must be an integer in"),
        (LANDMARK, {"max_landmarks": 10**12}, "max_landmarks must be an integer in"),
        (GRID, {"recovery_threshold": 0.0}, r"recovery_threshold must be in \(0, 1\]"),
        (GRID, {"recovery_threshold": 2.0}, r"recovery_threshold must be in \(0, 1\]"),
        (GRID, {"recovery_threshold": "half"}, "recovery_threshold must be"),
    ],
    ids=lambda v: str(v)[:50] if isinstance(v, dict) else None,
)
def test_unrepresentable_values_are_refused_naming_the_field(env_id: str, kwargs: dict,
                                                             match: str) -> None:
    with pytest.raises(ValueError, match=match):
        gym.make(env_id, **kwargs)


def test_a_config_over_the_memory_bound_is_refused_before_allocating() -> None:
    # 0.01 m cells over a 100 m x 100 m map with 360 headings: 3.6e10 grid poses
    with pytest.raises(ValueError, match=r"needs about .* GiB of arrays .* over the bound"):
        gym.make("ActiveLoc/GridMarkov-v0", grid_cell_size=0.01, map_size=(100.0, 100.0),
                 grid_headings=360)


def test_start_pose_outside_a_landmark_map_is_refused() -> None:
    with pytest.raises(ValueError, match=r"start_pose .* outside the map"):
        gym.make(LANDMARK, map="textbook", start="fixed", start_pose=(500.0, 500.0, 0.0))
    with pytest.raises(ValueError, match=r"start_pose .* outside the map"):
        gym.make(LANDMARK, start="fixed", start_pose=(-5.0, 1.0, 0.0))


def test_start_pose_in_an_occupied_cell_or_outside_a_grid_map_is_refused() -> None:
    rows = ["#" * 40] + ["#" + "." * 18 + "#" + "." * 19 + "#"] * 38 + ["#" * 40]
    grid = OccupancyGrid.from_ascii(rows, resolution=0.25)  # 10 m x 10 m, a wall at x = 4.875
    env = gym.make(GRID, map=grid, start="fixed", start_pose=(2.0, 5.0, 0.0))
    env.reset(seed=0)
    np.testing.assert_allclose(env.unwrapped.core.pose[0, :2], (2.0, 5.0))
    with pytest.raises(ValueError, match=r"start_pose \(4.8, 5.0\) is in an occupied"):
        gym.make(GRID, map=grid, start="fixed", start_pose=(4.8, 5.0, 0.0))
    with pytest.raises(ValueError, match=r"start_pose \(-100.0, 5.0\) is outside the map"):
        gym.make(GRID, map=grid, start="fixed", start_pose=(-100.0, 5.0, 0.0))


def test_a_fixed_start_blocked_on_a_generated_map_is_refused_at_reset() -> None:
    env = gym.make(GRID, map="rooms", start="fixed", start_pose=(0.05, 0.05, 0.0))
    with pytest.raises(ValueError, match=r"start_pose \(0.05, 0.05\) is in an occupied"):
        env.reset(seed=0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"test_set": 10**5}, r"test_set must be .* an integer count in \[1, 13056\]"),
        ({"maze_index": 10**5}, r"maze_index must be in \[0, 13056\), got 100000"),
        ({"size": 21, "test_set": 10**6}, r"test_set must be .* in \[1, 100000\]"),
    ],
)
def test_maze_test_sets_too_large_to_generate_are_refused_at_once(kwargs: dict,
                                                                  match: str) -> None:
    start = time.perf_counter()
    with pytest.raises(ValueError, match=match):
        gym.make("ActiveLoc/Maze-v0", **kwargs)
    assert time.perf_counter() - start < 1.0  # refused, not generated


def test_a_maze_index_option_beyond_the_standard_set_is_refused_at_once() -> None:
    env = gym.make("ActiveLoc/Maze-v0")
    with pytest.raises(ValueError, match=r"options\['maze_index'\] must be an integer in \[0, "):
        env.reset(options={"maze_index": 10**5})


def test_maze_test_set_count_is_bounded_by_the_distinct_pairs_of_the_size() -> None:
    assert max_test_set_count(5) == 112  # four 2 x 2 mazes, 7 free cells, 4 headings
    assert max_test_set_count(7) == 13056  # 192 spanning trees of 3 x 3 cells, 17 cells
    assert max_test_set_count(21) == MAX_TEST_SET_COUNT


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"workers": 1.5}, r"workers \(or None\) must be an integer in \[1, 1024\], got 1.5"),
        ({"workers": "2"}, r"workers \(or None\) must be an integer in \[1, 1024\], got '2'"),
        ({"max_episode_steps": 1.5}, r"max_episode_steps \(or None\) must be an integer >= 1"),
        ({"max_episode_steps": float("nan")}, r"max_episode_steps \(or None\) must be an "),
        ({"render_envs": 0}, r"render_envs must be an integer in \[1, 2\], got 0"),
    ],
)
def test_the_vector_env_refuses_bad_arguments_by_name(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        gym.make_vec(LANDMARK, 2, vectorization_mode="vector_entry_point", **kwargs)


@pytest.mark.parametrize("dtype_name", ["float32", "float16", "bfloat16", "float64"])
def test_torch_tensors_are_actions_in_every_float_dtype(dtype_name: str) -> None:
    torch = pytest.importorskip("torch")
    dtype = getattr(torch, dtype_name)
    env = gym.make("ActiveLoc/LandmarkEKF-v0")
    env.reset(seed=0)
    _, reward, *_ = env.step(torch.tensor([0.5, -0.25], dtype=dtype, requires_grad=True))
    assert np.isfinite(reward)
    vec = gym.make_vec("ActiveLoc/LandmarkEKF-v0", 2, vectorization_mode="vector_entry_point")
    vec.reset(seed=0)
    _, rewards, *_ = vec.step(torch.tensor([[0.5, -0.25], [0.0, 1.0]], dtype=dtype))
    assert np.isfinite(rewards).all()
    maze = gym.make("ActiveLoc/Maze-v0")
    maze.reset(seed=0)
    maze.step(torch.tensor(2))
    with pytest.raises(ValueError, match="must be an integer index, got tensor"):
        maze.step(torch.tensor(2.0, dtype=dtype))
