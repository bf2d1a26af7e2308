"""What the planning agents share: candidate actions, belief entropy, cheaper particle copies.

Nothing here reads the true pose: every function works from a planner view (see
:mod:`active_loc.envs.planner_view` and :class:`active_loc.envs.maze_env.MazePlannerView`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from active_loc.beliefs.mcl import MCLBelief


def candidate_actions(view: Any) -> list[Any]:
    """The actions a planner compares: every action of a discrete space; for a continuous one
    the env's motion primitives (stay, forward, forward-left, forward-right, turn left, turn
    right) encoded as float32 actions."""
    space = view.action_space
    if isinstance(space, spaces.Discrete):
        return list(range(int(space.n)))
    limits = view.limits
    return [a.astype(space.dtype) for a in limits.encode(limits.primitives())]


def primitive_action(view: Any, index: int) -> Any:
    """The env action of motion primitive ``index`` (of ``actions.PRIMITIVES``): the index
    itself in a discrete space, the primitive's control encoded in a continuous one."""
    if isinstance(view.action_space, spaces.Discrete):
        return index
    control = view.limits.primitives()[index]
    return view.limits.encode(control).astype(view.action_space.dtype)


def control_of(view: Any, action: Any) -> np.ndarray:
    """(V m/s, omega rad/s) of an action, or ``None`` for views without controls (the maze)."""
    return view.decode(action) if hasattr(view, "decode") else None


def travel_of(view: Any, action: Any) -> float:
    """How far an action moves the robot if nothing blocks it: metres (V dt), or cells for the
    maze's move forward (action 2)."""
    if hasattr(view, "limits"):
        return abs(float(view.decode(action)[0])) * view.limits.dt
    return 1.0 if int(action) == 2 else 0.0


def entropy_of(belief: Any) -> float:
    """Entropy (nats) of a belief of batch size 1, whatever the filter."""
    return float(np.ravel(belief.entropy())[0])


def systematic_picks(weights: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
    """``count`` indices into ``weights`` ``(K,)`` (not necessarily normalized) drawn by
    systematic resampling with one uniform from ``rng``."""
    cumulative = np.cumsum(weights)
    positions = (rng.random() + np.arange(count)) / count * cumulative[-1]
    return np.minimum(np.searchsorted(cumulative, positions, side="right"),
                      cumulative.shape[0] - 1)


def planning_belief(belief: Any, max_particles: int, rng: np.random.Generator) -> Any:
    """A copy of ``belief`` to plan with: a particle belief with more than ``max_particles``
    particles is resampled down to that many (systematic, by weight, with ``rng``), without
    KLD sampling or injection, so that simulating many hypothetical steps stays affordable.
    Other beliefs are copied as they are."""
    if not isinstance(belief, MCLBelief) or belief.n_active <= max_particles:
        return belief.copy()
    picks = systematic_picks(belief.weights, max_particles, rng)
    out = MCLBelief(
        belief.free_space, belief.motion, max_particles, resampling=belief.resampling,
        resample_threshold=belief.resample_threshold,
        likelihood_exponent=belief.likelihood_exponent, entropy_bins=belief.entropy_bins,
    )
    out.set_particles(belief.particles[picks])
    return out


def collision_penalty_of(view: Any) -> float:
    """The env's collision penalty (nats) as the view reports it; 0 for views without one."""
    return float(getattr(view, "collision_penalty", 0.0))


def expected_cost_after(
    view: Any, action: Any, belief: Any, n_hypotheses: int, seed: int
) -> float:
    """``E[H(b')] + collision_penalty * P(blocked)`` after ``action``, one step ahead (nats).

    Minimizing it maximizes the env's expected reward, information gain minus the collision
    penalty (the step cost is the same for every action). Without the penalty term a planner
    on a grid map happily drives into walls: the scan repeated from where it stopped still
    lowers the entropy of a filter that takes its beams as independent.

    Exact for the maze (every possible depth reading, weighted by its probability; its
    reward has no collision term). Otherwise the mean over ``n_hypotheses`` simulated steps
    (a pose drawn from the belief, moved, its scan, the update), drawn from a Generator seeded
    with ``seed``, so that every action is scored on the same random numbers. For the EKF the
    posterior covariance does not depend on the measured values, only on which landmarks are
    in view, so the hypotheses only sample that.
    """
    if hasattr(view, "outcomes"):
        return sum(p * entropy_of(post) for _, p, post in view.outcomes(action, belief))
    penalty = collision_penalty_of(view)
    rng = np.random.default_rng(seed)
    total = 0.0
    for _ in range(n_hypotheses):
        after, _, _, blocked = view.hypothesize(action, belief, rng)
        total += entropy_of(after) + (penalty if blocked else 0.0)
    return total / n_hypotheses
