"""The info rule (:mod:`active_loc.envs.outcome`): every scalar info entry has one numpy dtype
on every step and for every id, and the reward terms are also given as flat keys."""

from __future__ import annotations

import itertools
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.passive_env_checker import data_shares_objects

import active_loc  # noqa: F401
from active_loc.envs.multi_robot import parallel_env
from active_loc.envs.outcome import flat_reward_terms, info_dtype, info_value, typed_info

#: the ids checked, with cheap kwargs; an episode ends within the steps run
IDS = {
    "ActiveLoc/Textbook-v0": {},
    "ActiveLoc/LandmarkEKF-v0": {},
    "ActiveLoc/LandmarkMCL-v0": {"n_particles": 500},
    "ActiveLoc/GridMarkov-v0": {},
    "ActiveLoc/Maze-v0": {"size": 7},
}
LIMIT, STEPS = 5, 12
#: the keys every env shares (``step_info``), with their types
SHARED = {"pose_error": np.float64, "heading_error": np.float64, "entropy": np.float64,
          "localized": np.ndarray, "is_success": np.ndarray, "collisions": np.int64}
#: keys the maze adds itself (typed by its own info builder)
MAZE_OWN_KEYS = {"depth", "max_prob"}


def layout(info: dict[str, Any]) -> dict[str, tuple[type, np.dtype | None]]:
    """key -> (type, dtype) of an info dict (nested dicts by their entries)."""
    out: dict[str, tuple[type, np.dtype | None]] = {}
    for key, value in info.items():
        if isinstance(value, dict):
            out.update({f"{key}.{k}": (type(v), info_dtype(v)) for k, v in value.items()})
        else:
            out[key] = (type(value), info_dtype(value))
    return out


def infos_of(env_id: str) -> list[dict[str, Any]]:
    """The infos of a reset and ``STEPS`` random steps (reset again at an episode's end)."""
    env = gym.make(env_id, max_episode_steps=LIMIT, **IDS[env_id])
    env.action_space.seed(0)
    infos = [env.reset(seed=0)[1]]
    for _ in range(STEPS):
        *_, terminated, truncated, info = env.step(env.action_space.sample())
        infos.append(info)
        if terminated or truncated:
            infos.append(env.reset()[1])
    return infos


@pytest.mark.parametrize("env_id", IDS)
def test_every_scalar_has_one_numpy_dtype_on_every_step(env_id: str) -> None:
    infos = infos_of(env_id)
    first = layout(infos[0])
    for info in infos[1:]:
        assert layout(info) == first
    for previous, info in itertools.pairwise(infos):
        assert not data_shares_objects(previous, info)  # gymnasium's checker would warn
    for key, (kind, dtype) in first.items():
        if env_id == "ActiveLoc/Maze-v0" and key in MAZE_OWN_KEYS:
            continue
        assert kind in (np.float64, np.int64, np.ndarray, list), (key, kind)
        if kind is np.ndarray:  # flags: 0-d bool arrays
            assert dtype == np.bool_ and infos[0][key].shape == (), key
    for key, kind in SHARED.items():
        assert first[key][0] is kind, key


def test_the_shared_keys_have_the_same_dtypes_for_every_id() -> None:
    layouts = [layout(infos_of(env_id)[-1]) for env_id in IDS]
    for key in SHARED:
        assert len({entries[key] for entries in layouts}) == 1, key
    reals = {entries["reward_info_gain"] for entries in layouts}
    assert reals == {(np.float64, np.dtype(np.float64))}


@pytest.mark.parametrize("env_id", IDS)
def test_the_flat_reward_terms_are_the_nested_ones(env_id: str) -> None:
    for info in infos_of(env_id):
        terms = info["reward_terms"]
        assert {k for k in info if k.startswith("reward_") and k != "reward_terms"} == {
            f"reward_{term}" for term in terms}
        for term, value in terms.items():
            assert info[f"reward_{term}"] == value and type(value) is np.float64


def test_sync_vector_env_stacks_the_flags_as_bool_arrays() -> None:
    """A numpy bool scalar would be stacked into an object array, whose mean is a logical or."""
    envs = gym.make_vec("ActiveLoc/GridMarkov-v0", 3, vectorization_mode="sync")
    _, info = envs.reset(seed=0)
    for key in ("localized", "is_success", "kidnapped"):
        assert info[key].dtype == np.bool_, key
    assert info["collisions"].dtype == np.int64 and info["entropy"].dtype == np.float64
    assert info["reward_info_gain"].dtype == np.float64


def test_multi_robot_infos_follow_the_rule() -> None:
    env = parallel_env(n_robots=2)
    _, infos = env.reset(seed=0)
    steps = [infos]
    for _ in range(3):
        steps.append(env.step({a: env.action_space(a).sample() for a in env.agents})[4])
    for infos in steps:
        for info in infos.values():
            assert layout(info) == layout(steps[0]["robot_0"])
            assert isinstance(info["fused"], np.ndarray) and info["fused"].dtype == np.bool_
            assert type(info["n_visible"]) is np.int64 and isinstance(info["detected"], list)
            assert info["reward_info_gain"] == info["reward_terms"]["info_gain"]


def test_the_rule() -> None:
    assert [info_dtype(v) for v in (True, np.bool_(False), 3, np.int32(3), np.uint8(1), 1.5,
                                    np.float32(1.5), np.zeros(2), "a", [1])] == [
        np.bool_, np.bool_, np.int64, np.int64, np.int64, np.float64, np.float64, np.float64,
        None, None]
    assert type(info_value(np.float32(0.5))) is np.float64
    assert type(info_value(7)) is np.int64
    flag = info_value(True)
    assert isinstance(flag, np.ndarray) and flag.shape == () and flag.dtype == np.bool_ and flag
    assert info_value(np.array(False)).dtype == np.bool_
    assert info_value([1, 2]) == [1, 2]
    assert flat_reward_terms({"info_gain": 1.0, "collision": 0.0}) == {
        "reward_info_gain": 1.0, "reward_collision": 0.0}
    info = typed_info({"entropy": 1.0, "reward_terms": {"info_gain": 0.5}, "n_visible": 2})
    assert list(info) == ["entropy", "reward_terms", "reward_info_gain", "n_visible"]
    assert layout(typed_info(info)) == layout(info)  # idempotent
