"""``observation="image"``: the belief as an image over the map, beside the observation vector.

The image's belief channels are checked against histograms computed here from the belief
itself, its map channel against a map drawn by hand; the env with an image observation must
step exactly as the one without (the same vector, rewards and infos), and its native vector
env as single envs seeded seed + i.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode

from active_loc.envs.belief_image import (
    grid_image_index,
    map_channel,
    observation_vector,
    particle_image,
    pooled_grid_image,
)
from active_loc.envs.config import LocalizationConfig
from active_loc.maps import LandmarkMap, OccupancyGrid
from tests.envs.test_envs import vector_actions

IMAGE_IDS = ("ActiveLoc/GridMCL-v0", "ActiveLoc/GridMarkov-v0", "ActiveLoc/LandmarkMCL-v0",
             "ActiveLoc/GridMCLKidnapped-v0")
#: a short limit, so that the sub-envs end (and are reset) within a test
LIMIT = 6


def histogram(particles: np.ndarray, weights: np.ndarray, bounds: tuple, size: int,
              headings: int) -> np.ndarray:
    """``(H, R, R)`` the weighted histogram of particles, brute force."""
    out = np.zeros((headings, size, size))
    x_min, y_min, x_max, y_max = bounds
    for (x, y, theta), w in zip(particles, weights, strict=True):
        ix = min(max(math.floor((x - x_min) / (x_max - x_min) * size), 0), size - 1)
        iy = min(max(math.floor((y - y_min) / (y_max - y_min) * size), 0), size - 1)
        wrapped = (theta + math.pi) % (2 * math.pi) - math.pi
        ih = min(math.floor((wrapped + math.pi) / (2 * math.pi) * headings), headings - 1)
        out[ih, iy, ix] += w
    return out


def test_particle_image_is_the_weighted_histogram() -> None:
    rng = np.random.default_rng(0)
    k, size, headings = 2000, 8, 6
    bounds = (-1.0, 2.0, 5.0, 6.0)
    particles = np.column_stack([rng.uniform(-2.0, 6.0, k), rng.uniform(1.0, 7.0, k),
                                 rng.uniform(-7.0, 7.0, k)])  # some outside the box
    weights = rng.random(k)
    weights /= weights.sum()
    out = np.full((headings + 1, size, size), 0.5, dtype=np.float32)
    particle_image(particles, weights, np.array(bounds), out)
    expected = histogram(particles, weights, bounds, size, headings)
    np.testing.assert_allclose(out[:headings], expected, atol=1e-6)
    assert np.all(out[headings] == 0.5)  # the map channel is left alone


def test_one_cell_holding_all_the_mass_stays_in_the_box() -> None:
    particles = np.zeros((1000, 3))
    weights = np.full(1000, 1e-3)
    out = np.zeros((3, 4, 4), dtype=np.float32)
    particle_image(particles, weights, np.array([-1.0, -1.0, 1.0, 1.0]), out)
    assert out.max() <= 1.0 and out.sum() == pytest.approx(1.0, abs=1e-5)


def test_grid_image_pools_the_belief_of_each_cell() -> None:
    env = gym.make("ActiveLoc/GridMarkov-v0", observation="image", image_size=8,
                   image_headings=4)
    obs, _ = env.reset(seed=2)
    rng = np.random.default_rng(2)
    for _ in range(4):
        obs, *_ = env.step(rng.uniform(-1, 1, 2))
    core = env.unwrapped.core
    belief = core.belief
    poses = belief.cell_poses().reshape(-1, 3)
    prob = belief.prob[0].reshape(-1)
    expected = histogram(poses, prob, core.maps[0].bounds, 8, 4)
    np.testing.assert_allclose(obs["image"][:4], expected, atol=1e-6)
    assert obs["image"][:4].sum() == pytest.approx(1.0, abs=1e-5)


def test_grid_image_index_maps_cells_and_headings() -> None:
    xs, ys = np.meshgrid([0.5, 1.5, 2.5, 3.5], [0.5, 1.5], indexing="ij")  # (4, 2) cells
    cells, channels = grid_image_index(xs, ys, np.array([0.0, np.pi / 2, np.pi, -np.pi / 2]),
                                       (0.0, 0.0, 4.0, 2.0), 2, 4)
    # image cells of 2 m x 1 m: x in [0, 2) -> column 0, y in [0, 1) -> row 0
    assert cells.tolist() == [0, 2, 0, 2, 1, 3, 1, 3]
    # bins from -pi: [-pi, -pi/2), [-pi/2, 0), [0, pi/2), [pi/2, pi); pi wraps to -pi
    assert channels.tolist() == [2, 3, 0, 1]
    prob = np.zeros((4, 2, 4))
    prob[3, 1, 2] = 0.75
    prob[0, 0, 0] = 0.25
    out = np.zeros((5, 2, 2), dtype=np.float32)
    pooled_grid_image(prob, cells, channels, out)
    assert out[0, 1, 1] == 0.75 and out[2, 0, 0] == 0.25 and out.sum() == 1.0


def test_map_channel_of_a_grid_and_of_landmarks() -> None:
    grid = OccupancyGrid.from_ascii(["##..", "#...", "....", "...?"], resolution=0.5)
    channel = map_channel(grid, grid.bounds, 2)  # 1 m x 1 m image cells of 4 map cells
    # rows from the bottom: "...?" and "...." below, "#..." and "##.." above
    np.testing.assert_allclose(channel, [[0.0, 0.25], [0.75, 0.0]])
    landmarks = LandmarkMap(np.array([[1.0, 1.0], [9.0, 9.0], [9.5, 8.0]]), (0.0, 0.0, 10.0, 10.0))
    marks = map_channel(landmarks, landmarks.bounds, 2)
    np.testing.assert_array_equal(marks, [[1.0, 0.0], [0.0, 1.0]])


@pytest.mark.parametrize("env_id", IMAGE_IDS)
def test_the_image_changes_nothing_else(env_id: str) -> None:
    """The same seeded steps with and without the image: the same vector, rewards, flags and
    infos; every image observation in the space, its belief mass summing to 1."""
    plain = gym.make(env_id)
    imaged = gym.make(env_id, observation="image")
    assert isinstance(imaged.observation_space, gym.spaces.Dict)
    assert imaged.observation_space["vector"] == plain.observation_space
    rng = np.random.default_rng(1)
    a, info_a = plain.reset(seed=11)
    b, info_b = imaged.reset(seed=11)
    for step in range(12):
        assert imaged.observation_space.contains(b)
        np.testing.assert_array_equal(observation_vector(b), a)
        assert b["image"][:-1].sum() == pytest.approx(1.0, abs=1e-4)
        assert info_a == info_b
        if step == 11:
            break
        action = rng.uniform(-1, 1, 2)
        a, reward_a, term_a, trunc_a, info_a = plain.step(action)
        b, reward_b, term_b, trunc_b, info_b = imaged.step(action)
        assert (reward_a, term_a, trunc_a) == (reward_b, term_b, trunc_b)
        if term_a or trunc_a:
            a, info_a = plain.reset()
            b, info_b = imaged.reset()


@pytest.mark.parametrize("env_id", ["ActiveLoc/GridMCL-v0", "ActiveLoc/GridMarkov-v0"])
def test_the_gymnasium_checker_passes(env_id: str) -> None:
    check_env(gym.make(env_id, observation="image").unwrapped, skip_render_check=True)


def assert_obs_equal(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> None:
    assert a.keys() == b.keys()
    for key in a:
        assert a[key].dtype == b[key].dtype and np.array_equal(a[key], b[key]), key


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
@pytest.mark.parametrize("env_id", ["ActiveLoc/GridMCL-v0", "ActiveLoc/GridMarkov-v0"])
def test_native_vector_env_equals_single_envs(env_id: str, mode: AutoresetMode) -> None:
    n = 3
    kwargs: dict[str, Any] = {"observation": "image", "image_size": 12}
    native = gym.make_vec(env_id, n, vectorization_mode="vector_entry_point",
                          autoreset_mode=mode, max_episode_steps=LIMIT, **kwargs)
    sync = gym.make_vec(env_id, n, vectorization_mode="sync",
                        vector_kwargs={"autoreset_mode": mode}, max_episode_steps=LIMIT,
                        **kwargs)
    assert native.single_observation_space == sync.single_observation_space
    obs_n, _ = native.reset(seed=4)
    obs_s, _ = sync.reset(seed=4)
    assert_obs_equal(obs_n, obs_s)
    rng = np.random.default_rng(4)
    ended = 0
    for _ in range(3 * LIMIT):
        actions = vector_actions(native.action_space, rng)
        obs_n, rew_n, term_n, trunc_n, info_n = native.step(actions)
        obs_s, rew_s, term_s, trunc_s, info_s = sync.step(actions)
        assert_obs_equal(obs_n, obs_s)
        assert np.array_equal(rew_n, rew_s)
        assert np.array_equal(term_n | trunc_n, term_s | trunc_s)
        if "final_obs" in info_n:
            for b in np.flatnonzero(info_n["_final_obs"]):
                assert_obs_equal(info_n["final_obs"][b], info_s["final_obs"][b])
        ended += int(np.sum(term_n | trunc_n))
    assert ended >= n
    native.close()
    sync.close()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"observation": "image"}, "needs belief='mcl' or 'grid'"),
        ({"belief": "mcl", "observation": "image", "image_size": 3}, "image_size"),
        ({"belief": "mcl", "observation": "image", "image_size": 32.0}, "image_size"),
        ({"belief": "mcl", "observation": "image", "image_headings": 0}, "image_headings"),
        ({"belief": "mcl", "observation": "pixels"}, "observation"),
    ],
)
def test_bad_image_settings_are_refused(kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        LocalizationConfig(**kwargs)
