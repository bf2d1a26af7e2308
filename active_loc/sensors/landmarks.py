"""Landmark sensors with known correspondences.

Two measurement models of the chapter, each giving a 2-vector per landmark:

* relative position (section 13.8, problem 1): the landmark in the robot frame,
  ``z = R(theta)^T (m - p)`` (m);
* range and bearing (eq. 13.8): ``z = (|m - p|, atan2(m_y - y, m_x - x) - theta)`` (m, rad),
  with the Jacobian of eq. 13.9.

A landmark is seen when it lies within ``max_range`` (m) and inside the field of view
``fov`` (rad, centred on the heading). Measurement noise is N(0, R). The kernels here work on
one pose and one landmark; the sensor classes apply them to batches.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from active_loc.geometry import wrap_angle, wrap_angle_scalar

RELATIVE_POSITION = 0
RANGE_BEARING = 1


@numba.njit(cache=True, nogil=True)
def measurement(kind: int, x: float, y: float, theta: float, mx: float, my: float) -> tuple:
    """h(pose, m) of landmark ``(mx, my)`` seen from pose ``(x, y, theta)``: ``(z0, z1)``."""
    dx = mx - x
    dy = my - y
    if kind == RELATIVE_POSITION:
        c = np.cos(theta)
        s = np.sin(theta)
        return c * dx + s * dy, -s * dx + c * dy
    return np.sqrt(dx * dx + dy * dy), wrap_angle_scalar(np.arctan2(dy, dx) - theta)


@numba.njit(cache=True, nogil=True)
def measurement_and_jacobian(
    kind: int, x: float, y: float, theta: float, mx: float, my: float
) -> tuple:
    """h(pose, m) and its Jacobian dh/dpose, as the 8-tuple
    ``(z0, z1, H00, H01, H02, H10, H11, H12)`` (scalars: no allocation on the step path)."""
    dx = mx - x
    dy = my - y
    if kind == RELATIVE_POSITION:
        c = np.cos(theta)
        s = np.sin(theta)
        z0 = c * dx + s * dy
        z1 = -s * dx + c * dy
        return z0, z1, -c, -s, z1, s, -c, -z0
    # a landmark exactly at the robot has no bearing; keep the Jacobian finite
    q = max(dx * dx + dy * dy, 1e-12)
    r = np.sqrt(q)
    bearing = wrap_angle_scalar(np.arctan2(dy, dx) - theta)
    return r, bearing, -dx / r, -dy / r, 0.0, dy / q, -dx / q, -1.0


@numba.njit(cache=True, nogil=True)
def expected_measurement(
    kind: int, pose: NDArray, landmark: NDArray, z: NDArray, jac: NDArray
) -> None:
    """h(pose, m) into ``z`` ``(2,)`` and its Jacobian dh/dpose into ``jac`` ``(2, 3)``."""
    out = measurement_and_jacobian(kind, pose[0], pose[1], pose[2], landmark[0], landmark[1])
    z[0], z[1] = out[0], out[1]
    jac[0, 0], jac[0, 1], jac[0, 2] = out[2], out[3], out[4]
    jac[1, 0], jac[1, 1], jac[1, 2] = out[5], out[6], out[7]


@numba.njit(cache=True, nogil=True)
def in_view(
    x: float, y: float, theta: float, mx: float, my: float, fov: float, max_range: float
) -> bool:
    """Whether landmark ``(mx, my)`` is within ``max_range`` (m) and the field of view ``fov``
    (rad) of pose ``(x, y, theta)``."""
    dx = mx - x
    dy = my - y
    if dx * dx + dy * dy > max_range * max_range:
        return False
    if fov >= 2.0 * np.pi:
        return True
    bearing = wrap_angle_scalar(np.arctan2(dy, dx) - theta)
    return abs(bearing) <= 0.5 * fov


@numba.njit(cache=True, nogil=True)
def sees_a_landmark(
    x: float, y: float, theta: float, landmarks: NDArray, fov: float, max_range: float
) -> bool:
    """Whether any landmark of ``landmarks`` ``(n, 2)`` is in view (:func:`in_view`) of pose
    ``(x, y, theta)``."""
    for j in range(landmarks.shape[0]):
        if in_view(x, y, theta, landmarks[j, 0], landmarks[j, 1], fov, max_range):
            return True
    return False


@numba.njit(cache=True, nogil=True)
def measure_landmarks(
    kind: int,
    pose: NDArray,
    landmarks: NDArray,
    count: int,
    fov: float,
    max_range: float,
    noise_root: tuple,
    normals: NDArray,
    z: NDArray,
    visible: NDArray,
) -> int:
    """Simulate one scan of all landmarks from the true ``pose``.

    Args:
        landmarks: ``(N, 2)`` positions; only the first ``count`` rows are real (the rest pad).
        noise_root: ``(l00, l10, l11)``, the lower Cholesky factor L of R (L L^T = R).
        normals: N(0, 1) draws, consumed in order, 2 per landmark in view (at most ``2 N``).
        z: ``(N, 2)`` out: measurements (zero where not visible).
        visible: ``(N,)`` out: which landmarks were seen.

    Returns:
        How many normals were used (2 per landmark seen).
    """
    l00, l10, l11 = noise_root
    x, y, theta = pose[0], pose[1], pose[2]
    used = 0
    for j in range(landmarks.shape[0]):
        mx, my = landmarks[j, 0], landmarks[j, 1]
        seen = j < count and in_view(x, y, theta, mx, my, fov, max_range)
        visible[j] = seen
        if not seen:
            z[j, 0] = 0.0
            z[j, 1] = 0.0
            continue
        z0, z1 = measurement(kind, x, y, theta, mx, my)
        e0 = normals[used]
        e1 = normals[used + 1]
        used += 2
        z[j, 0] = z0 + l00 * e0
        z1 += l10 * e0 + l11 * e1
        z[j, 1] = wrap_angle_scalar(z1) if kind == RANGE_BEARING else z1
    return used


def _check_sensor(name: str, noise_cov: NDArray, fov: float, max_range: float) -> NDArray:
    r = np.array(noise_cov, dtype=np.float64)
    if r.shape != (2, 2) or not np.all(np.isfinite(r)):
        raise ValueError(f"{name}.noise_cov must be a finite (2, 2) matrix, got {r.tolist()}")
    if not np.allclose(r, r.T) or np.linalg.eigvalsh(r).min() <= 0:
        raise ValueError(f"{name}.noise_cov must be symmetric positive definite, got {r.tolist()}")
    if not (0 < fov <= 2 * np.pi):
        raise ValueError(f"{name}.fov must be in (0, 2*pi] rad, got {fov}")
    if not max_range > 0:
        raise ValueError(f"{name}.max_range must be > 0 m, got {max_range}")
    r.setflags(write=False)
    return r


@dataclass(frozen=True)
class LandmarkSensor:
    """Base of the landmark sensors: noise, field of view and range, batched helpers.

    Attributes:
        noise_cov: ``(2, 2)`` measurement noise covariance R, positive definite.
        fov: field of view (rad), centred on the heading; ``2*pi`` sees all around.
        max_range: maximum range (m); ``inf`` for unlimited.
    """

    noise_cov: NDArray[np.float64] = field(default_factory=lambda: 0.25 * np.eye(2))
    fov: float = 2 * np.pi
    max_range: float = float("inf")

    kind = RELATIVE_POSITION
    #: which of the two measurement components are angles (wrapped residuals)
    angular = (False, False)

    def __post_init__(self) -> None:
        name = type(self).__name__
        r = _check_sensor(name, self.noise_cov, float(self.fov), float(self.max_range))
        object.__setattr__(self, "noise_cov", r)
        root = np.linalg.cholesky(r)
        root.setflags(write=False)
        object.__setattr__(self, "_noise_root", root)

    @property
    def noise_root(self) -> NDArray[np.float64]:
        """``(2, 2)`` Cholesky factor L of R."""
        return self._noise_root  # type: ignore[attr-defined]

    def expected(self, poses: ArrayLike, landmarks: ArrayLike) -> NDArray[np.float64]:
        """h(pose, m) for poses ``(..., 3)`` against landmarks ``(N, 2)``: ``(..., N, 2)``."""
        raise NotImplementedError

    def jacobian(self, poses: ArrayLike, landmarks: ArrayLike) -> NDArray[np.float64]:
        """dh/dpose for poses ``(..., 3)`` against landmarks ``(N, 2)``: ``(..., N, 2, 3)``."""
        poses = np.asarray(poses, dtype=np.float64)
        landmarks = np.asarray(landmarks, dtype=np.float64)
        flat = poses.reshape(-1, 3)
        out = np.empty((flat.shape[0], landmarks.shape[0], 2, 3))
        z = np.empty(2)
        for b in range(flat.shape[0]):
            for j in range(landmarks.shape[0]):
                expected_measurement(self.kind, flat[b], landmarks[j], z, out[b, j])
        return out.reshape(*poses.shape[:-1], landmarks.shape[0], 2, 3)

    def visible(self, poses: ArrayLike, landmarks: ArrayLike) -> NDArray[np.bool_]:
        """Which landmarks ``(N, 2)`` each pose ``(..., 3)`` sees: ``(..., N)`` booleans."""
        poses = np.asarray(poses, dtype=np.float64)
        landmarks = np.asarray(landmarks, dtype=np.float64)
        dx = landmarks[:, 0] - poses[..., None, 0]
        dy = landmarks[:, 1] - poses[..., None, 1]
        seen = dx**2 + dy**2 <= self.max_range**2
        if self.fov < 2 * np.pi:
            bearing = wrap_angle(np.arctan2(dy, dx) - poses[..., None, 2])
            seen &= np.abs(bearing) <= 0.5 * self.fov
        return seen

    def residual(self, z: ArrayLike, z_expected: ArrayLike) -> NDArray[np.float64]:
        """Innovation ``z - z_expected`` ``(..., 2)`` with angular components wrapped."""
        diff = np.asarray(z, dtype=np.float64) - np.asarray(z_expected, dtype=np.float64)
        for i, is_angle in enumerate(self.angular):
            if is_angle:
                diff[..., i] = wrap_angle(diff[..., i])
        return diff

    def measure(
        self, poses: ArrayLike, landmarks: ArrayLike, rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Noisy measurements ``(..., N, 2)`` (zero where unseen) and visibility ``(..., N)``."""
        poses = np.asarray(poses, dtype=np.float64)
        landmarks = np.asarray(landmarks, dtype=np.float64)
        flat = poses.reshape(-1, 3)
        n = landmarks.shape[0]
        z = np.zeros((flat.shape[0], n, 2))
        seen = np.zeros((flat.shape[0], n), dtype=np.bool_)
        normals = rng.standard_normal((flat.shape[0], 2 * n))
        root = self.noise_root
        for b in range(flat.shape[0]):
            measure_landmarks(
                self.kind, flat[b], landmarks, n, float(self.fov), float(self.max_range),
                (root[0, 0], root[1, 0], root[1, 1]), normals[b], z[b], seen[b],
            )
        return z.reshape(*poses.shape[:-1], n, 2), seen.reshape(*poses.shape[:-1], n)


