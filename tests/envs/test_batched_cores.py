"""The particle and grid cores with B members: each member is the single env's episode.

A core of three members, fed the members' Generators and actions, must give the rows and
observations of three one-member cores fed the same, bit for bit, whether its members run in
turn or on worker threads; a member left out of a step (``active``) must not touch its
Generator, and its reset must make it a fresh episode.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import active_loc  # noqa: F401  (registers the ids)
from active_loc.envs.grid_core import GridCore
from active_loc.envs.particle_core import ParticleCore

CASES = [
    ("ActiveLoc/GridMarkov-v0", {}),
    ("ActiveLoc/GridMarkov-v0", {"map_pool": 2, "initial_belief": "gaussian"}),
    ("ActiveLoc/GridMarkov-v0", {"dynamic_obstacles": (2, 0.5, 0.2)}),
    ("ActiveLoc/GridMarkov-v0", {"lidar_model": "beam", "n_beams": 12}),
    ("ActiveLoc/GridMCLKidnapped-v0", {"n_particles": 2000, "min_particles": 200}),
    ("ActiveLoc/LandmarkMCL-v0", {"n_particles": 2000, "min_particles": 200}),
]


def cores(env_id: str, kwargs: dict[str, Any], n: int) -> tuple[Any, list[Any]]:
    template = gym.make(env_id, **kwargs).unwrapped
    core_type = type(template.core)
    assert core_type in (GridCore, ParticleCore)
    return (core_type(template.config, batch_size=n),
            [core_type(template.config) for _ in range(n)])


def assert_same(batch: Any, singles: list[Any]) -> None:
    for b, single in enumerate(singles):
        np.testing.assert_array_equal(batch.state[b], single.state[0])
        np.testing.assert_array_equal(batch.obs[b], single.obs[0])


@pytest.mark.parametrize("threads", [None, 2])
@pytest.mark.parametrize(("env_id", "kwargs"), CASES)
def test_a_core_of_three_members_equals_three_single_cores(env_id, kwargs, threads):
    n, steps, skipped = 3, 10, 1
    batch, singles = cores(env_id, kwargs, n)
    rngs = [np.random.default_rng(s) for s in (5, 6, 7)]
    twins = [np.random.default_rng(s) for s in (5, 6, 7)]
    for b in range(n):
        batch.reset_member(b, rngs[b])
        singles[b].reset_member(0, twins[b])
    assert_same(batch, singles)
    action_rng = np.random.default_rng(0)
    for t in range(steps):
        actions = action_rng.uniform(-1.0, 1.0, (n, 2))
        batch.actions[:] = actions
        active = np.ones(n, dtype=np.bool_)
        if t == steps // 2:
            active[skipped] = False  # as the vector env does for a member it resets next
        assert batch.step(rngs, active, threads=threads) == -1
        for b in np.flatnonzero(active):
            singles[b].actions[0] = actions[b]
            assert singles[b].step((twins[b],)) == -1
        if not active[skipped]:
            state = rngs[skipped].bit_generator.state
            assert state == twins[skipped].bit_generator.state
            batch.reset_members([skipped], [rngs[skipped]], threads=threads)
            singles[skipped].reset_member(0, twins[skipped])
        assert_same(batch, singles)


def test_a_non_finite_action_names_its_member_and_moves_no_one():
    batch, _ = cores("ActiveLoc/GridMarkov-v0", {}, 3)
    rngs = [np.random.default_rng(s) for s in range(3)]
    for b in range(3):
        batch.reset_member(b, rngs[b])
    before = batch.state.copy()
    batch.actions[:] = 0.5
    batch.actions[2, 1] = np.nan
    assert batch.step(rngs) == 2
    np.testing.assert_array_equal(batch.state, before)
