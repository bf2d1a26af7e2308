"""``ActionRepeat``: one agent step is k env steps of the same action."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import active_loc  # noqa: F401  (registers the env ids)
from active_loc.envs.action_repeat import ActionRepeat

ID = "ActiveLoc/LandmarkEKF-v0"


def test_a_held_action_is_the_env_stepped_k_times_with_the_rewards_summed() -> None:
    held = ActionRepeat(gym.make(ID, action_type="discrete"), repeat=3)
    plain = gym.make(ID, action_type="discrete")
    obs_held, _ = held.reset(seed=4)
    obs_plain, _ = plain.reset(seed=4)
    np.testing.assert_array_equal(obs_held, obs_plain)
    steps = 0
    for action in (1, 4, 0, 2, 3, 1, 1, 4):
        obs_held, reward, terminated, truncated, info = held.step(action)
        total = 0.0
        for _ in range(3):
            obs_plain, r, term, trunc, plain_info = plain.step(action)
            total += float(r)
            steps += 1
            if term or trunc:
                break
        np.testing.assert_array_equal(obs_held, obs_plain)
        assert reward == pytest.approx(total, abs=1e-12)
        assert (terminated, truncated) == (term, trunc)
        assert info["entropy"] == plain_info["entropy"]
        if terminated or truncated:
            break
    assert held.unwrapped.planner_view().step == steps > 3


def test_an_episode_end_cuts_the_repeat_short() -> None:
    env = ActionRepeat(gym.make(ID, action_type="discrete", max_episode_steps=4,
                                terminate_when_localized=False), repeat=3)
    env.reset(seed=0)
    *_, truncated, _ = env.step(1)
    assert not truncated and env.unwrapped.planner_view().step == 3
    *_, truncated, _ = env.step(1)  # one step left of the episode's four
    assert truncated and env.unwrapped.planner_view().step == 4


@pytest.mark.parametrize("repeat", [0, -2, 1.5, True])
def test_a_bad_repeat_is_a_clear_error(repeat: object) -> None:
    with pytest.raises(ValueError, match="repeat must be an integer >= 1"):
        ActionRepeat(gym.make(ID), repeat=repeat)  # type: ignore[arg-type]
