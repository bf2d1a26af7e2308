"""Multi-step lookahead: expected entropy a few steps ahead, minus the cost of travel.

Active Markov localization (Fox, Burgard and Thrun, "Active Markov localization for mobile
robots", Robotics and Autonomous Systems 25, 1998) chooses where to go by the expected entropy
after getting there plus the cost of the trip. Here that is a k-step lookahead:

* in ``Maze-v0``, an exact expectimax tree over all action sequences and depth readings;
* with continuous robots, sampled rollouts of macro-actions (one motion primitive held for k
  steps), scored by the mean over the rollouts of the summed entropies (plus the env's
  collision penalty on every step a rollout bumps into a wall).

A longer view is what keeps it out of the one-step agent's dithering (turn left, turn right,
...): a turn pair that gains nothing now is compared with sequences that reach something
informative later, and ties go to the previous action.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from active_loc.agents.planning import (
    candidate_actions,
    collision_penalty_of,
    entropy_of,
    planning_belief,
    travel_of,
)


class HorizonPlannerAgent:
    """Minimizes ``E[H(b_{t+1}) + ... + H(b_{t+k})] + travel_cost * distance`` (plus the
    collision penalty times the expected number of bumps) over k-step plans. Summing the
    entropies along the plan, not just the last one, makes information
    gained sooner worth more: with the final entropy alone, a step wasted now (a move into a
    wall) costs nothing whenever the rest of the plan can still gain the same, and the
    re-planned agent wastes the next step too.

    Args:
        horizon: k, the number of steps looked ahead (>= 1).
        travel_cost: nats per metre travelled (per cell moved in the maze); 0 ignores travel.
        n_rollouts: sampled scan sequences per macro-action (continuous robots).
        max_particles: particle beliefs are resampled down to this many for planning.
        seed: the agent's own Generator (hypotheses and ties).
    """

    def __init__(self, horizon: int = 3, travel_cost: float = 0.01, n_rollouts: int = 4,
                 max_particles: int = 300, seed: int | None = None) -> None:
        if horizon < 1 or n_rollouts < 1 or max_particles < 1 or not travel_cost >= 0:
            raise ValueError("HorizonPlannerAgent: horizon, n_rollouts and max_particles must "
                             "be >= 1 and travel_cost >= 0")
        self.horizon = int(horizon)
        self.travel_cost = float(travel_cost)
        self.n_rollouts = int(n_rollouts)
        self.max_particles = int(max_particles)
        self.rng = np.random.default_rng(seed)
        self._previous: Any = None

    # --- the maze: exact expectimax ------------------------------------------------------------

    def _maze_value(self, view: Any, belief: Any, depth: int) -> float:
        """Least expected sum of the next ``depth`` entropies plus travel."""
        if depth == 0:
            return 0.0
        if belief.max_prob()[0] >= 1.0 - 1e-12:
            return depth * entropy_of(belief)  # localized: nothing left to learn
        return min(self._maze_action_value(view, a, belief, depth) for a in range(3))

    def _maze_action_value(self, view: Any, action: int, belief: Any, depth: int) -> float:
        value = self.travel_cost * travel_of(view, action)
        for _, p, posterior in view.outcomes(action, belief):
            value += p * (entropy_of(posterior) + self._maze_value(view, posterior, depth - 1))
        return value

    # --- continuous robots: sampled macro-action rollouts ----------------------------------

    def _rollout_value(self, view: Any, action: Any, belief: Any, seed: int) -> float:
        rng = np.random.default_rng(seed)
        penalty = collision_penalty_of(view)
        total = 0.0
        for _ in range(self.n_rollouts):
            b = belief
            for _ in range(self.horizon):
                b, _, _, blocked = view.hypothesize(action, b, rng)
                total += entropy_of(b) + (penalty if blocked else 0.0)
        return total / self.n_rollouts + self.travel_cost * self.horizon * travel_of(view, action)

    def scores(self, view: Any) -> tuple[list[Any], np.ndarray]:
        """The candidate first actions and the value of the best plan starting with each."""
        actions = candidate_actions(view)
        belief = planning_belief(view.belief, self.max_particles, self.rng)
        if hasattr(view, "outcomes"):
            values = [self._maze_action_value(view, a, belief, self.horizon) for a in actions]
        else:
            seed = int(self.rng.integers(2**63))  # common random numbers across the plans
            values = [self._rollout_value(view, a, belief, seed) for a in actions]
        return actions, np.array(values)

    def _tie_break(self, best: np.ndarray) -> int:
        """Among equally good first actions: the previous one (keep going), else random."""
        if self._previous is not None and self._previous in best.tolist():
            return int(self._previous)
        return int(self.rng.choice(best))

    def act(self, observation: Any, view: Any) -> Any:
        if view.step == 0:
            self._previous = None  # a new episode
        actions, values = self.scores(view)
        best = np.flatnonzero(values <= values.min() + 1e-9)
        index = self._tie_break(best)
        self._previous = index
        return actions[index]
