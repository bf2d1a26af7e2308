"""Reward terms, each named so that ``info["reward_terms"]`` shows what the reward is made of.

The uncertainty term depends on ``reward=``:

* ``"info_gain"`` (default): ``H(b_{t-1}) - H(b_t)`` in nats. Summed over an episode it
  telescopes to ``H_0 - H_T``.
* ``"neg_entropy"``: ``-H(b_t)``, a per-step cost on the current uncertainty.
* ``"logdet"``: ``log det Sigma_{t-1} - log det Sigma_t`` (D-optimality gain; for a Gaussian
  twice the info gain), also telescoping.
* ``"trace"``: ``tr Sigma_{t-1} - tr Sigma_t`` (A-optimality gain, m^2 + rad^2), telescoping.

Then ``step_cost`` (``-step_cost`` every step) and ``collision`` (``-collision_penalty`` on a
blocked move).
"""

from __future__ import annotations

import numba

#: reward name -> code used by the kernels
REWARD_CODES = {"info_gain": 0, "neg_entropy": 1, "logdet": 2, "trace": 3}


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


def reward_terms(
    reward: str, uncertainty: float, collided: bool, step_cost: float, collision_penalty: float
) -> dict[str, float]:
    """The named terms of one step's reward; the reward is their sum."""
    return {
        reward: uncertainty,
        "step_cost": -step_cost,
        "collision": -collision_penalty if collided else 0.0,
    }
