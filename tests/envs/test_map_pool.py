"""``map_pool=N``: episodes draw one of N seeded maps, built once with their derived tables."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import active_loc  # noqa: F401  (registers the ids)

POOLED_IDS = ["ActiveLoc/LandmarkMCL-v0", "ActiveLoc/GridMCL-v0", "ActiveLoc/GridMarkov-v0",
              "ActiveLoc/LandmarkEKF-v0"]
SMALL = {"ActiveLoc/LandmarkMCL-v0": {"n_particles": 2000, "min_particles": 200},
         "ActiveLoc/GridMCL-v0": {"n_particles": 2000, "min_particles": 200},
         "ActiveLoc/GridMarkov-v0": {}, "ActiveLoc/LandmarkEKF-v0": {}}


def map_signature(env: gym.Env) -> bytes:
    lmap = env.unwrapped.core.maps[0]
    values = getattr(lmap, "values", None)
    return (values if values is not None else lmap.positions).tobytes()


@pytest.mark.parametrize("env_id", POOLED_IDS)
def test_episodes_draw_from_the_same_n_maps(env_id):
    """Two envs seeded differently see maps of one pool of 3, and only those."""
    seen = []
    for seed in (0, 1):
        env = gym.make(env_id, map_pool=3, **SMALL[env_id])
        env.reset(seed=seed)
        maps = {map_signature(env)}
        for _ in range(11):
            env.reset()
            maps.add(map_signature(env))
        seen.append(maps)
    assert len(seen[0]) <= 3 and len(seen[1]) <= 3
    assert len(seen[0] | seen[1]) <= 3
    assert len(seen[0]) >= 2  # 12 draws from 3 maps: all alike has probability 3^-11


def test_without_a_pool_every_episode_has_a_new_map():
    env = gym.make("ActiveLoc/GridMarkov-v0")
    env.reset(seed=0)
    maps = {map_signature(env)}
    for _ in range(5):
        env.reset()
        maps.add(map_signature(env))
    assert len(maps) == 6


def test_the_derived_tables_are_built_once_and_shared():
    """Two envs drawing the same pool map use one distance field and likelihood table."""
    a = gym.make("ActiveLoc/GridMCL-v0", map_pool=1, n_particles=1000, min_particles=100)
    b = gym.make("ActiveLoc/GridMCL-v0", map_pool=1, n_particles=1000, min_particles=100)
    a.reset(seed=0)
    b.reset(seed=5)
    ca, cb = a.unwrapped.core, b.unwrapped.core
    assert ca.maps[0] is cb.maps[0]
    da, db = ca.episode(0).data, cb.episode(0).data
    assert da is db and da.distance is db.distance and da.log_table is db.log_table


def test_grid_cores_keep_their_own_scratch():
    """The Markov filter's per-step likelihood buffer is the core's own, never the pool's."""
    a = gym.make("ActiveLoc/GridMarkov-v0", map_pool=1)
    b = gym.make("ActiveLoc/GridMarkov-v0", map_pool=1)
    a.reset(seed=0)
    b.reset(seed=1)
    ua, ub = a.unwrapped.core, b.unwrapped.core
    assert ua.episode(0).data.template is ub.episode(0).data.template
    assert ua._log_lik is not ub._log_lik


@pytest.mark.parametrize("env_id", ["ActiveLoc/GridMCL-v0", "ActiveLoc/LandmarkEKF-v0",
                                    "ActiveLoc/GridMarkov-v0"])
def test_vector_env_with_a_pool_equals_single_envs(env_id):
    n, steps = 3, 25
    kwargs = {"map_pool": 2, **SMALL[env_id]}
    envs = gym.make_vec(env_id, n, vectorization_mode="vector_entry_point", **kwargs)
    singles = [gym.make(env_id, **kwargs) for _ in range(n)]
    obs, _ = envs.reset(seed=10)
    for i, env in enumerate(singles):
        o, _ = env.reset(seed=10 + i)
        np.testing.assert_array_equal(obs[i], o)
    rng = np.random.default_rng(0)
    ended = [False] * n
    for _ in range(steps):
        actions = rng.uniform(-1, 1, (n, 2)).astype(np.float32)
        obs, rewards, term, trunc, _ = envs.step(actions)
        for i, env in enumerate(singles):
            if ended[i]:  # NEXT_STEP autoreset: this step reset sub-env i
                o, _ = env.reset()
                ended[i] = False
            else:
                o, r, te, tr, _ = env.step(actions[i])
                assert (rewards[i], term[i], trunc[i]) == (r, te, tr)
                ended[i] = te or tr
            np.testing.assert_array_equal(obs[i], o)
    envs.close()


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"map_pool": 0}, "map_pool"),
        ({"map_pool": 2.5}, "map_pool"),
        ({"map_pool": True}, "map_pool"),
        ({"map_pool": "4"}, "map_pool"),
        ({"map_pool": 10**9}, "map_pool"),
        ({"map_pool": 3, "map": "textbook"}, "map_pool"),
    ],
)
def test_bad_pools_are_refused_by_name(kwargs, needle):
    with pytest.raises(ValueError, match=needle):
        gym.make("ActiveLoc/LandmarkEKF-v0", **kwargs)
