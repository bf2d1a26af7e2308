"""The registered ids: discrete-action variants of the landmark ids and the namespace list."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import active_loc  # noqa: F401  (registers the ids)
from active_loc.cli import main
from active_loc.envs.registration import ALL_ENV_IDS, DISCRETE_ENV_IDS

DISCRETE_IDS = [env_id for env_id, _, _ in DISCRETE_ENV_IDS]


def test_every_landmark_id_has_a_discrete_variant() -> None:
    assert DISCRETE_IDS == [
        "ActiveLoc/TextbookDiscrete-v0", "ActiveLoc/LandmarkEKFDiscrete-v0",
        "ActiveLoc/LandmarkEKFUnknownDiscrete-v0", "ActiveLoc/LandmarkMCLDiscrete-v0",
    ]
    assert set(DISCRETE_IDS) <= set(ALL_ENV_IDS) <= set(gym.registry)


@pytest.mark.parametrize("env_id", DISCRETE_IDS)
def test_a_discrete_id_is_its_base_id_with_discrete_actions(env_id: str) -> None:
    base_id = env_id.replace("Discrete-v0", "-v0")
    env, base = gym.make(env_id), gym.make(base_id, action_type="discrete")
    assert env.action_space == gym.spaces.Discrete(6) == base.action_space
    assert env.spec.max_episode_steps == base.spec.max_episode_steps
    obs, _ = env.reset(seed=5)
    expected, _ = base.reset(seed=5)
    actions = np.random.default_rng(0).integers(0, 6, size=25)
    for action in actions:
        np.testing.assert_array_equal(obs, expected)
        obs, reward, terminated, truncated, _ = env.step(int(action))
        expected, base_reward, *ends, _ = base.step(int(action))
        assert reward == base_reward and [terminated, truncated] == ends
        if terminated or truncated:
            break


def test_a_discrete_id_makes_a_native_vector_env_with_discrete_actions() -> None:
    envs = gym.make_vec("ActiveLoc/LandmarkEKFDiscrete-v0", 3,
                        vectorization_mode="vector_entry_point")
    assert envs.action_space == gym.spaces.MultiDiscrete([6, 6, 6])
    envs.reset(seed=0)
    envs.step(np.array([1, 2, 3]))
    envs.close()


def test_the_cli_lists_the_discrete_ids(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["envs"]) == 0
    listing = capsys.readouterr().out
    for env_id in ALL_ENV_IDS:
        assert env_id in listing
    assert "ActiveLoc/LandmarkEKFDiscrete-v0" in listing
