"""``active_loc.integrations.sb3``: the native vector env behind stable-baselines3's ``VecEnv``.

The reference is SB3's own ``DummyVecEnv`` over ``gym.make`` envs seeded seed + i: the same
observations, rewards, dones and per-env infos, exactly. Then PPO and ``EvalCallback`` on it.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import EvalCallback
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor

from active_loc.integrations.sb3 import NativeVecEnv, make_native_vec_env

N_ENVS = 3
#: a short limit, so that every sub-env ends (and is reset) several times
LIMIT = 8
CASES = [
    ("ActiveLoc/LandmarkEKF-v0", {"action_type": "discrete"}),
    ("ActiveLoc/LandmarkEKF-v0", {"action_type": "continuous"}),
    ("ActiveLoc/Maze-v0", {}),
]
#: the per-env info keys compared (besides terminal_observation), all present on every step
INFO_KEYS = ("is_success", "pose_error", "entropy", "collisions", "reward_terms",
             "TimeLimit.truncated")
#: small networks: these tests check plumbing, not learning
TINY_POLICY = {"net_arch": [16]}


def random_actions(space: gym.Space, rng: np.random.Generator, n: int) -> np.ndarray:
    """A batch of actions as SB3 passes them: int (n,) for Discrete, float32 (n, 2) for Box."""
    if isinstance(space, gym.spaces.Discrete):
        return rng.integers(0, space.n, n)
    return rng.uniform(-1.0, 1.0, (n, *space.shape)).astype(np.float32)


def assert_value_equal(a: Any, b: Any, key: str) -> None:
    """Python scalars (or nested dicts of them) of the same type and value."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), key
        for k in a:
            assert_value_equal(a[k], b[k], f"{key}.{k}")
        return
    assert type(a) is type(b), (key, type(a), type(b))
    assert np.array_equal(a, b, equal_nan=True), (key, a, b)


@pytest.mark.parametrize(("env_id", "kwargs"), CASES)
def test_native_vec_env_equals_dummy_vec_env(env_id: str, kwargs: dict[str, Any]) -> None:
    native = NativeVecEnv(env_id, N_ENVS, {"max_episode_steps": LIMIT, **kwargs})
    dummy = DummyVecEnv(
        [lambda: gym.make(env_id, max_episode_steps=LIMIT, **kwargs) for _ in range(N_ENVS)]
    )
    assert native.observation_space == dummy.observation_space
    assert native.action_space == dummy.action_space
    native.seed(7)
    dummy.seed(7)
    obs_n, obs_d = native.reset(), dummy.reset()
    assert obs_n.dtype == obs_d.dtype and np.array_equal(obs_n, obs_d)
    rng = np.random.default_rng(7)
    episodes = np.zeros(N_ENVS, dtype=int)
    for _ in range(6 * LIMIT):
        actions = random_actions(dummy.action_space, rng, N_ENVS)
        obs_n, rew_n, done_n, infos_n = native.step(actions)
        obs_d, rew_d, done_d, infos_d = dummy.step(actions)
        for mine, theirs in ((obs_n, obs_d), (rew_n, rew_d), (done_n, done_d)):
            assert mine.dtype == theirs.dtype and np.array_equal(mine, theirs)
        for i, (info_n, info_d) in enumerate(zip(infos_n, infos_d, strict=True)):
            assert info_n.keys() == info_d.keys()
            for key in INFO_KEYS:
                assert_value_equal(info_n[key], info_d[key], key)
            if done_d[i]:
                assert np.array_equal(info_n["terminal_observation"],
                                      info_d["terminal_observation"])
                # the reset info of the new episode, as DummyVecEnv keeps it
                for key in INFO_KEYS[:-1]:
                    assert_value_equal(native.reset_infos[i][key], dummy.reset_infos[i][key], key)
        episodes += done_d
    assert episodes.min() >= 3, episodes  # every sub-env ended (and was reset) several times
    native.close()
    dummy.close()


def test_ppo_learns_on_the_native_vec_env() -> None:
    env = make_native_vec_env("ActiveLoc/LandmarkEKF-v0", 4, seed=0,
                              info_keywords=("is_success", "pose_error"))
    assert isinstance(env, VecMonitor) and isinstance(env.venv, NativeVecEnv)
    model = PPO("MlpPolicy", env, n_steps=32, batch_size=64, n_epochs=1, seed=0, device="cpu",
                policy_kwargs=TINY_POLICY)
    model.learn(256)
    assert model.num_timesteps >= 256
    episodes = list(model.ep_info_buffer)
    assert episodes and {"r", "l", "t", "is_success", "pose_error"} <= episodes[0].keys()
    env.close()


