"""What a step produced, by name, and the info dict every env builds from it.

The simulators keep a step's metrics in packed arrays for their kernels; :class:`StepOutcome`
is the one typed view of them that the env shells read (``core.outcome(b)``), and
:func:`step_info` the one builder of the info keys they share (the single env, the vector
env's per-sub-env dicts, the multi-robot env and the maze).

The info rule, here once for every env (:func:`info_value` for an entry, :func:`typed_info`
for a whole dict; :func:`step_info` builds the shared keys by it):

* every scalar has one dtype on every step and for every id, so that a generic reader
  (TorchRL's ``default_info_dict_reader``, gymnasium's vector envs) sees what it can stack:
  reals are ``numpy.float64``, counts ``numpy.int64``, flags 0-d ``numpy.bool_`` arrays
  (:func:`info_dtype`). Flags are arrays rather than ``numpy.bool_`` scalars because
  ``numpy.bool_`` is no ``numpy.number``: gymnasium's ``SyncVectorEnv`` would stack it into
  an object array, whose ``mean()`` is a logical or, not a rate.
* the nested ``reward_terms`` dict is also given flat: ``reward_<term>`` next to it
  (``info["reward_info_gain"] == info["reward_terms"]["info_gain"]``), for readers that take
  only flat keys.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, NamedTuple, TypeVar

import numpy as np

from active_loc.envs.rewards import reward_terms, step_reward

#: the prefix of the flat reward-term keys: ``info["reward_" + term]``
REWARD_KEY_PREFIX = "reward_"

_T = TypeVar("_T")


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


def step_info(
    outcome: StepOutcome, collisions: int, reward: RewardSettings, **extra: Any
) -> dict[str, Any]:
    """The info keys every env returns: ``pose_error`` (m), ``heading_error`` (rad),
    ``entropy`` (nats), ``localized``, ``is_success``, ``collisions`` (this episode so far),
    ``reward_terms`` and its flat ``reward_<term>`` keys, then the env's own ``extra`` keys;
    all under the rule (what :func:`typed_info` gives, the fixed keys converted by their kind
    directly: this runs on every step)."""
    terms = {name: _real(value) for name, value in reward_terms(
        reward.name, outcome.uncertainty, outcome.collided, reward.step_cost,
        reward.collision_penalty, outcome.outcome if reward.has_outcome else None,
    ).items()}
    info = {
        "pose_error": _real(outcome.pose_error),
        "heading_error": _real(outcome.heading_error),
        "entropy": _real(outcome.entropy),
        "localized": _flag(outcome.localized),
        "is_success": _flag(outcome.success),
        "collisions": _count(collisions),
        "reward_terms": terms,
        **flat_reward_terms(terms),
    }
    for key, value in extra.items():
        info[key] = info_value(value)
    return info


def info_dtype(value: Any) -> np.dtype | None:
    """The dtype an info entry is kept in, scalar or array alike: float64 for reals, int64
    for counts, bool for flags; None for anything else (lists, strings, dicts)."""
    if isinstance(value, (np.ndarray, np.generic)):
        kind = value.dtype.kind
    elif isinstance(value, bool):  # before int: bool is an int
        kind = "b"
    elif isinstance(value, int):
        kind = "i"
    elif isinstance(value, float):
        kind = "f"
    else:
        return None
    return _DTYPES.get(kind)


#: numpy dtype kind -> the info dtype (signed and unsigned counts alike)
_DTYPES = {"b": np.dtype(np.bool_), "i": np.dtype(np.int64), "u": np.dtype(np.int64),
           "f": np.dtype(np.float64)}


def info_value(value: Any) -> Any:
    """One info entry under the rule: a float64 or int64 scalar, a new 0-d bool array (new:
    infos of different steps share no object), or ``value`` itself when it is no scalar (an
    array of more dimensions, a list, a string)."""
    convert = _CONVERT.get(type(value))  # the types the envs hand in, looked up at once
    if convert is not None:
        return convert(value)
    if isinstance(value, np.ndarray) and value.ndim > 0:
        return value
    dtype = info_dtype(value)
    if dtype is None:
        return value
    if dtype.kind == "b":
        return _flag(value)
    return dtype.type(value)


# -- the conversions of the rule, by kind (infos are built on every step: kept cheap) -----

_real = np.float64
_FALSE, _TRUE = np.array(False), np.array(True)  # copied, never handed out
#: np.int64 of the small counts, made once (numpy scalars are immutable, so infos may share
#: them; making one costs twice a float64)
_SMALL_INTS = tuple(np.int64(i) for i in range(1024))


def _flag(value: Any) -> np.ndarray:
    return (_TRUE if value else _FALSE).copy()


def _count(value: Any) -> np.int64:
    return _SMALL_INTS[value] if 0 <= value < 1024 else np.int64(value)


def _same(value: Any) -> Any:
    return value


#: type -> its conversion (no isinstance chain for the types the envs hand in)
_CONVERT: dict[type, Callable[[Any], Any]] = {
    float: _real, int: _count, bool: _flag, np.float64: _same, np.int64: _same,
    np.bool_: _flag, np.float32: _real, np.int32: _count,
}


def flat_reward_terms(terms: Mapping[str, _T]) -> dict[str, _T]:
    """``reward_terms`` as flat keys: ``{"reward_info_gain": terms["info_gain"], ...}``
    (scalars of one step, or the ``(n,)`` arrays of a vector env's batch)."""
    return {REWARD_KEY_PREFIX + name: value for name, value in terms.items()}


def typed_info(info: Mapping[str, Any]) -> dict[str, Any]:
    """``info`` under the rule of this module: every scalar (nested ones included) as
    :func:`info_value` has it, and the flat ``reward_<term>`` keys right after
    ``reward_terms``. Typing a typed info again changes nothing."""
    out: dict[str, Any] = {}
    for key, value in info.items():
        if isinstance(value, Mapping):
            out[key] = {k: info_value(v) for k, v in value.items()}
            if key == "reward_terms":
                out.update(flat_reward_terms(out[key]))
        elif key not in out:  # a flat reward key is made from reward_terms
            out[key] = info_value(value)
    return out
