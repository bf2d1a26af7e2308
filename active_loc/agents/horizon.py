"""Multi-step lookahead: expected entropy a few steps ahead, minus the cost of travel.

Active Markov localization (Fox, Burgard and Thrun, "Active Markov localization for mobile
robots", Robotics and Autonomous Systems 25, 1998) chooses where to go by the expected entropy
after getting there plus the cost of the trip. Here that is a k-step lookahead:

* in ``Maze-v0``, an exact expectimax tree over all action sequences and depth readings;
* with continuous robots, a tree of macro-actions (one motion primitive held for ``hold``
  steps), ``horizon`` macro-actions deep, scored by sampled rollouts. Each rollout follows a
  pose drawn from the belief (the same poses for every plan) through the plan: that robot
  moves (a wall blocks it), the belief is predicted with its controls, and at the end of each
  macro-action the belief is corrected with the scan simulated from where that robot stands.

A plan's cost is the sum of the entropies along it, plus the travel cost per metre and the
env's collision penalty per bump. For particle and grid beliefs the entropy after each
macro-action is counted as the one-step agent counts it: the entropy before, minus what that
macro-action's scan removes in the bins of the belief it corrects
(:func:`~active_loc.agents.planning.entropy_after_scan`), so that where histogram bin edges
cut a sharp belief does not rank the plans.

Summing the entropies, not just taking the last one, makes information gained sooner worth
more: with the final entropy alone, a step wasted now (a move into a wall) costs nothing
whenever the rest of the plan can still gain the same.

The macro-actions are what let it see far enough. Five steps of 0.2 s per macro-action and
three of them look 3 m ahead, which is what it takes to get out of a room and look down a
corridor; three single steps look 0.6 m ahead, and from there every action looks alike. The
longer view also keeps it out of the one-step agent's dithering (turn left, turn right, ...):
a turn pair that gains nothing now is compared with plans that reach something informative
later, and ties go to the previous action.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from active_loc.agents.maze_search import distinguishing_plan
from active_loc.agents.planning import (
    candidate_actions,
    collision_penalty_of,
    entropy_after_scan,
    entropy_of,
    planning_belief,
    primitive_action,
    travel_of,
)
from active_loc.envs.actions import PRIMITIVE_NAMES
from active_loc.envs.maze_core import MOVE_FORWARD, TURN_LEFT

#: the motion primitives a macro-action holds: all but "stay", which spends a whole
#: macro-action rescanning one view (and a lidar filter that takes its beams as independent
#: would count those repeats as new information)
MACRO_PRIMITIVES = tuple(i for i, name in enumerate(PRIMITIVE_NAMES) if name != "stay")


class HorizonPlannerAgent:
    """Minimizes the expected ``H(b_{t+1}) + ... + H(b_{t+k})`` plus the travel cost and the
    collision penalty over k-step plans (see the module docstring).

    In ``Maze-v0`` a plan is ``horizon`` actions, scored exactly and re-planned every step.
    With continuous robots it is ``horizon`` macro-actions of ``hold`` steps each; the entropy
    after each macro-action counts for each of its steps, and the agent holds the best plan's
    first macro-action for ``hold`` steps before it plans again.

    Args:
        horizon: k, the actions (maze) or macro-actions looked ahead (>= 1).
        hold: steps a macro-action holds its motion primitive (>= 1; continuous robots).
        travel_cost: nats per metre travelled (per cell moved in the maze); 0 ignores travel.
        n_rollouts: poses drawn from the belief to roll each plan out from (continuous robots).
        max_particles: particle beliefs are resampled down to this many for planning.
        seed: the agent's own Generator (rollouts and ties).
    """

    def __init__(self, horizon: int = 3, hold: int = 5, travel_cost: float = 0.01,
                 n_rollouts: int = 3, max_particles: int = 200,
                 seed: int | None = None) -> None:
        if min(horizon, hold, n_rollouts, max_particles) < 1 or not travel_cost >= 0:
            raise ValueError("HorizonPlannerAgent: horizon, hold, n_rollouts and max_particles "
                             "must be >= 1 and travel_cost >= 0")
        self.horizon = int(horizon)
        self.hold = int(hold)
        self.travel_cost = float(travel_cost)
        self.n_rollouts = int(n_rollouts)
        self.max_particles = int(max_particles)
        self.rng = np.random.default_rng(seed)
        self._previous: int | None = None  # index of the last choice among the candidates
        self._held: list[Any] = []  # the rest of the macro-action being held

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

    # --- continuous robots: rollouts of macro-action plans ---------------------------------

    def _plan_costs(self, view: Any, belief: Any, entropy: float, pose: NDArray[np.float64],
                    depth: int, seed: list[int]) -> NDArray[np.float64]:
        """The cost (nats) of every plan ``depth`` macro-actions long from ``belief`` (whose
        entropy counts as ``entropy``), rolled out from the hypothetical robot at ``pose``
        ``(3,)``: ``(len(MACRO_PRIMITIVES) ** depth,)``, the plans in lexicographic order.
        Siblings draw the same noise (``seed`` and the depth seed it), so that plans are
        compared on common random numbers."""
        if depth == 0:
            return np.zeros(1)
        penalty = collision_penalty_of(view)
        costs = []
        for primitive in MACRO_PRIMITIVES:
            rng = np.random.default_rng([*seed, depth])
            action = primitive_action(view, primitive)
            control = view.decode(action)
            travel = self.travel_cost * travel_of(view, action)  # of one unblocked step
            moved = belief.copy()
            at, blocked_steps = view.drive(moved, pose, control, self.hold, rng)
            cost = 0.0
            for blocked in blocked_steps:
                cost += penalty if blocked else travel
            after = entropy_after_scan(view, moved, at, rng, entropy)
            cost += self.hold * after
            costs.append(cost + self._plan_costs(view, moved, after, at, depth - 1, seed))
        return np.concatenate(costs)

    def _macro_scores(self, view: Any) -> NDArray[np.float64]:
        """For each first macro-action, the expected cost of the best plan starting with it:
        the plans' costs averaged over the rollouts, then the least per first macro-action."""
        belief = planning_belief(view.belief, self.max_particles, self.rng)
        seed = int(self.rng.integers(2**63))  # common random numbers across the plans
        start = entropy_of(belief)
        total = np.zeros(len(MACRO_PRIMITIVES) ** self.horizon)
        for rollout in range(self.n_rollouts):
            pose = view.draw_pose(belief, np.random.default_rng([seed, rollout]))
            total += self._plan_costs(view, belief, start, pose, self.horizon, [seed, rollout])
        return (total / self.n_rollouts).reshape(len(MACRO_PRIMITIVES), -1).min(axis=1)

    # --- choosing --------------------------------------------------------------------------

    def scores(self, view: Any) -> tuple[list[Any], NDArray[np.float64]]:
        """The candidate first actions (maze actions, or the macro-actions' primitives as env
        actions) and the expected cost of the best plan starting with each."""
        if hasattr(view, "outcomes"):
            belief = view.belief.copy()
            actions = candidate_actions(view)
            values = [self._maze_action_value(view, a, belief, self.horizon) for a in actions]
            return actions, np.array(values)
        actions = [primitive_action(view, p) for p in MACRO_PRIMITIVES]
        return actions, self._macro_scores(view)

    def _uninformative(self, view: Any, actions: list[Any], values: NDArray[np.float64]) -> bool:
        """Whether the maze belief is ambiguous and no plan within the horizon lowers its
        entropy: every first action then costs ``horizon`` times the entropy now plus its own
        travel (the cheapest continuation, turning in place, travels nothing)."""
        if view.belief.max_prob()[0] >= 1.0 - 1e-12:
            return False
        flat = self.horizon * entropy_of(view.belief)
        return all(value >= flat + self.travel_cost * travel_of(view, action) - 1e-9
                   for action, value in zip(actions, values, strict=True))

    def _search_maze(self, view: Any) -> int:
        """The first action of the shortest sequence that tells the hypotheses apart
        (:func:`~active_loc.agents.maze_search.distinguishing_plan`); where none is left,
        forward, where it is open under the likeliest hypothesis, so that the robot does not
        turn in place."""
        plan = distinguishing_plan(view, view.episode_length - view.step)
        if plan is not None:
            action = plan[0]
        else:
            x, y, h = np.unravel_index(int(np.argmax(view.belief.prob[0])),
                                       view.belief.prob.shape[1:])
            blocked = view.motion.move(view.belief.free[0], (x, y, h), MOVE_FORWARD)[1]
            action = TURN_LEFT if blocked else MOVE_FORWARD
        self._previous = action
        return action

    def _tie_break(self, best: NDArray[np.int64]) -> int:
        """Among equally good first actions: the previous one (keep going), else random."""
        if self._previous is not None and self._previous in best.tolist():
            return int(self._previous)
        return int(self.rng.choice(best))

    def act(self, observation: Any, view: Any) -> Any:
        if view.step == 0:
            self._previous, self._held = None, []  # a new episode
        if self._held:
            return self._held.pop()
        actions, values = self.scores(view)
        if hasattr(view, "outcomes") and self._uninformative(view, actions, values):
            return self._search_maze(view)
        best = np.flatnonzero(values <= values.min() + 1e-9)
        index = self._tie_break(best)
        self._previous = index
        if not hasattr(view, "outcomes"):
            self._held = [actions[index]] * (self.hold - 1)
        return actions[index]
