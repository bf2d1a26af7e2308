"""The registered EKF ids start unlocalized: no landmark in view at reset, so no episode is
over before the agent has looked (start='unseen')."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import active_loc  # noqa: F401  (registers the ids)
from active_loc.sensors.landmarks import sees_a_landmark


@pytest.mark.parametrize("env_id", ["ActiveLoc/LandmarkEKF-v0",
                                    "ActiveLoc/LandmarkEKFUnknown-v0"])
def test_no_episode_of_the_ekf_ids_ends_at_the_first_step(env_id: str) -> None:
    env = gym.make(env_id)
    config = env.unwrapped.config
    assert config.start == "unseen"
    for seed in range(300):
        env.reset(seed=seed)
        core = env.unwrapped.core
        x, y, theta = core.pose[0]
        assert not sees_a_landmark(x, y, theta, core.maps[0].positions, config.fov,
                                   config.max_range)
        _, _, terminated, truncated, info = env.step(np.zeros(2, dtype=np.float32))
        assert not (terminated or truncated), seed
        assert not info["localized"]


def test_unseen_starts_are_reproducible_and_follow_the_seed() -> None:
    env = gym.make("ActiveLoc/LandmarkEKF-v0")
    env.reset(seed=3)
    first = env.unwrapped.core.pose[0].copy()
    env.reset(seed=3)
    np.testing.assert_array_equal(env.unwrapped.core.pose[0], first)
    env.reset(seed=4)
    assert not np.array_equal(env.unwrapped.core.pose[0], first)


def test_an_impossible_unseen_start_is_refused_naming_the_option() -> None:
    env = gym.make("ActiveLoc/LandmarkEKF-v0", fov=2 * np.pi, max_range=float("inf"))
    with pytest.raises(ValueError, match=r"start='unseen': no start pose without a landmark"):
        env.reset(seed=0)


def test_unseen_starts_need_the_ekf_on_a_landmark_map() -> None:
    with pytest.raises(ValueError, match=r"start='unseen' .* needs belief='ekf'"):
        gym.make("ActiveLoc/LandmarkMCL-v0", start="unseen")
