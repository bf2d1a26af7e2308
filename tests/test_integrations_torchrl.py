"""``active_loc.integrations.torchrl``: the ids as TorchRL envs pass ``check_env_specs`` and roll
out, single and as the native vector env (through ``make_torchrl_env`` and through TorchRL's
own ``GymWrapper`` in each autoreset mode it takes), and TorchRL's generic info reader reads
their info. Skipped when TorchRL is not installed."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("torchrl")

import torch
from gymnasium.vector import AutoresetMode
from torchrl.data import Categorical, Unbounded
from torchrl.envs import GymEnv, GymWrapper
from torchrl.envs.libs.gym import default_info_dict_reader
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


# -- GymWrapper over the native vector env, in each autoreset mode --------------------------

#: rollout length and episode limit: every sub-env ends (and is reset) within a rollout
ROLLOUT, LIMIT = 9, 4
VECTOR_IDS = ["ActiveLoc/LandmarkEKF-v0", "ActiveLoc/GridMarkov-v0", "ActiveLoc/Maze-v0"]
#: info keys a generic reader is asked for (a flat reward term among them), with their dtypes
READ_KEYS = {"is_success": torch.bool, "entropy": torch.float64, "pose_error": torch.float64,
             "reward_info_gain": torch.float64, "collisions": torch.int64}
#: every flat reward term of the localization ids (their rewards are the sums)
REWARD_KEYS = ("reward_info_gain", "reward_step_cost", "reward_collision", "reward_outcome")


def assert_reward_is_the_flat_terms(rollout: Any) -> None:
    """The reward is the sum of the flat terms read (TorchRL fills a key it does not find
    with zeros: this tells a read term from a missing one)."""
    nxt = rollout["next"]
    total = sum(nxt[key] for key in REWARD_KEYS)
    torch.testing.assert_close(nxt["reward"][..., 0], total.float(), rtol=1e-6, atol=1e-6)
    assert (nxt["reward_info_gain"] != 0).any() and (nxt["entropy"] != 0).all()


def native_vector_env(env_id: str, mode: AutoresetMode, n: int = 3) -> gym.vector.VectorEnv:
    kwargs = {} if env_id == "ActiveLoc/Maze-v0" else {"action_type": "discrete"}
    return gym.make_vec(env_id, n, vectorization_mode="vector_entry_point",
                        autoreset_mode=mode, max_episode_steps=LIMIT, **kwargs)


def single_envs(env_id: str, n: int = 3) -> list[gym.Env]:
    kwargs = {} if env_id == "ActiveLoc/Maze-v0" else {"action_type": "discrete"}
    return [gym.make(env_id, max_episode_steps=LIMIT, **kwargs) for _ in range(n)]


def seeded_rollout(env: Any, seed: int) -> Any:
    """``ROLLOUT`` random steps from gymnasium's ``reset(seed=seed)``, through episode ends."""
    start = env.reset(seed=seed)
    torch.manual_seed(seed)
    return env.rollout(ROLLOUT, tensordict=start, auto_reset=False, break_when_any_done=False)


def assert_step_is_single(rollout: Any, b: int, t: int, step: tuple) -> None:
    """Step t of sub-env b in the rollout is the single env's ``step``: observation, reward,
    flags and the info keys the rollout read."""
    obs, reward, terminated, truncated, info = step
    nxt = rollout["next"]
    np.testing.assert_array_equal(nxt["observation"][b, t].numpy(), obs)
    assert nxt["reward"][b, t, 0].item() == pytest.approx(reward, rel=1e-6)
    assert (nxt["terminated"][b, t, 0].item(), nxt["truncated"][b, t, 0].item()) == (
        terminated, truncated)
    for key in READ_KEYS:
        if key in nxt.keys():
            assert nxt[key][b, t].item() == info[key].item(), (key, b, t)


@pytest.mark.parametrize("env_id", VECTOR_IDS)
def test_gym_wrapper_over_the_native_vector_env_with_disabled_autoreset(env_id: str) -> None:
    """DISABLED: TorchRL resets ended sub-envs by ``reset_mask``; every step of every episode
    is the single env's (sub-env i seeded seed + i, reset unseeded after an end)."""
    env = GymWrapper(native_vector_env(env_id, AutoresetMode.DISABLED),
                     categorical_action_encoding=True)
    env.set_info_dict_reader(default_info_dict_reader())  # every info key, dtypes read off
    check_env_specs(env, seed=0)
    rollout = seeded_rollout(env, 3)
    assert rollout.batch_size == torch.Size([3, ROLLOUT])
    assert rollout["next", "done"].sum() >= 3 * 2  # each sub-env ended twice
    for b, single in enumerate(single_envs(env_id)):
        obs, _ = single.reset(seed=3 + b)
        np.testing.assert_array_equal(rollout["observation"][b, 0].numpy(), obs)
        for t in range(ROLLOUT):
            step = single.step(rollout["action"][b, t].numpy())
            assert_step_is_single(rollout, b, t, step)
            if step[2] or step[3]:
                obs, _ = single.reset()
                if t + 1 < ROLLOUT:
                    np.testing.assert_array_equal(rollout["observation"][b, t + 1].numpy(), obs)
    env.close()


