"""Belief entropy, one definition for every filter (nats).

The entropy of a pose belief is the differential entropy of its density over
``(x, y, theta)``. For a Gaussian it is the closed form ``0.5 log((2 pi e)^3 det Sigma)``;
histogram and particle beliefs use the entropy of the histogram on the pose grid plus
``log(cell volume)``, which makes the figures comparable across filters.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

#: log((2 pi e)^3), the dimension-dependent constant of the 3-D Gaussian entropy
LOG_2PIE_3 = 3.0 * np.log(2.0 * np.pi * np.e)


def gaussian_entropy(cov: ArrayLike) -> NDArray[np.float64]:
    """Entropy (nats) of 3-D Gaussians with covariances ``(..., 3, 3)``; shape ``(...)``.

    Raises:
        ValueError: if a covariance is not positive definite.
    """
    cov = np.asarray(cov, dtype=np.float64)
    try:
        root = np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        raise ValueError("gaussian_entropy: covariance is not positive definite") from None
    logdet = 2.0 * np.sum(np.log(np.diagonal(root, axis1=-2, axis2=-1)), axis=-1)
    return 0.5 * (LOG_2PIE_3 + logdet)


@numba.njit(cache=True, nogil=True)
def det3(a: NDArray) -> float:
    """Determinant of a ``(3, 3)`` matrix."""
    return (
        a[0, 0] * (a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1])
        - a[0, 1] * (a[1, 0] * a[2, 2] - a[1, 2] * a[2, 0])
        + a[0, 2] * (a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0])
    )


@numba.njit(cache=True, nogil=True)
def gaussian_entropy3(cov: NDArray) -> float:
    """Kernel twin of :func:`gaussian_entropy` for one ``(3, 3)`` covariance (nats)."""
    return 0.5 * (LOG_2PIE_3 + np.log(det3(cov)))
