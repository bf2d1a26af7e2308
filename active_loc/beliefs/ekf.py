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
from active_loc.motion import UnicycleModel, unicycle_jacobian, unicycle_mean
from active_loc.sensors.landmarks import RANGE_BEARING, LandmarkSensor, expected_measurement


@numba.njit(cache=True)
def _symmetrize3(a: NDArray) -> None:
    for i in range(3):
        for j in range(i + 1, 3):
            m = 0.5 * (a[i, j] + a[j, i])
            a[i, j] = m
            a[j, i] = m


@numba.njit(cache=True)
def ekf_predict(
    mu: NDArray, cov: NDArray, v: float, omega: float, dt: float, noise_cov: NDArray
) -> None:
    """Prediction in place: ``mu = f(mu, u)``, ``Sigma = F Sigma F^T + Q``.

    Args:
        mu: ``(3,)`` mean; cov: ``(3, 3)`` covariance; noise_cov: ``(3, 3)`` Q.
        v, omega: control (m/s, rad/s); dt: time step (s).
    """
    jac = np.empty((3, 3))
    unicycle_jacobian(mu[2], v, dt, jac)
    unicycle_mean(mu, v, omega, dt, mu)
    tmp = np.zeros((3, 3))
    for i in range(3):
        for k in range(3):
            for j in range(3):
                tmp[i, j] += jac[i, k] * cov[k, j]
    for i in range(3):
        for j in range(3):
            acc = noise_cov[i, j]
            for k in range(3):
                acc += tmp[i, k] * jac[j, k]
            cov[i, j] = acc
    _symmetrize3(cov)


@numba.njit(cache=True)
def _cholesky(a: NDArray) -> NDArray:
    """Lower Cholesky factor of a symmetric positive definite matrix ``(d, d)``."""
    d = a.shape[0]
    low = np.zeros((d, d))
    for j in range(d):
        acc = a[j, j]
        for k in range(j):
            acc -= low[j, k] * low[j, k]
        if not acc > 0.0:
            raise ValueError("EKF innovation covariance S is not positive definite")
        low[j, j] = np.sqrt(acc)
        for i in range(j + 1, d):
            acc = a[i, j]
            for k in range(j):
                acc -= low[i, k] * low[j, k]
            low[i, j] = acc / low[j, j]
    return low


@numba.njit(cache=True)
def _cholesky_solve(low: NDArray, b: NDArray) -> NDArray:
    """Solve ``(L L^T) x = b`` for ``b`` of shape ``(d, m)``."""
    d, m = b.shape
    x = b.copy()
    for c in range(m):
        for i in range(d):
            acc = x[i, c]
            for k in range(i):
                acc -= low[i, k] * x[k, c]
            x[i, c] = acc / low[i, i]
        for i in range(d - 1, -1, -1):
            acc = x[i, c]
            for k in range(i + 1, d):
                acc -= low[k, i] * x[k, c]
            x[i, c] = acc / low[i, i]
    return x


@numba.njit(cache=True)
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

    Args:
        mu: ``(3,)`` mean; cov: ``(3, 3)`` covariance.
        z: ``(N, 2)`` measurements; visible: ``(N,)`` mask; landmarks: ``(N, 2)`` (m).
        kind: sensor kind (``RELATIVE_POSITION`` or ``RANGE_BEARING``).
        noise_cov: ``(2, 2)`` R of one landmark measurement.

    Returns:
        The normalized innovation squared ``nu^T S^-1 nu`` (0 when nothing is visible).
    """
    n = landmarks.shape[0]
    m = 0
    for j in range(n):
        if visible[j]:
            m += 1
    if m == 0:
        return 0.0
    d = 2 * m
    jac = np.empty((d, 3))
    nu = np.empty(d)
    zhat = np.empty(2)
    row = 0
    for j in range(n):
        if not visible[j]:
            continue
        expected_measurement(kind, mu, landmarks[j], zhat, jac[row : row + 2])
        nu[row] = z[j, 0] - zhat[0]
        nu[row + 1] = z[j, 1] - zhat[1]
        if kind == RANGE_BEARING:
            nu[row + 1] = wrap_angle_scalar(nu[row + 1])
        row += 2
    # H Sigma, (d, 3); S = H Sigma H^T + R_blk, (d, d)
    h_cov = np.zeros((d, 3))
    for i in range(d):
        for k in range(3):
            for j in range(3):
                h_cov[i, j] += jac[i, k] * cov[k, j]
    s = np.zeros((d, d))
    for i in range(d):
        for j in range(d):
            acc = 0.0
            for k in range(3):
                acc += h_cov[i, k] * jac[j, k]
            s[i, j] = acc
    for blk in range(m):
        for a in range(2):
            for b in range(2):
                s[2 * blk + a, 2 * blk + b] += noise_cov[a, b]
    low = _cholesky(s)
    # K^T = S^-1 H Sigma, (d, 3)
    gain_t = _cholesky_solve(low, h_cov)
    white = _cholesky_solve(low, nu.reshape(d, 1))
    nis = 0.0
    for i in range(d):
        nis += nu[i] * white[i, 0]
    for i in range(3):
        acc = 0.0
        for k in range(d):
            acc += gain_t[k, i] * nu[k]
        mu[i] += acc
    mu[2] = wrap_angle_scalar(mu[2])
    # Joseph form: A = I - K H; Sigma = A Sigma A^T + K R_blk K^T
    a_mat = np.eye(3)
    for i in range(3):
        for j in range(3):
            for k in range(d):
                a_mat[i, j] -= gain_t[k, i] * jac[k, j]
    a_cov = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            for k in range(3):
                a_cov[i, j] += a_mat[i, k] * cov[k, j]
    new_cov = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for k in range(3):
                acc += a_cov[i, k] * a_mat[j, k]
            new_cov[i, j] = acc
    for blk in range(m):
        for i in range(3):
            for j in range(3):
                acc = 0.0
                for a in range(2):
                    for b in range(2):
                        acc += gain_t[2 * blk + a, i] * noise_cov[a, b] * gain_t[2 * blk + b, j]
                new_cov[i, j] += acc
    _symmetrize3(new_cov)
    cov[:, :] = new_cov
    return nis


@numba.njit(cache=True)
def ekf_predict_batch(
    mu: NDArray, cov: NDArray, controls: NDArray, dt: float, noise_cov: NDArray
) -> None:
    """:func:`ekf_predict` over ``(B, 3)`` means, ``(B, 3, 3)`` covariances, ``(B, 2)`` controls."""
    for b in range(mu.shape[0]):
        ekf_predict(mu[b], cov[b], controls[b, 0], controls[b, 1], dt, noise_cov)


@numba.njit(cache=True)
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
        out = EKFBelief.__new__(EKFBelief)
        out.mean = self.mean.copy()
        out.cov = self.cov.copy()
        out.motion = self.motion
        out.sensor = self.sensor
        out.last_nis = self.last_nis.copy()
        return out
