"""Reward terms, each named so that ``info["reward_terms"]`` shows what the reward is made of.

The uncertainty term depends on ``reward=``:

* ``"info_gain"`` (default): ``H(b_{t-1}) - H(b_t)`` in nats. Summed over an episode it
  telescopes to ``H_0 - H_T``.
* ``"neg_entropy"``: ``-H(b_t)``, a per-step cost on the current uncertainty.
* ``"logdet"``: ``log det Sigma_{t-1} - log det Sigma_t`` (D-optimality gain; for a Gaussian
  twice the info gain), also telescoping.
* ``"trace"``: ``tr Sigma_{t-1} - tr Sigma_t`` (A-optimality gain, m^2 + rad^2), telescoping.

Then ``step_cost`` (``-step_cost`` every step) and ``collision`` (``-collision_penalty`` on a
blocked move). The envs of :class:`~active_loc.envs.config.LocalizationConfig` add ``outcome``:
on the step an episode terminates because the belief is confident, ``+outcome_reward`` if it is
right (``is_success``) and ``-outcome_reward`` if it is confidently wrong (a false
convergence); 0 on every other step. The uncertainty terms pay as much for a confident wrong
belief as for a right one; this term is what tells them apart. It is computed from the truth,
as rewards may be: the agent never sees it, only the reward.
"""

from __future__ import annotations

import numba

#: reward name -> code used by the kernels
REWARD_CODES = {"info_gain": 0, "neg_entropy": 1, "logdet": 2, "trace": 3}


@numba.njit(cache=True, nogil=True)
def outcome_term(terminal: bool, success: bool, outcome_reward: float) -> float:
    """The ``outcome`` term of one step: ``+-outcome_reward`` on a terminal step (right or
    confidently wrong), else 0."""
    if not terminal:
        return 0.0
    return outcome_reward if success else -outcome_reward


@numba.njit(cache=True, nogil=True)
def uncertainty_reward(
    code: int,
    prev_entropy: float,
    entropy: float,
    prev_logdet: float,
    logdet: float,
    prev_trace: float,
    trace: float,
) -> float:
    """The uncertainty term of one step for reward ``code`` (see :data:`REWARD_CODES`)."""
    if code == 0:
        return prev_entropy - entropy
    if code == 1:
        return -entropy
    if code == 2:
        return prev_logdet - logdet
    return prev_trace - trace


@numba.njit(cache=True, nogil=True)
def step_reward(
    uncertainty: float, collided: bool, step_cost: float, collision_penalty: float,
    outcome: float,
) -> float:
    """The reward of one step: the sum of the terms :func:`reward_terms` names (every env, and
    the kernels of the vector envs, total them here)."""
    return uncertainty - step_cost - (collision_penalty if collided else 0.0) + outcome


def reward_terms(
    reward: str, uncertainty: float, collided: bool, step_cost: float, collision_penalty: float,
    outcome: float | None = None,
) -> dict[str, float]:
    """The named terms of one step's reward; the reward is their sum. ``outcome`` (the
    signed outcome term) is a key only where the env has one (None: it has not)."""
    terms = {
        reward: uncertainty,
        "step_cost": -step_cost,
        "collision": -collision_penalty if collided else 0.0,
    }
    if outcome is not None:
        terms["outcome"] = outcome
    return terms
