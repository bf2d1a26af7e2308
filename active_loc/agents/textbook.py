"""The passive controls of the chapter's exercise (section 13.8, problem 1)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from active_loc.envs.planner_view import PlannerView


class TextbookAgent:
    """V = 1 m/s and omega = sin(k dt) at step k = 1, 2, ... (the exercise's controls).

    Passive: it never looks at the belief. The step counter comes from the planner view, so
    one agent can serve many episodes. Actions are float64 so the controls are exact.
    """

    def __init__(self, speed: float = 1.0) -> None:
        self.speed = speed

    def act(self, observation: Any, view: PlannerView) -> NDArray[np.float64]:
        k = view.step + 1
        return view.limits.encode(np.array([self.speed, np.sin(k * view.limits.dt)]))