@pytest.mark.parametrize("env_id", VECTOR_IDS)
def test_gym_wrapper_over_the_native_vector_env_with_same_step_autoreset(env_id: str) -> None:
    """SAME_STEP: TorchRL reads every info key itself (a nested dict would stop it) and takes
    the ended step's observation and info from ``final_obs`` and ``final_info``: the first
    episode is the single env's, an end's "next" is the last step, not the reset, and the
    following step starts from a reset."""
    env = GymWrapper(native_vector_env(env_id, AutoresetMode.SAME_STEP),
                     categorical_action_encoding=True)
    check_env_specs(env, seed=0)
    rollout = seeded_rollout(env, 3)
    nxt = rollout["next"]
    for key, dtype in READ_KEYS.items():
        assert nxt[key].dtype == dtype, key
    done = nxt["done"][..., 0]
    assert done[:, LIMIT - 1].all() and done.sum() >= 3 * 2
    for b, single in enumerate(single_envs(env_id)):
        obs, _ = single.reset(seed=3 + b)
        np.testing.assert_array_equal(rollout["observation"][b, 0].numpy(), obs)
        for t in range(LIMIT):  # the first episode, its last step included
            assert_step_is_single(rollout, b, t, single.step(rollout["action"][b, t].numpy()))
    for t in range(ROLLOUT - 1):
        going = ~done[:, t]  # a going sub-env's next observation is where the step starts
        assert torch.equal(nxt["observation"][going, t], rollout["observation"][going, t + 1])
        if done[:, t].any():  # an ended one starts a new episode: no collision yet
            assert (rollout["collisions"][done[:, t], t + 1] == 0).all()
    env.close()


def test_gym_wrapper_refuses_next_step_autoreset() -> None:
    """TorchRL itself takes only SAME_STEP and DISABLED (make_torchrl_env uses DISABLED)."""
    with pytest.raises(RuntimeError, match="auto-reset mode must be one of SAME_STEP"):
        GymWrapper(native_vector_env("ActiveLoc/LandmarkEKF-v0", AutoresetMode.NEXT_STEP))


# -- a generic info reader -------------------------------------------------------------------

SINGLE_IDS = ["ActiveLoc/Textbook-v0", "ActiveLoc/LandmarkEKF-v0", "ActiveLoc/LandmarkMCL-v0",
              "ActiveLoc/GridMarkov-v0"]


@pytest.mark.parametrize("env_id", SINGLE_IDS)
def test_default_info_dict_reader_reads_a_single_env(env_id: str) -> None:
    """TorchRL's default reader, given the keys only, reads the info scalars (their
    ``.dtype``) and a flat reward term; given the dtypes as specs, the specs check out."""
    kwargs = {"n_particles": 500} if "MCL" in env_id else {}
    env = GymEnv(env_id, **kwargs)
    env.set_info_dict_reader(default_info_dict_reader([*READ_KEYS, *REWARD_KEYS]))
    rollout = env.rollout(6)
    for key, dtype in READ_KEYS.items():
        assert rollout["next", key].dtype == dtype, key
        assert rollout["next", key].shape == rollout.batch_size, key
    assert_reward_is_the_flat_terms(rollout)
    typed = GymEnv(env_id, **kwargs)
    specs = {key: Unbounded((), dtype=dtype) for key, dtype in READ_KEYS.items()}
    typed.set_info_dict_reader(default_info_dict_reader(list(READ_KEYS), spec=specs))
    check_env_specs(typed, seed=0)


def test_default_info_dict_reader_reads_the_native_vector_env() -> None:
    """The same keys off the batched info of n sub-envs (specs of the batch shape: TorchRL's
    keys-only specs are unbatched)."""
    env = GymWrapper(native_vector_env("ActiveLoc/LandmarkEKF-v0", AutoresetMode.DISABLED),
                     categorical_action_encoding=True)
    dtypes = {**READ_KEYS, **dict.fromkeys(REWARD_KEYS, torch.float64)}
    specs = {key: Unbounded((3,), dtype=dtype) for key, dtype in dtypes.items()}
    env.set_info_dict_reader(default_info_dict_reader(list(dtypes), spec=specs))
    check_env_specs(env, seed=0)
    rollout = env.rollout(2 * LIMIT, break_when_any_done=False)
    for key, dtype in dtypes.items():
        assert rollout["next", key].dtype == dtype, key
        assert rollout["next", key].shape == (3, 2 * LIMIT), key
    assert_reward_is_the_flat_terms(rollout)
