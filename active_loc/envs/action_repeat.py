"""``ActionRepeat``: each action held for k env steps, as one step of the agent.

Frame skipping, as in Atari training: the agent decides every k steps, so a plan that pays off
only metres later (out of a room, down a corridor) is k times fewer decisions away.
"""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium as gym


class ActionRepeat(gym.Wrapper):
    """Each :meth:`step` applies the action ``repeat`` times, or until the episode ends.

    Returns the last observation, the sum of the rewards, the last ``terminated`` and
    ``truncated``, and the last step's info. Rewards that are differences (the information
    gain) sum to the change over the whole repeat.

    Args:
        env: the env to wrap.
        repeat: k >= 1, env steps per agent step (1 leaves the env as it is).
    """

    def __init__(self, env: gym.Env, repeat: int) -> None:
        if isinstance(repeat, bool) or not isinstance(repeat, int) or repeat < 1:
            raise ValueError(f"ActionRepeat: repeat must be an integer >= 1, got {repeat!r}")
        super().__init__(env)
        self.repeat = repeat

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        total = 0.0
        for _ in range(self.repeat):
            obs, reward, terminated, truncated, info = self.env.step(action)
            total += float(reward)
            if terminated or truncated:
                break
        return obs, total, terminated, truncated, info
