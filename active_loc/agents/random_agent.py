"""Uniformly random actions: the baseline every other agent must beat."""

from __future__ import annotations

from typing import Any

import numpy as np

from active_loc.envs.planner_view import PlannerView


class RandomAgent:
    """Samples the action space with its own seeded Generator (never the global RNG)."""

    def __init__(self, seed: int | None = None) -> None:
        self.rng = np.random.default_rng(seed)

    def act(self, observation: Any, view: PlannerView) -> Any:
        space = view.action_space
        if hasattr(space, "n"):
            return int(self.rng.integers(space.n))
        return self.rng.uniform(space.low, space.high).astype(space.dtype)
