"""``active_loc.integrations.torchrl``: the ids as TorchRL envs pass ``check_env_specs`` and roll
out, single and as the native vector env. Skipped when TorchRL is not installed."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("torchrl")

import torch
from torchrl.data import Categorical
from torchrl.envs import GymEnv
from torchrl.envs.utils import check_env_specs

import active_loc  # noqa: F401
from active_loc.integrations.torchrl import DEFAULT_INFO_KEYS, make_torchrl_env

STEPS = 20
CASES = [
    ("ActiveLoc/Textbook-v0", {}),
    ("ActiveLoc/LandmarkEKF-v0", {}),
    ("ActiveLoc/LandmarkEKF-v0", {"action_type": "discrete"}),
    ("ActiveLoc/Maze-v0", {}),
]


def check_rollout(env: Any, steps: int, **kwargs: Any) -> Any:
    """``env.rollout(steps)`` with the observation of the gymnasium space, rewards and flags."""
    torch.manual_seed(0)
    rollout = env.rollout(steps, **kwargs)
    n = rollout.batch_size[-1]
    assert 1 <= n <= steps
    obs = rollout["next", "observation"]
    assert obs.dtype == torch.float32 and torch.isfinite(obs).all()
    assert rollout["next", "reward"].shape == (*rollout.batch_size, 1)
    assert rollout["next", "done"].dtype == torch.bool
    for key, dtype in DEFAULT_INFO_KEYS.items():
        assert rollout["next", key].dtype == dtype, key
        assert rollout["next", key].shape == rollout.batch_size, key
    return rollout


@pytest.mark.parametrize(("env_id", "kwargs"), CASES)
def test_make_torchrl_env_specs_and_rollout(env_id: str, kwargs: dict[str, Any]) -> None:
    env = make_torchrl_env(env_id, **kwargs)
    gym_env = gym.make(env_id, **kwargs)
    assert env.batch_size == torch.Size([])
    assert tuple(env.observation_spec["observation"].shape) == gym_env.observation_space.shape
    if isinstance(gym_env.action_space, gym.spaces.Discrete):
        assert isinstance(env.action_spec, Categorical)
        assert env.action_spec.space.n == gym_env.action_space.n
    else:
        assert tuple(env.action_spec.shape) == gym_env.action_space.shape
    env.set_seed(0)
    check_env_specs(env, seed=0)
    rollout = check_rollout(env, STEPS)
    obs = rollout["next", "observation"].numpy()
    assert all(gym_env.observation_space.contains(o) for o in obs)
    env.close()
    gym_env.close()


def test_torchrl_rollout_equals_gymnasium() -> None:
    """The same seed and actions give the same observations and rewards as gymnasium."""
    env = make_torchrl_env("ActiveLoc/LandmarkEKF-v0", action_type="discrete")
    start = env.reset(seed=3)  # gymnasium's reset(seed=3)
    rollout = check_rollout(env, STEPS, tensordict=start, auto_reset=False)
    gym_env = gym.make("ActiveLoc/LandmarkEKF-v0", action_type="discrete")
    obs, _ = gym_env.reset(seed=3)
    np.testing.assert_array_equal(rollout["observation"][0].numpy(), obs)
    for t, action in enumerate(rollout["action"].numpy()):
        obs, reward, terminated, truncated, info = gym_env.step(int(action))
        np.testing.assert_array_equal(rollout["next", "observation"][t].numpy(), obs)
        assert rollout["next", "reward"][t, 0].item() == pytest.approx(reward, rel=1e-6)
        assert rollout["next", "terminated"][t, 0].item() == terminated
        assert rollout["next", "truncated"][t, 0].item() == truncated
        assert rollout["next", "is_success"][t].item() == info["is_success"]
        assert rollout["next", "pose_error"][t].item() == pytest.approx(info["pose_error"],
                                                                       rel=1e-6)


@pytest.mark.parametrize(("env_id", "kwargs"), CASES[1:])
def test_make_torchrl_env_native_vector(env_id: str, kwargs: dict[str, Any]) -> None:
    """num_envs wraps the native vector env (batch size [n], partial resets by mask)."""
    env = make_torchrl_env(env_id, num_envs=3, max_episode_steps=5, **kwargs)
    assert env.batch_size == torch.Size([3])
    env.set_seed(0)
    check_env_specs(env, seed=0)
    # 12 steps > the limit of 5: every sub-env ends and is reset along the way
    rollout = check_rollout(env, 12, break_when_any_done=False)
    assert rollout.batch_size == torch.Size([3, 12])
    assert rollout["next", "done"].any(dim=1).all()
    env.close()


def test_info_keys_options() -> None:
    env = make_torchrl_env("ActiveLoc/Textbook-v0", info_keys=("is_success",))
    td = env.reset()
    assert "is_success" in td.keys() and "pose_error" not in td.keys()
    env = make_torchrl_env("ActiveLoc/Textbook-v0", info_keys={"n_visible": torch.int64})
    check_env_specs(env, seed=0)
    env = make_torchrl_env("ActiveLoc/Textbook-v0", info_keys=())
    assert "is_success" not in env.reset().keys()
    with pytest.raises(ValueError, match="no default dtype"):
        make_torchrl_env("ActiveLoc/Textbook-v0", info_keys=("n_visible",))
    with pytest.raises(ValueError, match="ActiveLoc id"):
        make_torchrl_env("CartPole-v1")
    with pytest.raises(ValueError, match="num_envs"):
        make_torchrl_env("ActiveLoc/Textbook-v0", num_envs=0)


@pytest.mark.parametrize(("env_id", "kwargs"), CASES)
def test_gym_env_by_id(env_id: str, kwargs: dict[str, Any]) -> None:
    """``torchrl.envs.GymEnv(id)`` as is."""
    env = GymEnv(env_id, **kwargs)
    check_env_specs(env, seed=0)
    assert env.rollout(STEPS)["next", "observation"].dtype == torch.float32
