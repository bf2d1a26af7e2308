"""The one action check every env uses (``active_loc.envs.actions.check_action``)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch

import active_loc  # noqa: F401  (registers the ids)
from active_loc.envs.actions import check_action

BOX = gym.spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
DISCRETE = gym.spaces.Discrete(6)


def test_torch_tensors_and_lists_are_converted():
    np.testing.assert_array_equal(check_action(torch.tensor([0.5, -0.25]), BOX), [0.5, -0.25])
    np.testing.assert_array_equal(check_action([0.5, -0.25], BOX), [0.5, -0.25])
    assert check_action(torch.tensor(3), DISCRETE) == 3
    assert check_action(np.int64(2), DISCRETE) == 2


@pytest.mark.parametrize(
    ("action", "space", "match"),
    [
        (torch.tensor([0.5]), BOX, r"my_action must have shape \(2,\)"),
        (["a", "b"], BOX, "my_action must be real numbers"),
        ([np.nan, 0.0], BOX, "my_action contains NaN or inf"),
        (torch.tensor(1.5), DISCRETE, "my_action must be an integer index"),
        (True, DISCRETE, "my_action must be an integer index"),
        (6, DISCRETE, r"my_action must be an integer in \[0, 6\)"),
    ],
)
def test_bad_actions_are_refused_by_name(action, space, match):
    with pytest.raises(ValueError, match=match):
        check_action(action, space, "my_action")


@pytest.mark.parametrize("env_id", ["ActiveLoc/LandmarkEKF-v0", "ActiveLoc/GridMarkov-v0"])
def test_envs_step_with_torch_actions(env_id):
    env = gym.make(env_id)
    env.reset(seed=0)
    env.step(torch.tensor([0.2, 0.1]))
    vec = gym.make_vec(env_id, 2, vectorization_mode="vector_entry_point")
    vec.reset(seed=0)
    vec.step(torch.zeros((2, 2)))
    vec.close()
