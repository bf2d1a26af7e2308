"""EKF localization with unknown correspondences (the chapter's Algorithm 3).

The measurements of a scan come without landmark identities. Each measurement ``z_i`` is
matched to the landmark of maximum likelihood under the *predicted* belief N(mu_bar, Sigma_bar)
(eqs. 13.6-13.7): for every landmark k,

    z_hat_k = h(mu_bar, m_k),   H_k = dh/dx (mu_bar, m_k),   S_k = H_k Sigma_bar H_k^T + R
    d2_ik   = (z_i - z_hat_k)^T S_k^-1 (z_i - z_hat_k)            (bearing residual wrapped)
    j(i)    = argmax_k N(z_i; z_hat_k, S_k) = argmin_k d2_ik + log det S_k

A chi-square validation gate then marks ``z_i`` unmatched (index N, the chapter's one-based
"N + 1") when ``d2_i,j(i)`` exceeds the ``gate`` quantile of chi^2 with 2 degrees of freedom,
``-2 ln(1 - gate)``; unmatched measurements are left out of the update. ``gate = None`` (or 1)
disables the gate: every measurement is matched to some landmark, clutter included.

Each measurement is associated independently (two measurements may pick the same landmark),
all under the predicted belief, as in the chapter's approximation. The matched measurements
then enter one stacked EKF update linearized at the predicted mean
(:func:`active_loc.beliefs.ekf.ekf_update`, Joseph form), which is the chapter's loop of
per-measurement updates with every Jacobian taken at mu_bar.

Arrays are batch-first: means ``(B, 3)``, covariances ``(B, 3, 3)``, scans ``(B, M, 2)`` of
which the first ``n[b]`` rows are real, maps ``(B, L, 2)`` of which the first ``count[b]`` are.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from active_loc.beliefs.ekf import EKFBelief, ekf_update
from active_loc.geometry import wrap_angle_scalar
from active_loc.sensors.landmarks import RANGE_BEARING, LandmarkSensor, measurement_and_jacobian

#: default probability of the validation gate (chi-square with 2 dof)
DEFAULT_GATE = 0.99


def gate_threshold(gate: float | None) -> float:
    """The Mahalanobis (squared) threshold of a gate probability: ``-2 ln(1 - gate)``, the
    ``gate`` quantile of chi^2 with 2 dof; ``inf`` for ``None`` or 1 (no gate).

    Raises:
        ValueError: unless ``gate`` is None or in (0, 1].
    """
    if gate is None:
        return math.inf
    if isinstance(gate, bool) or not isinstance(gate, (int, float, np.integer, np.floating)):
        raise ValueError(f"association_gate must be None or a number in (0, 1], got {gate!r}")
    if not 0.0 < gate <= 1.0:
        raise ValueError(f"association_gate must be None or in (0, 1], got {gate}")
    if gate == 1.0:
        return math.inf
    return -2.0 * math.log1p(-float(gate))


@numba.njit(cache=True, nogil=True)
def associate(
    mu: NDArray,
    cov: NDArray,
    z: NDArray,
    n: int,
    landmarks: NDArray,
    count: int,
    kind: int,
    noise_cov: NDArray,
    threshold: float,
    index: NDArray,
    d2: NDArray,
) -> None:
    """Maximum-likelihood data association with a validation gate (eqs. 13.6-13.7).

    Args:
        mu: ``(3,)`` predicted mean; cov: ``(3, 3)`` predicted covariance.
        z: ``(M, 2)`` measurements, the first ``n`` real.
        landmarks: ``(L, 2)`` positions (m), the first ``count`` real.
        kind: sensor kind; noise_cov: ``(2, 2)`` R.
        threshold: the gate on d^2 (:func:`gate_threshold`); ``inf`` for none.
        index: ``(M,)`` int out: the landmark of each measurement, ``count`` if unmatched.
        d2: ``(M,)`` out: the Mahalanobis distance squared to the most likely landmark.
    """
    if n == 0:
        return
    # the predicted measurement and the Cholesky factor of S_k of every landmark, once
    pred = np.empty((count, 6))  # z_hat (2), l00, l10, l11, log det S
    r00, r11 = noise_cov[0, 0], noise_cov[1, 1]
    r01 = 0.5 * (noise_cov[0, 1] + noise_cov[1, 0])
    for k in range(count):
        zh0, zh1, h00, h01, h02, h10, h11, h12 = measurement_and_jacobian(
            kind, mu[0], mu[1], mu[2], landmarks[k, 0], landmarks[k, 1]
        )
        # H Sigma (2 x 3), then S = H Sigma H^T + R
        a0 = h00 * cov[0, 0] + h01 * cov[1, 0] + h02 * cov[2, 0]
        a1 = h00 * cov[0, 1] + h01 * cov[1, 1] + h02 * cov[2, 1]
        a2 = h00 * cov[0, 2] + h01 * cov[1, 2] + h02 * cov[2, 2]
        b0 = h10 * cov[0, 0] + h11 * cov[1, 0] + h12 * cov[2, 0]
        b1 = h10 * cov[0, 1] + h11 * cov[1, 1] + h12 * cov[2, 1]
        b2 = h10 * cov[0, 2] + h11 * cov[1, 2] + h12 * cov[2, 2]
        s00 = a0 * h00 + a1 * h01 + a2 * h02 + r00
        s01 = 0.5 * ((a0 * h10 + a1 * h11 + a2 * h12) + (b0 * h00 + b1 * h01 + b2 * h02)) + r01
        s11 = b0 * h10 + b1 * h11 + b2 * h12 + r11
        if not s00 > 0.0:
            raise ValueError("association: innovation covariance S is not positive definite")
        l00 = np.sqrt(s00)
        l10 = s01 / l00
        l11_sq = s11 - l10 * l10
        if not l11_sq > 0.0:
            raise ValueError("association: innovation covariance S is not positive definite")
        l11 = np.sqrt(l11_sq)
        pred[k, 0] = zh0
        pred[k, 1] = zh1
        pred[k, 2] = l00
        pred[k, 3] = l10
        pred[k, 4] = l11
        pred[k, 5] = 2.0 * np.log(l00 * l11)
    for i in range(n):
        best = count
        best_score = np.inf
        best_d2 = np.inf
        for k in range(count):
            nu0 = z[i, 0] - pred[k, 0]
            nu1 = z[i, 1] - pred[k, 1]
            if kind == RANGE_BEARING:
                nu1 = wrap_angle_scalar(nu1)
            w0 = nu0 / pred[k, 2]
            w1 = (nu1 - pred[k, 3] * w0) / pred[k, 4]
            dist = w0 * w0 + w1 * w1
            score = dist + pred[k, 5]  # -2 log N(z; z_hat, S) up to a constant
            if score < best_score:
                best_score = score
                best = k
                best_d2 = dist
        d2[i] = best_d2
        index[i] = best if best_d2 <= threshold else count


@numba.njit(cache=True, nogil=True)
def associate_and_update(
    mu: NDArray,
    cov: NDArray,
    z: NDArray,
    n: int,
    landmarks: NDArray,
    count: int,
    kind: int,
    noise_cov: NDArray,
    threshold: float,
    index: NDArray,
    d2: NDArray,
) -> float:
    """Algorithm 3's correction in place: :func:`associate` under the predicted belief
    ``mu`` ``(3,)``, ``cov`` ``(3, 3)``, then one stacked EKF update with the matched
    measurements (arguments as in :func:`associate`).

    Returns:
        The normalized innovation squared of the update (0 when nothing matched).
    """
    if n == 0:
        return 0.0  # nothing seen: the belief stays as predicted
    associate(mu, cov, z, n, landmarks, count, kind, noise_cov, threshold, index, d2)
    matched_landmarks = np.zeros((n, 2))
    matched = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        if index[i] < count:
            matched[i] = True
            matched_landmarks[i, 0] = landmarks[index[i], 0]
            matched_landmarks[i, 1] = landmarks[index[i], 1]
    # row i of the stacked update pairs measurement i with its landmark
    return ekf_update(mu, cov, z[:n], matched, matched_landmarks, kind, noise_cov)


@numba.njit(cache=True, nogil=True)
def associate_and_update_batch(
    mu: NDArray,
    cov: NDArray,
    z: NDArray,
    n: NDArray,
    landmarks: NDArray,
    count: NDArray,
    kind: int,
    noise_cov: NDArray,
    threshold: float,
    index: NDArray,
    d2: NDArray,
    nis: NDArray,
) -> None:
    """:func:`associate_and_update` over a batch: mu ``(B, 3)``, cov ``(B, 3, 3)``, z
    ``(B, M, 2)`` with ``n`` ``(B,)`` real rows, landmarks ``(B, L, 2)`` with ``count``
    ``(B,)`` real rows; index and d2 ``(B, M)`` out, nis ``(B,)`` out."""
    for b in range(mu.shape[0]):
        nis[b] = associate_and_update(
            mu[b], cov[b], z[b], n[b], landmarks[b], count[b], kind, noise_cov, threshold,
            index[b], d2[b],
        )


def associate_measurements(
    mean: ArrayLike,
    cov: ArrayLike,
    z: ArrayLike,
    landmarks: ArrayLike,
    sensor: LandmarkSensor,
    gate: float | None = DEFAULT_GATE,
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """ML association of the measurements ``z`` ``(n, 2)`` to ``landmarks`` ``(L, 2)`` under
    the predicted belief N(mean ``(3,)``, cov ``(3, 3)``), gated with probability ``gate``.

    Returns:
        The landmark index of each measurement ``(n,)`` (``L`` = unmatched) and its squared
        Mahalanobis distance to the most likely landmark ``(n,)``.
    """
    threshold = gate_threshold(gate)
    mean = np.ascontiguousarray(mean, dtype=np.float64).reshape(3)
    cov = np.ascontiguousarray(cov, dtype=np.float64).reshape(3, 3)
    z = np.ascontiguousarray(z, dtype=np.float64).reshape(-1, 2)
    landmarks = np.ascontiguousarray(landmarks, dtype=np.float64).reshape(-1, 2)
    index = np.empty(z.shape[0], dtype=np.int64)
    d2 = np.empty(z.shape[0])
    associate(mean, cov, z, z.shape[0], landmarks, landmarks.shape[0], sensor.kind,
              sensor.noise_cov, threshold, index, d2)
    return index, d2


def update_with_association(
    belief: EKFBelief,
    z: ArrayLike,
    landmarks: ArrayLike,
    gate: float | None = DEFAULT_GATE,
) -> NDArray[np.int64]:
    """Algorithm 3's correction of a predicted single belief (B = 1) in place with the
    unlabelled measurements ``z`` ``(n, 2)`` of map ``landmarks`` ``(L, 2)``.

    Sets ``belief.last_nis`` and returns the association ``(n,)`` (``L`` = unmatched).
    """
    if belief.batch_size != 1:
        raise ValueError(
            f"update_with_association: a single belief (B = 1) expected, got B = "
            f"{belief.batch_size}"
        )
    threshold = gate_threshold(gate)
    z = np.ascontiguousarray(z, dtype=np.float64).reshape(1, -1, 2)
    landmarks = np.ascontiguousarray(landmarks, dtype=np.float64).reshape(1, -1, 2)
    n = np.array([z.shape[1]], dtype=np.int64)
    count = np.array([landmarks.shape[1]], dtype=np.int64)
    index = np.empty((1, z.shape[1]), dtype=np.int64)
    d2 = np.empty((1, z.shape[1]))
    associate_and_update_batch(
        belief.mean, belief.cov, z, n, landmarks, count, belief.sensor.kind,
        belief.sensor.noise_cov, threshold, index, d2, belief.last_nis,
    )
    return index[0]
