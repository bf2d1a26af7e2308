"""The same EKF through ``filterpy.kalman.ExtendedKalmanFilter``: the reference backend.

``filterpy`` is the project's reference implementation. This backend runs the identical model
(unicycle prediction, stacked landmark update, Joseph form) through it, so the numba EKF can be
checked step for step and single envs can choose it with ``ekf_backend="filterpy"``.
It holds one belief (B = 1); it is slower and meant for checking, not for training.
"""

from __future__ import annotations

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter
from numpy.typing import ArrayLike, NDArray

from active_loc.beliefs.entropy import gaussian_entropy
from active_loc.geometry import wrap_angle
from active_loc.motion import UnicycleModel
from active_loc.sensors.landmarks import LandmarkSensor


class UnicycleEKF(ExtendedKalmanFilter):
    """filterpy's EKF with the nonlinear unicycle prediction ``x = f(x, u)``."""

    def __init__(self, motion: UnicycleModel) -> None:
        super().__init__(dim_x=3, dim_z=2)
        self.motion = motion
        self.Q = motion.noise_cov.copy()

    def predict_x(self, u: NDArray = 0) -> None:
        self.x = self.motion.mean(self.x.ravel(), u).reshape(3, 1)

    def predict_with_control(self, u: NDArray) -> None:
        """F at the prior mean, then filterpy's predict (x = f(x, u), P = F P F^T + Q)."""
        self.F = self.motion.jacobian(self.x.ravel(), u)
        self.predict(u)


class FilterpyEKFBelief:
    """A single Gaussian belief (batch of one) updated by filterpy.

    Same interface as :class:`active_loc.beliefs.ekf.EKFBelief` with ``B = 1``.
    """

    def __init__(
        self, mean: ArrayLike, cov: ArrayLike, motion: UnicycleModel, sensor: LandmarkSensor
    ) -> None:
        mean = np.asarray(mean, dtype=np.float64).reshape(-1, 3)
        cov = np.asarray(cov, dtype=np.float64).reshape(-1, 3, 3)
        if mean.shape[0] != 1:
            raise ValueError(
                "FilterpyEKFBelief holds one belief (B = 1); use EKFBelief for batches"
            )
        self.motion = motion
        self.sensor = sensor
        self.filter = UnicycleEKF(motion)
        self.filter.x = mean[0].reshape(3, 1).copy()
        self.filter.P = cov[0].copy()
        self.last_nis = np.zeros(1)

    @property
    def batch_size(self) -> int:
        return 1

    def set(self, mean: ArrayLike, cov: ArrayLike) -> None:
        """Restart the filter at mean ``(3,)`` and covariance ``(3, 3)``."""
        self.filter.x = np.array(mean, dtype=np.float64).reshape(3, 1)
        self.filter.P = np.array(cov, dtype=np.float64).reshape(3, 3)

    @property
    def mean(self) -> NDArray[np.float64]:
        return self.filter.x.reshape(1, 3)

    @property
    def cov(self) -> NDArray[np.float64]:
        return self.filter.P.reshape(1, 3, 3)

    def predict(self, controls: ArrayLike) -> None:
        self.filter.predict_with_control(np.asarray(controls, dtype=np.float64).reshape(2))
        self.filter.x[2, 0] = wrap_angle(self.filter.x[2, 0])

    def update(self, z: ArrayLike, visible: ArrayLike, landmarks: ArrayLike) -> None:
        z = np.asarray(z, dtype=np.float64).reshape(-1, 2)
        visible = np.asarray(visible, dtype=np.bool_).reshape(-1)
        seen = np.asarray(landmarks, dtype=np.float64).reshape(-1, 2)[visible]
        if seen.shape[0] == 0:
            self.last_nis[0] = 0.0
            return
        sensor = self.sensor

        def hx(x: NDArray) -> NDArray:
            return sensor.expected(x.ravel(), seen).reshape(-1, 1)

        def jacobian(x: NDArray) -> NDArray:
            return sensor.jacobian(x.ravel(), seen).reshape(-1, 3)

        def residual(a: NDArray, b: NDArray) -> NDArray:
            return sensor.residual(a.reshape(-1, 2), b.reshape(-1, 2)).reshape(-1, 1)

        r_blk = np.kron(np.eye(seen.shape[0]), sensor.noise_cov)
        self.filter.update(z[visible].reshape(-1, 1), jacobian, hx, R=r_blk, residual=residual)
        self.filter.x[2, 0] = wrap_angle(self.filter.x[2, 0])
        y = self.filter.y.ravel()
        self.last_nis[0] = float(y @ np.linalg.solve(self.filter.S, y))

    def entropy(self) -> NDArray[np.float64]:
        return gaussian_entropy(self.cov)

    def copy(self) -> FilterpyEKFBelief:
        return FilterpyEKFBelief(self.mean.copy(), self.cov.copy(), self.motion, self.sensor)
