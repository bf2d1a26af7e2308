"""What the planning agents share: candidate actions, belief entropy, cheaper particle copies.

Nothing here reads the true pose: every function works from a planner view (see
:mod:`active_loc.envs.planner_view` and :class:`active_loc.envs.maze_env.MazePlannerView`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from active_loc.beliefs.grid import GridBelief
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


def has_histogram_entropy(belief: Any) -> bool:
    """Whether ``belief``'s entropy is counted in bins of the pose space: MCL particles in
    histogram bins, a grid belief in its cells (an EKF's is the Gaussian's closed form)."""
    return isinstance(belief, (MCLBelief, GridBelief))


def expected_cost_after(
    view: Any, action: Any, belief: Any, n_hypotheses: int, seed: int, hold: int = 1
) -> float:
    """The one-step score of ``action`` (nats, lower is better): the entropy expected after
    it, plus ``collision_penalty * P(blocked)``. With ``hold`` > 1 (not in the maze) the
    action is held for ``hold`` steps and scored after the scan at the end; the penalty counts
    every blocked step.

    Without the penalty term a planner on a grid map happily drives into walls: the scan
    repeated from where it stopped still lowers the entropy of a filter that takes its beams
    as independent.

    Exact for the maze (every possible depth reading, weighted by its probability; its
    reward has no collision term). Otherwise the mean over ``n_hypotheses`` simulated steps
    (a pose drawn from the belief, moved, its scan, the update), drawn from a Generator seeded
    with ``seed``, so that every action is scored on the same random numbers. For the EKF the
    posterior covariance does not depend on the measured values, only on which landmarks are
    in view, so the hypotheses only sample that. For these two the score is ``E[H(b')]``, and
    minimizing it maximizes the env's expected reward (information gain minus the collision
    penalty; the step cost is the same for every action).

    MCL and grid beliefs score ``H(b) - E[H(b-) - H(b')]``, where ``b-`` is the belief
    predicted with the action under the same hypothesis: the entropy the scan is expected to
    remove, in the bins of the belief it corrects. Their entropy is a histogram's, and it
    depends on where the bin edges cut a sharp belief: a cloud of a few degrees moved across
    a 10-degree heading edge gains up to log 2 nats with nothing learned or lost (on the
    symmetric arena a 0.3 rad turn predicted 0.4 nats more than staying, before any scan).
    Scored as ``E[H(b')]``, those shifts decided the choice. The move itself changes the
    exact entropy by the same amount for every action (the unicycle step keeps volumes and
    the noise is additive), except where poses are pushed into walls. The env's reward keeps
    the shifts, step by step; over an episode they cancel (the information gains sum to the
    first entropy minus the last).
    """
    if hasattr(view, "outcomes"):
        return sum(p * entropy_of(post) for _, p, post in view.outcomes(action, belief))
    penalty = collision_penalty_of(view)
    start = entropy_of(belief)
    rng = np.random.default_rng(seed)
    total = 0.0
    for _ in range(n_hypotheses):
        after, pose, blocked = view.predict_hypothesis(action, belief, rng, steps=hold)
        total += entropy_after_scan(view, after, pose, rng, start)
        total += penalty * blocked
    return total / n_hypotheses


def entropy_after_scan(view: Any, predicted: Any, pose: NDArray[np.float64],
                       rng: np.random.Generator, entropy_before: float) -> float:
    """Correct ``predicted`` (in place) with the scan simulated from ``pose`` ``(3,)`` and
    return the entropy (nats) a planner counts after it: the belief's own for an EKF; for
    particle and grid beliefs ``entropy_before`` (what the planner counted before the move)
    minus the entropy the scan removed in ``predicted``'s bins (see
    :func:`expected_cost_after`)."""
    if not has_histogram_entropy(predicted):
        view.correct(predicted, pose, rng)
        return entropy_of(predicted)
    before_scan = entropy_of(predicted)
    view.correct(predicted, pose, rng)
    return entropy_before - (before_scan - entropy_of(predicted))
