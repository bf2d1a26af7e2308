"""The episode metrics of a belief against the truth, one definition for every simulator.

Confident (``localized``): the largest position standard deviation of the belief is at most
``localized_position_std`` and its heading standard deviation at most
``localized_heading_std``. Right (``success``): confident, within ``success_position_tol`` and
``success_heading_tol`` of the true pose, and no kidnapping unresolved. The episode may end
(``terminal``) when the belief is confident and no kidnapping is unresolved. A kidnapping is
unresolved from the reset until ``kidnap_grace`` steps after it: before it, localizing is not
yet the end of the task; on its step and just after, the belief is still confident about the
old pose, and the filter has not yet had the scans to react. The errors use the truth: they
are for evaluation and rewards, never for the agent's observation.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray


@numba.njit(cache=True, nogil=True)
def position_std(cov: NDArray) -> float:
    """Square root of the largest eigenvalue of the ``2 x 2`` position block of ``cov``
    ``(3, 3)`` (m), in closed form."""
    half_trace = 0.5 * (cov[0, 0] + cov[1, 1])
    gap = np.sqrt(max(0.25 * (cov[0, 0] - cov[1, 1]) ** 2 + cov[0, 1] ** 2, 0.0))
    return np.sqrt(max(half_trace + gap, 0.0))


@numba.njit(cache=True, nogil=True)
def belief_metrics(
    cov: NDArray,
    pos_err: float,
    head_err: float,
    kidnap_unresolved: bool,
    localized_position_std: float,
    localized_heading_std: float,
    success_position_tol: float,
    success_heading_tol: float,
) -> tuple[float, float, bool, bool, bool]:
    """``(pos_std, head_std, localized, success, terminal)`` of a belief with covariance
    ``cov`` ``(3, 3)`` whose mean is ``pos_err`` (m) and ``head_err`` (rad) from the truth
    (see the module docstring)."""
    pos_std = position_std(cov)
    head_std = np.sqrt(max(cov[2, 2], 0.0))
    localized = pos_std <= localized_position_std and head_std <= localized_heading_std
    success = (localized and not kidnap_unresolved and pos_err <= success_position_tol
               and head_err <= success_heading_tol)
    terminal = localized and not kidnap_unresolved
    return pos_std, head_std, localized, success, terminal
