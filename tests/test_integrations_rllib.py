"""``active_loc.integrations.rllib``: one PPO iteration of RLlib on ``ActiveLoc/LandmarkEKF-v0``
registered with ``register_env``, sampled by a remote env runner (another process, where only
the env creator imports ``active_loc``), and on the native vector env. Skipped when RLlib is
not installed."""

from __future__ import annotations

import math

import gymnasium as gym
import pytest

ray = pytest.importorskip("ray")
pytest.importorskip("ray.rllib.algorithms.ppo")

from ray.rllib.algorithms.ppo import PPOConfig  # noqa: E402
from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig  # noqa: E402
from ray.rllib.utils.metrics import (  # noqa: E402
    ENV_RUNNER_RESULTS,
    EPISODE_RETURN_MEAN,
    LEARNER_RESULTS,
    NUM_ENV_STEPS_SAMPLED_LIFETIME,
    NUM_EPISODES,
)

from active_loc.integrations.rllib import (  # noqa: E402
    RLLIB_ENV_IDS,
    env_creator,
    register_rllib_envs,
)

ENV_ID = "ActiveLoc/LandmarkEKF-v0"


def test_env_creator_makes_the_env() -> None:
    env = env_creator(ENV_ID)({"action_type": "discrete"})
    assert isinstance(env.action_space, gym.spaces.Discrete)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert "ActiveLoc/Maze-v0" in RLLIB_ENV_IDS and ENV_ID in RLLIB_ENV_IDS
    with pytest.raises(ValueError, match="ActiveLoc id"):
        register_rllib_envs(["CartPole-v1"])


def test_env_creator_vector_entry_point() -> None:
    """With ``num_envs`` (RLlib's vector_entry_point mode) the creator gives the native vector
    env."""
    envs = env_creator(ENV_ID)({"action_type": "discrete", "num_envs": 3})
    assert isinstance(envs, gym.vector.VectorEnv) and envs.num_envs == 3
    obs, _ = envs.reset(seed=0)
    assert obs.shape == (3, *envs.single_observation_space.shape)
    envs.close()


def ppo_config(num_env_runners: int, vectorize_mode: str, num_envs: int) -> PPOConfig:
    """A tiny PPO: 64 steps a batch, one epoch, a 16-unit MLP."""
    return (
        PPOConfig()
        # 16-step episodes, so that some end within the 64 sampled steps
        .environment(ENV_ID, env_config={"action_type": "discrete", "max_episode_steps": 16})
        .env_runners(num_env_runners=num_env_runners, num_envs_per_env_runner=num_envs,
                     gym_env_vectorize_mode=vectorize_mode,
                     rollout_fragment_length=64 // num_envs)
        .training(train_batch_size_per_learner=64, minibatch_size=32, num_epochs=1)
        .rl_module(model_config=DefaultModelConfig(fcnet_hiddens=[16]))
        .debugging(seed=0)
    )


def test_ppo_one_iteration() -> None:
    """One PPO iteration sampled by a remote env runner (one env), then one sampled by the
    local env runner on the native vector env (2 sub-envs)."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
             configure_logging=False, ignore_reinit_error=True)
    results = []
    try:
        assert register_rllib_envs() == RLLIB_ENV_IDS
        for config in (ppo_config(1, "sync", 1), ppo_config(0, "vector_entry_point", 2)):
            algo = config.build_algo()
            try:
                results.append(algo.train())
            finally:
                algo.stop()
    finally:
        ray.shutdown()
    for result in results:
        assert result["training_iteration"] == 1
        runners = result[ENV_RUNNER_RESULTS]
        assert runners[NUM_ENV_STEPS_SAMPLED_LIFETIME] >= 64
        assert runners[NUM_EPISODES] >= 1
        assert math.isfinite(runners[EPISODE_RETURN_MEAN])
        assert "default_policy" in result[LEARNER_RESULTS]