@dataclass(frozen=True)
class RelativePositionSensor(LandmarkSensor):
    """Landmark position in the robot frame, ``R(theta)^T (m - p)`` (m); the textbook sensor."""

    kind = RELATIVE_POSITION
    angular = (False, False)

    def expected(self, poses: ArrayLike, landmarks: ArrayLike) -> NDArray[np.float64]:
        poses = np.asarray(poses, dtype=np.float64)
        landmarks = np.asarray(landmarks, dtype=np.float64)
        dx = landmarks[:, 0] - poses[..., None, 0]
        dy = landmarks[:, 1] - poses[..., None, 1]
        c, s = np.cos(poses[..., None, 2]), np.sin(poses[..., None, 2])
        return np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1)


@dataclass(frozen=True)
class RangeBearingSensor(LandmarkSensor):
    """Range (m) and bearing (rad) to each landmark, eq. 13.8."""

    noise_cov: NDArray[np.float64] = field(
        default_factory=lambda: np.diag([0.1**2, np.deg2rad(2.0) ** 2])
    )
    kind = RANGE_BEARING
    angular = (False, True)

    @classmethod
    def from_std(
        cls, range_std: float, bearing_std: float, fov: float = 2 * np.pi,
        max_range: float = float("inf"),
    ) -> RangeBearingSensor:
        """Sensor with diagonal R = diag(range_std^2, bearing_std^2) (m, rad)."""
        if not (range_std > 0 and bearing_std > 0):
            raise ValueError(
                f"RangeBearingSensor: range_std and bearing_std must be > 0, got "
                f"{range_std}, {bearing_std}"
            )
        return cls(np.diag([range_std**2, bearing_std**2]), fov=fov, max_range=max_range)

    def expected(self, poses: ArrayLike, landmarks: ArrayLike) -> NDArray[np.float64]:
        poses = np.asarray(poses, dtype=np.float64)
        landmarks = np.asarray(landmarks, dtype=np.float64)
        dx = landmarks[:, 0] - poses[..., None, 0]
        dy = landmarks[:, 1] - poses[..., None, 1]
        bearing = wrap_angle(np.arctan2(dy, dx) - poses[..., None, 2])
        return np.stack([np.hypot(dx, dy), bearing], axis=-1)
