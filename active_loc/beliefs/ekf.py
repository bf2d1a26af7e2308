"""EKF localization with known correspondences (the chapter's Algorithm 2).

The belief is a Gaussian N(mu, Sigma) over the pose. Prediction pushes the mean through the
unicycle model and the covariance through its Jacobian F (``Sigma = F Sigma F^T + Q``).
Correction stacks the measurements of every landmark visible this step into one update:

    S = H Sigma H^T + R_blk,   K = Sigma H^T S^-1   (a Cholesky solve, never an inverse)
    mu += K nu                 (nu with wrapped bearings; heading wrapped after)
    Sigma = (I - K H) Sigma (I - K H)^T + K R_blk K^T        (Joseph form, then symmetrized)

Landmarks that are not visible do not enter H, so they change nothing. The kernels below work on
one belief; the ``*_batch`` kernels loop over a leading batch axis B, and :class:`EKFBelief`
holds ``(B, 3)`` means and ``(B, 3, 3)`` covariances.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from active_loc.beliefs.entropy import gaussian_entropy
from active_loc.geometry import wrap_angle_scalar
from active_loc.motion import UnicycleModel, unicycle_mean
from active_loc.sensors.landmarks import RANGE_BEARING, LandmarkSensor, measurement_and_jacobian


@numba.njit(cache=True, nogil=True)
def ekf_predict(
    mu: NDArray, cov: NDArray, v: float, omega: float, dt: float, noise_cov: NDArray
) -> None:
    """Prediction in place: ``mu = f(mu, u)``, ``Sigma = F Sigma F^T + Q``.

    Args:
        mu: ``(3,)`` mean; cov: ``(3, 3)`` covariance; noise_cov: ``(3, 3)`` Q.
        v, omega: control (m/s, rad/s); dt: time step (s).
    """
    # F = I + e_02 f0 + e_12 f1 (unicycle_jacobian), so F Sigma F^T in closed form
    f0 = -v * np.sin(mu[2]) * dt
    f1 = v * np.cos(mu[2]) * dt
    unicycle_mean(mu, v, omega, dt, mu)
    c02, c12, c22 = cov[0, 2], cov[1, 2], cov[2, 2]
    # rows of F Sigma
    r00 = cov[0, 0] + f0 * c02
    r01 = cov[0, 1] + f0 * c12
    r11 = cov[1, 1] + f1 * c12
    r10 = cov[1, 0] + f1 * c02
    p02 = c02 + f0 * c22
    p12 = c12 + f1 * c22
    p00 = r00 + p02 * f0
    p11 = r11 + p12 * f1
    p01 = 0.5 * ((r01 + p02 * f1) + (r10 + p12 * f0))
    cov[0, 0] = p00 + noise_cov[0, 0]
    cov[1, 1] = p11 + noise_cov[1, 1]
    cov[2, 2] = c22 + noise_cov[2, 2]
    cov[0, 1] = p01 + 0.5 * (noise_cov[0, 1] + noise_cov[1, 0])
    cov[1, 0] = cov[0, 1]
    cov[0, 2] = p02 + 0.5 * (noise_cov[0, 2] + noise_cov[2, 0])
    cov[2, 0] = cov[0, 2]
    cov[1, 2] = p12 + 0.5 * (noise_cov[1, 2] + noise_cov[2, 1])
    cov[2, 1] = cov[1, 2]


@numba.njit(cache=True, nogil=True)
def ekf_update(
    mu: NDArray,
    cov: NDArray,
    z: NDArray,
    visible: NDArray,
    landmarks: NDArray,
    kind: int,
    noise_cov: NDArray,
) -> float:
    """Stacked correction in place with every visible landmark.

    Every Jacobian H_j and prediction h(mu_bar, m_j) is taken at the predicted mean mu_bar, as
    in one update with the stacked z, H and block-diagonal R. Because R is block diagonal, that
    stacked update factors exactly into one 2-D update per landmark (block elimination of S),
    provided each later innovation is shifted by the mean change so far,
    ``nu_j = z_j - h(mu_bar, m_j) - H_j (mu - mu_bar)``. This computes the stacked result
    (equal to filterpy's stacked update to rounding) with 2 x 2 solves only and no
    ``2m x 2m`` matrix.

    Args:
        mu: ``(3,)`` mean; cov: ``(3, 3)`` covariance; both updated in place.
        z: ``(N, 2)`` measurements; visible: ``(N,)`` mask; landmarks: ``(N, 2)`` (m).
        kind: sensor kind (``RELATIVE_POSITION`` or ``RANGE_BEARING``).
        noise_cov: ``(2, 2)`` R of one landmark measurement, positive definite.

    Returns:
        The normalized innovation squared of the stacked update, ``nu^T S^-1 nu`` (the sum of
        the per-block terms); 0 when nothing is visible.
    """
    if not np.any(visible):
        return 0.0  # nothing seen: the belief stays bit-identical
    # scratch rows: 0-1 H_j (2, 3); 2-3 K_j^T (2, 3); 4-6 A = I - K H; 7-9 A Sigma
    work = np.empty((10, 3))
    jac = work[0:2]
    gain_t = work[2:4]
    a_mat = work[4:7]
    a_cov = work[7:10]
    bar0, bar1, bar2 = mu[0], mu[1], mu[2]
    r00, r01, r11 = noise_cov[0, 0], 0.5 * (noise_cov[0, 1] + noise_cov[1, 0]), noise_cov[1, 1]
    nis = 0.0
    for j in range(landmarks.shape[0]):
        if not visible[j]:
            continue
        # linearize at the predicted mean (not the partially updated one): stacked semantics
        zhat0, zhat1, jac[0, 0], jac[0, 1], jac[0, 2], jac[1, 0], jac[1, 1], jac[1, 2] = (
            measurement_and_jacobian(kind, bar0, bar1, bar2, landmarks[j, 0], landmarks[j, 1])
        )
        d0, d1, d2 = mu[0] - bar0, mu[1] - bar1, wrap_angle_scalar(mu[2] - bar2)
        nu0 = z[j, 0] - zhat0
        nu1 = z[j, 1] - zhat1
        if kind == RANGE_BEARING:
            nu1 = wrap_angle_scalar(nu1)
        nu0 -= jac[0, 0] * d0 + jac[0, 1] * d1 + jac[0, 2] * d2
        nu1 -= jac[1, 0] * d0 + jac[1, 1] * d1 + jac[1, 2] * d2
        # H Sigma (2, 3) into gain_t, then S = H Sigma H^T + R (2 x 2)
        for r in range(2):
            for c in range(3):
                gain_t[r, c] = (
                    jac[r, 0] * cov[0, c] + jac[r, 1] * cov[1, c] + jac[r, 2] * cov[2, c]
                )
        s00 = gain_t[0, 0] * jac[0, 0] + gain_t[0, 1] * jac[0, 1] + gain_t[0, 2] * jac[0, 2] + r00
        s10 = gain_t[1, 0] * jac[0, 0] + gain_t[1, 1] * jac[0, 1] + gain_t[1, 2] * jac[0, 2] + r01
        s11 = gain_t[1, 0] * jac[1, 0] + gain_t[1, 1] * jac[1, 1] + gain_t[1, 2] * jac[1, 2] + r11
        # Cholesky S = L L^T, then K^T = S^-1 (H Sigma) and S^-1 nu by two triangular solves
        if not s00 > 0.0:
            raise ValueError("EKF innovation covariance S is not positive definite")
        l00 = np.sqrt(s00)
        l10 = s10 / l00
        l11_sq = s11 - l10 * l10
        if not l11_sq > 0.0:
            raise ValueError("EKF innovation covariance S is not positive definite")
        l11 = np.sqrt(l11_sq)
        for c in range(3):
            y0 = gain_t[0, c] / l00
            y1 = (gain_t[1, c] - l10 * y0) / l11
            gain_t[1, c] = y1 / l11
            gain_t[0, c] = (y0 - l10 * gain_t[1, c]) / l00
        w0 = nu0 / l00
        w1 = (nu1 - l10 * w0) / l11
        nis += w0 * w0 + w1 * w1
        for c in range(3):
            mu[c] += gain_t[0, c] * nu0 + gain_t[1, c] * nu1
        # Joseph form: A = I - K H; Sigma = A Sigma A^T + K R K^T, symmetrized
        for r in range(3):
            for c in range(3):
                a_mat[r, c] = (1.0 if r == c else 0.0) - (
                    gain_t[0, r] * jac[0, c] + gain_t[1, r] * jac[1, c]
                )
        for r in range(3):
            for c in range(3):
                a_cov[r, c] = (
                    a_mat[r, 0] * cov[0, c] + a_mat[r, 1] * cov[1, c] + a_mat[r, 2] * cov[2, c]
                )
        for r in range(3):
            kr0 = gain_t[0, r] * r00 + gain_t[1, r] * r01
            kr1 = gain_t[0, r] * r01 + gain_t[1, r] * r11
            for c in range(r + 1):
                val = a_cov[r, 0] * a_mat[c, 0] + a_cov[r, 1] * a_mat[c, 1]
                val += a_cov[r, 2] * a_mat[c, 2] + kr0 * gain_t[0, c] + kr1 * gain_t[1, c]
                cov[r, c] = val
                cov[c, r] = val
    mu[2] = wrap_angle_scalar(mu[2])
    return nis


@numba.njit(cache=True, nogil=True)
def ekf_predict_batch(
    mu: NDArray, cov: NDArray, controls: NDArray, dt: float, noise_cov: NDArray
) -> None:
    """:func:`ekf_predict` over ``(B, 3)`` means, ``(B, 3, 3)`` covariances, ``(B, 2)`` controls."""
    for b in range(mu.shape[0]):
        ekf_predict(mu[b], cov[b], controls[b, 0], controls[b, 1], dt, noise_cov)


@numba.njit(cache=True, nogil=True)
def ekf_update_batch(
    mu: NDArray,
    cov: NDArray,
    z: NDArray,
    visible: NDArray,
    landmarks: NDArray,
    kind: int,
    noise_cov: NDArray,
    nis: NDArray,
) -> None:
    """:func:`ekf_update` over a batch: z ``(B, N, 2)``, visible ``(B, N)``, landmarks
    ``(B, N, 2)``; the NIS of each member goes into ``nis`` ``(B,)``."""
    for b in range(mu.shape[0]):
        nis[b] = ekf_update(mu[b], cov[b], z[b], visible[b], landmarks[b], kind, noise_cov)


class EKFBelief:
    """A batch of Gaussian pose beliefs updated with the numba EKF kernels.

    Args:
        mean: ``(B, 3)`` initial means (m, m, rad).
        cov: ``(B, 3, 3)`` initial covariances, positive definite.
        motion: the motion model (dt and Q).
        sensor: the landmark sensor (kind and R).
    """

    def __init__(
        self,
        mean: ArrayLike,
        cov: ArrayLike,
        motion: UnicycleModel,
        sensor: LandmarkSensor,
    ) -> None:
        self.mean = np.array(mean, dtype=np.float64).reshape(-1, 3)
        self.cov = np.array(cov, dtype=np.float64).reshape(-1, 3, 3)
        if self.cov.shape[0] != self.mean.shape[0]:
            raise ValueError(
                f"EKFBelief: mean has batch {self.mean.shape[0]} but cov has {self.cov.shape[0]}"
            )
        if not (np.all(np.isfinite(self.mean)) and np.all(np.isfinite(self.cov))):
            raise ValueError("EKFBelief: mean and cov must be finite")
        if np.any(np.linalg.eigvalsh(self.cov) <= 0):
            raise ValueError("EKFBelief: cov must be positive definite")
        self.motion = motion
        self.sensor = sensor
        self.last_nis = np.zeros(self.mean.shape[0])

    @classmethod
    def wrap(
        cls, mean: NDArray, cov: NDArray, motion: UnicycleModel, sensor: LandmarkSensor
    ) -> EKFBelief:
        """A belief that works in place on the given ``(B, 3)`` and ``(B, 3, 3)`` arrays
        (views into a larger state, say), without copying or validating them."""
        out = cls.__new__(cls)
        out.mean = mean
        out.cov = cov
        out.motion = motion
        out.sensor = sensor
        out.last_nis = np.zeros(mean.shape[0])
        return out

    @property
    def batch_size(self) -> int:
        return int(self.mean.shape[0])

    def predict(self, controls: ArrayLike) -> None:
        """Motion update with controls ``(B, 2)`` = (V m/s, omega rad/s)."""
        controls = np.ascontiguousarray(controls, dtype=np.float64).reshape(self.batch_size, 2)
        ekf_predict_batch(self.mean, self.cov, controls, self.motion.dt, self.motion.noise_cov)

    def update(self, z: ArrayLike, visible: ArrayLike, landmarks: ArrayLike) -> None:
        """Measurement update with z ``(B, N, 2)``, visible ``(B, N)`` and landmarks
        ``(N, 2)`` (shared) or ``(B, N, 2)``."""
        z = np.ascontiguousarray(z, dtype=np.float64).reshape(self.batch_size, -1, 2)
        visible = np.ascontiguousarray(visible, dtype=np.bool_).reshape(z.shape[:2])
        landmarks = np.asarray(landmarks, dtype=np.float64)
        landmarks = np.ascontiguousarray(np.broadcast_to(landmarks, z.shape))
        ekf_update_batch(
            self.mean, self.cov, z, visible, landmarks, self.sensor.kind,
            self.sensor.noise_cov, self.last_nis,
        )

    def entropy(self) -> NDArray[np.float64]:
        """Differential entropy of each Gaussian (nats), ``(B,)``."""
        return gaussian_entropy(self.cov)

    def copy(self) -> EKFBelief:
        """An independent belief with copies of the arrays."""
        out = EKFBelief.wrap(self.mean.copy(), self.cov.copy(), self.motion, self.sensor)
        out.last_nis = self.last_nis.copy()
        return out
