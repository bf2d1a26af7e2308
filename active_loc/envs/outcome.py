"""What a step produced, by name, and the info dict every env builds from it.

The simulators keep a step's metrics in packed arrays for their kernels; :class:`StepOutcome`
is the one typed view of them that the env shells read (``core.outcome(b)``), and
:func:`step_info` the one builder of the info keys they share (the single env, the vector
env's per-sub-env dicts, the multi-robot env and the maze).
"""

from __future__ import annotations

from typing import Any, NamedTuple

from active_loc.envs.rewards import reward_terms, step_reward


class StepOutcome(NamedTuple):
    """One member's step, against the truth (metrics are for evaluation, never observed)."""

    pose_error: float  # m, belief mean to true pose
    heading_error: float  # rad
    entropy: float  # nats
    uncertainty: float  # the uncertainty reward term (the reward named by ``reward=``)
    collided: bool  # the move was blocked
    outcome: float  # the signed outcome term (``outcome_reward`` on a terminal step)
    localized: bool  # the belief is confident
    success: bool  # confident and right
    terminal: bool  # the episode's goal is reached (it ends with terminate_when_localized)
    kidnapped: bool  # the robot was kidnapped on this step
    n_visible: int  # landmarks in view
    nis: float  # normalized innovation squared of the EKF update (NaN without one)


class RewardSettings(NamedTuple):
    """The reward of a task: the uncertainty term's name and the fixed terms."""

    name: str
    step_cost: float
    collision_penalty: float
    has_outcome: bool = True  # the task has an outcome term (its key is in reward_terms)

    def total(self, outcome: StepOutcome) -> float:
        """The step's reward: :func:`~active_loc.envs.rewards.step_reward` of its terms."""
        return step_reward(outcome.uncertainty, outcome.collided, self.step_cost,
                           self.collision_penalty, outcome.outcome)


def step_info(outcome: StepOutcome, collisions: int, reward: RewardSettings) -> dict[str, Any]:
    """The info keys every env returns: ``pose_error``, ``heading_error``, ``entropy``,
    ``localized``, ``is_success``, ``collisions`` (this episode so far) and ``reward_terms``."""
    return {
        "pose_error": outcome.pose_error,
        "heading_error": outcome.heading_error,
        "entropy": outcome.entropy,
        "localized": outcome.localized,
        "is_success": outcome.success,
        "collisions": collisions,
        "reward_terms": reward_terms(
            reward.name, outcome.uncertainty, outcome.collided, reward.step_cost,
            reward.collision_penalty, outcome.outcome if reward.has_outcome else None,
        ),
    }
