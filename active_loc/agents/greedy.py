"""One-step information gain: the action whose expected posterior entropy is lowest.

Active localization as Burgard, Fox and Thrun posed it ("Active mobile robot localization",
IJCAI 1997): score each action by the entropy the belief is expected to have after it (plus
the env's collision penalty, weighted by the chance that the move is blocked), and take the
best.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from active_loc.agents.planning import (
    candidate_actions,
    expected_cost_after,
    planning_belief,
)


class GreedyInfoGainAgent:
    """Picks ``argmin_a E[H(b' | a)] + c P(blocked | a)`` over the candidate actions, one step
    ahead, where c is the env's collision penalty (see
    :func:`~active_loc.agents.planning.expected_cost_after`, which scores particle and grid
    beliefs by what the scan removes, free of where histogram bin edges fall).

    The expectation is exact in ``Maze-v0`` (every depth reading enumerated) and for the EKF
    (the posterior covariance depends only on which landmarks are in view; ``n_hypotheses``
    poses sample that), and a sample mean over ``n_hypotheses`` simulated scans for particle
    and grid beliefs. Particle beliefs are first resampled down to ``max_particles``. Ties
    (within ``1e-9`` nats) are broken at random with the agent's own Generator.

    Being myopic it can dither: where no single action is informative every action ties, and
    it may turn left and right in turn. With a lidar on a grid map, one step (0.2 m or
    0.3 rad) changes little of a 270-degree scan, so every action mostly repeats it, and a
    repeated scan still sharpens the modes the belief already has (the sensor's noise is
    independent from scan to scan): staying or turning in place scores about as well as
    driving somewhere that would tell the modes apart.
    :class:`~active_loc.agents.horizon.HorizonPlannerAgent` looks further.

    With ``hold`` > 1 an action is a motion primitive held for ``hold`` steps (continuous
    robots; 5 steps of 0.2 s drive 1 m or turn 86 degrees), scored after the scan at its end,
    and once chosen it is held for that long: the one-step choice of Burgard, Fox and Thrun,
    whose actions were motions of any length, among longer motions.

    Args:
        n_hypotheses: simulated scans per action (particle and grid beliefs, the EKF).
        max_particles: particle beliefs are resampled down to this many for planning.
        hold: steps an action is held, and scored over (>= 1; continuous robots).
        seed: the agent's own Generator (resampling, hypotheses and ties).
    """

    def __init__(self, n_hypotheses: int = 4, max_particles: int = 500, hold: int = 1,
                 seed: int | None = None) -> None:
        if min(n_hypotheses, max_particles, hold) < 1:
            raise ValueError("GreedyInfoGainAgent: n_hypotheses, max_particles and hold must "
                             "be >= 1")
        self.n_hypotheses = int(n_hypotheses)
        self.max_particles = int(max_particles)
        self.hold = int(hold)
        self.rng = np.random.default_rng(seed)
        self._held: list[Any] = []  # the rest of the action being held

    def scores(self, view: Any) -> tuple[list[Any], np.ndarray]:
        """The candidate actions and their expected posterior entropies plus expected collision
        penalties (nats), each action held for :attr:`hold` steps (continuous robots)."""
        actions = candidate_actions(view)
        belief = planning_belief(view.belief, self.max_particles, self.rng)
        seed = int(self.rng.integers(2**63))  # common random numbers across the actions
        values = np.array([
            expected_cost_after(view, a, belief, self.n_hypotheses, seed, self.hold)
            for a in actions
        ])
        return actions, values

    def act(self, observation: Any, view: Any) -> Any:
        if view.step == 0:
            self._held = []  # a new episode
        if self._held:
            return self._held.pop()
        actions, values = self.scores(view)
        best = np.flatnonzero(values <= values.min() + 1e-9)
        action = actions[int(self.rng.choice(best))]
        if not hasattr(view, "outcomes"):
            self._held = [action] * (self.hold - 1)
        return action