def test_eval_callback_records_success_without_a_monitor_warning(tmp_path: Path) -> None:
    train_env = make_native_vec_env("ActiveLoc/LandmarkEKF-v0", 2, seed=0,
                                    env_kwargs={"action_type": "discrete"})
    model = PPO("MlpPolicy", train_env, n_steps=32, batch_size=64, n_epochs=1, seed=0,
                device="cpu", policy_kwargs=TINY_POLICY)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        eval_env = make_native_vec_env("ActiveLoc/LandmarkEKF-v0", 2, seed=100,
                                       env_kwargs={"action_type": "discrete",
                                                   "max_episode_steps": 20})
        # with a log_path, EvalCallback keeps every evaluation's successes
        callback = EvalCallback(eval_env, eval_freq=32, n_eval_episodes=4, warn=True,
                                log_path=str(tmp_path))
        model.learn(128, callback=callback)
    messages = [str(w.message) for w in caught]
    assert not [m for m in messages if "Monitor" in m or "same type" in m], messages
    assert len(callback.evaluations_successes) == 2  # at 64 and 128 steps
    assert all(len(successes) == 4 for successes in callback.evaluations_successes)
    assert all(np.asarray(s).dtype == np.bool_ for s in callback.evaluations_successes[0])
    with np.load(tmp_path / "evaluations.npz") as data:
        assert data["successes"].shape == (2, 4)
    # without VecMonitor, SB3's check does warn (so the check above means something)
    bare = make_native_vec_env("ActiveLoc/LandmarkEKF-v0", 1, seed=0, monitor=False,
                               env_kwargs={"action_type": "discrete", "max_episode_steps": 5})
    assert bare.env_is_wrapped(Monitor) == [False]
    with pytest.warns(UserWarning, match="not wrapped with a ``Monitor``"):
        evaluate_policy(model, bare, n_eval_episodes=1)
    for env in (train_env, eval_env, bare):
        env.close()


def test_seed_and_options_are_used_once() -> None:
    env = NativeVecEnv("ActiveLoc/LandmarkEKF-v0", 2)
    env.seed(3)
    first = env.reset()
    single = gym.make("ActiveLoc/LandmarkEKF-v0")
    assert np.array_equal(first[1], single.reset(seed=4)[0])
    assert not np.array_equal(env.reset(), first)  # the seeds were cleared
    env.set_options([{"a": 1}, {"a": 2}])
    with pytest.raises(NotImplementedError, match="same options"):
        env.reset()
    env.close()


def test_attributes_methods_and_render() -> None:
    env = NativeVecEnv("ActiveLoc/Maze-v0", 3, {"render_mode": "rgb_array"})
    assert env.get_attr("render_mode") == ["rgb_array"] * 3
    assert env.get_attr("spec", indices=[1])[0].id == "ActiveLoc/Maze-v0"
    assert env.has_attr("render_mode") and not env.has_attr("action_masks")
    with pytest.raises(AttributeError, match="'walls'"):
        env.get_attr("walls")
    with pytest.raises(NotImplementedError, match="'render'"):
        env.env_method("render")
    with pytest.raises(NotImplementedError, match="'size'"):
        env.set_attr("size", 9)
    assert env.env_is_wrapped(Monitor, indices=[0, 2]) == [False, False]
    env.reset()
    frame = env.render()
    assert frame is not None and frame.dtype == np.uint8 and frame.ndim == 3
    assert np.array_equal(frame, env.vector_env.render())
    assert len(env.get_images()) == 1  # the vector env's frame, not one per sub-env
    env.close()


@pytest.mark.parametrize(
    ("env_id", "n_envs", "kwargs", "match"),
    [
        ("CartPole-v1", 2, {}, "must be an ActiveLoc id"),
        ("ActiveLoc/Nope-v0", 2, {}, "must be an ActiveLoc id"),
        ("ActiveLoc/LandmarkEKF-v0", 0, {}, "n_envs must be an integer >= 1"),
        ("ActiveLoc/LandmarkEKF-v0", 1.5, {}, "n_envs must be an integer >= 1"),
        ("ActiveLoc/LandmarkEKF-v0", 2, {"env_kwargs": {"autoreset_mode": "NextStep"}},
         "sets autoreset_mode itself"),
        ("ActiveLoc/LandmarkEKF-v0", 2, {"monitor": False, "info_keywords": ("is_success",)},
         "need monitor=True"),
    ],
)
def test_bad_input_is_a_clear_value_error(
    env_id: str, n_envs: Any, kwargs: dict[str, Any], match: str
) -> None:
    with pytest.raises(ValueError, match=match):
        make_native_vec_env(env_id, n_envs, **kwargs)


def test_subprocess_workers_make_the_ids_with_the_module_prefix() -> None:
    """SB3's ``SubprocVecEnv`` starts its workers by forkserver or spawn: they have not
    imported active_loc, so the id names its module ("active_loc:ActiveLoc/...")."""
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    env_id = "active_loc:ActiveLoc/LandmarkEKFDiscrete-v0"
    subproc = make_vec_env(env_id, n_envs=2, seed=3, vec_env_cls=SubprocVecEnv,
                           vec_env_kwargs={"start_method": "spawn"})
    local = make_vec_env(env_id, n_envs=2, seed=3, vec_env_cls=DummyVecEnv)
    try:
        np.testing.assert_array_equal(subproc.reset(), local.reset())
        for action in ([1, 2], [3, 0], [5, 4]):
            obs, rewards, dones, _ = subproc.step(np.array(action))
            expected, expected_rewards, expected_dones, _ = local.step(np.array(action))
            np.testing.assert_array_equal(obs, expected)
            # DummyVecEnv keeps rewards in float32, SubprocVecEnv in float64
            np.testing.assert_allclose(rewards, expected_rewards, rtol=1e-6)
            np.testing.assert_array_equal(dones, expected_dones)
    finally:
        subproc.close()
        local.close()
