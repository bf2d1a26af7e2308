"""Landmark detections without identities: misses, clutter, and a shuffled order.

With identical-looking landmarks the sensor returns a *set* of measurements: each landmark in
view is detected with probability ``1 - miss_probability`` (independently, per landmark and
scan), false detections (clutter) are added, and the order of the list is random, so that
neither the position in the list nor anything else tells which landmark a measurement came
from. The filter has to infer the correspondences (:mod:`active_loc.beliefs.association`).

Clutter model. The number of false detections of a scan is Poisson with mean
``clutter_rate``, drawn by inversion of one uniform and truncated at :attr:`max_clutter`, the
smallest count whose Poisson tail is below :data:`CLUTTER_TAIL` (so the truncation changes
nothing measurable and the number of draws per scan stays fixed). Each false detection is a
point uniform over the *area* of the sensor's field of view: bearing uniform in
``[-fov/2, fov/2]`` around the heading, range ``clutter_range * sqrt(u)`` (uniform over the
disc sector, not over the range interval), noise-free, then expressed in the sensor's
measurement space (range-bearing, or the position in the robot frame). ``clutter_range`` is
the sensor's ``max_range``, or a map-sized distance when the range is unlimited.

Randomness: one scan uses exactly :func:`detection_draws` uniforms and normals, whatever the
scene, drawn by the caller from the env's Generator and passed to :func:`simulate_detections`.
The true correspondence of each detection (landmark index, or -1 for clutter) is returned for
metrics only: a filter must never read it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from active_loc.geometry import wrap_angle_scalar
from active_loc.sensors.landmarks import RANGE_BEARING, LandmarkSensor, in_view, measurement

#: the Poisson clutter count is truncated where its tail probability falls below this
CLUTTER_TAIL = 1e-12
#: the largest clutter rate (false detections per scan) a model accepts
MAX_CLUTTER_RATE = 50.0
#: correspondence of a false detection
CLUTTER = -1


def max_clutter_count(clutter_rate: float) -> int:
    """The smallest k with ``P(Poisson(clutter_rate) > k) < CLUTTER_TAIL`` (0 for rate 0)."""
    if clutter_rate <= 0.0:
        return 0
    k = 0
    pmf = math.exp(-clutter_rate)
    cdf = pmf
    while 1.0 - cdf >= CLUTTER_TAIL:
        k += 1
        pmf *= clutter_rate / k
        cdf += pmf
    return k


def detection_draws(n_landmarks: int, max_clutter: int) -> tuple[int, int]:
    """``(uniforms, normals)`` one scan of :func:`simulate_detections` consumes.

    Uniforms: the clutter count (1), one miss draw per landmark (N), bearing and range of every
    possible clutter point (2 C), an ordering key per possible detection (N + C). Normals: the
    measurement noise of every landmark (2 N), whether it is seen or not.
    """
    return 1 + 2 * n_landmarks + 3 * max_clutter, 2 * n_landmarks


@numba.njit(cache=True, nogil=True)
def sort_order(keys: NDArray, n: int, order: NDArray) -> None:
    """The permutation sorting ``keys[:n]`` ascending into ``order[:n]`` (an insertion sort:
    scans hold a few tens of detections, where it beats ``np.argsort`` many times over)."""
    for i in range(n):
        order[i] = i
    for i in range(1, n):
        current = order[i]
        key = keys[current]
        j = i - 1
        while j >= 0 and keys[order[j]] > key:
            order[j + 1] = order[j]
            j -= 1
        order[j + 1] = current


@numba.njit(cache=True, nogil=True)
def simulate_detections(
    kind: int,
    pose: NDArray,
    landmarks: NDArray,
    count: int,
    fov: float,
    max_range: float,
    noise_root: tuple,
    miss_probability: float,
    clutter_rate: float,
    clutter_range: float,
    max_clutter: int,
    uniforms: NDArray,
    normals: NDArray,
    z: NDArray,
    truth: NDArray,
    detected: NDArray,
) -> int:
    """Simulate one scan of identical-looking landmarks from the true ``pose`` ``(3,)``.

    Args:
        kind: sensor kind (``RELATIVE_POSITION`` or ``RANGE_BEARING``).
        landmarks: ``(N, 2)`` positions (m); only the first ``count`` rows are real.
        fov, max_range: field of view (rad) and range (m) of the sensor.
        noise_root: ``(l00, l10, l11)``, the lower Cholesky factor L of R (L L^T = R).
        miss_probability: probability that a landmark in view is not detected.
        clutter_rate: mean number of false detections per scan.
        clutter_range: radius (m) of the sector the clutter is spread over.
        max_clutter: truncation of the clutter count (:func:`max_clutter_count`).
        uniforms, normals: U(0, 1) and N(0, 1) draws, ``detection_draws(N, max_clutter)``.
        z: ``(N + max_clutter, 2)`` out: the detections, rows ``[0, n)``, in random order.
        truth: ``(N + max_clutter,)`` int out: the landmark index of each detection, or
            :data:`CLUTTER` (-1); for metrics only.
        detected: ``(N,)`` bool out: which landmarks were detected.

    Returns:
        n, the number of detections.
    """
    n_rows = landmarks.shape[0]
    l00, l10, l11 = noise_root
    x, y, theta = pose[0], pose[1], pose[2]
    # clutter count by inversion of one uniform, truncated at max_clutter
    n_clutter = 0
    if max_clutter > 0:
        pmf = np.exp(-clutter_rate)
        cdf = pmf
        u = uniforms[0]
        while u > cdf and n_clutter < max_clutter:
            n_clutter += 1
            pmf *= clutter_rate / n_clutter
            cdf += pmf
    miss_base = 1
    clutter_base = 1 + n_rows
    key_base = 1 + n_rows + 2 * max_clutter
    keys = np.empty(n_rows + max_clutter)
    n = 0
    for j in range(n_rows):
        seen = j < count and in_view(x, y, theta, landmarks[j, 0], landmarks[j, 1], fov,
                                     max_range)
        seen = seen and uniforms[miss_base + j] >= miss_probability
        detected[j] = seen
        if not seen:
            continue
        z0, z1 = measurement(kind, x, y, theta, landmarks[j, 0], landmarks[j, 1])
        e0 = normals[2 * j]
        e1 = normals[2 * j + 1]
        z[n, 0] = z0 + l00 * e0
        z1 += l10 * e0 + l11 * e1
        z[n, 1] = wrap_angle_scalar(z1) if kind == RANGE_BEARING else z1
        truth[n] = j
        keys[n] = uniforms[key_base + j]
        n += 1
    full_circle = fov >= 2.0 * np.pi
    for c in range(n_clutter):
        u_b = uniforms[clutter_base + 2 * c]
        u_r = uniforms[clutter_base + 2 * c + 1]
        bearing = -np.pi + 2.0 * np.pi * u_b if full_circle else (u_b - 0.5) * fov
        r = clutter_range * np.sqrt(u_r)
        if kind == RANGE_BEARING:
            z[n, 0] = r
            z[n, 1] = wrap_angle_scalar(bearing)
        else:
            z[n, 0] = r * np.cos(bearing)
            z[n, 1] = r * np.sin(bearing)
        truth[n] = CLUTTER
        keys[n] = uniforms[key_base + n_rows + c]
        n += 1
    # drop the identities from the order: sort the detections by their random keys
    order = np.empty(n, dtype=np.int64)
    sort_order(keys, n, order)
    z_sorted = z[:n].copy()
    truth_sorted = truth[:n].copy()
    for i in range(n):
        z[i, 0] = z_sorted[order[i], 0]
        z[i, 1] = z_sorted[order[i], 1]
        truth[i] = truth_sorted[order[i]]
    return n


@dataclass(frozen=True)
class DetectionModel:
    """Misses and clutter of a landmark sensor whose landmarks look identical.

    Attributes:
        miss_probability: probability in [0, 1) that a landmark in view is not detected.
        clutter_rate: mean number of false detections per scan, in [0, MAX_CLUTTER_RATE].
        clutter_range: radius (m) of the field-of-view sector the clutter spreads over.
    """

    miss_probability: float = 0.0
    clutter_rate: float = 0.0
    clutter_range: float = 6.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.miss_probability < 1.0:
            raise ValueError(
                f"DetectionModel.miss_probability must be in [0, 1), got {self.miss_probability}"
            )
        if not 0.0 <= self.clutter_rate <= MAX_CLUTTER_RATE:
            raise ValueError(
                f"DetectionModel.clutter_rate must be in [0, {MAX_CLUTTER_RATE}] per scan, got "
                f"{self.clutter_rate}"
            )
        if not (math.isfinite(self.clutter_range) and self.clutter_range > 0.0):
            raise ValueError(
                f"DetectionModel.clutter_range must be a finite number > 0 m, got "
                f"{self.clutter_range}"
            )

    @property
    def max_clutter(self) -> int:
        """The truncation of the Poisson clutter count."""
        return max_clutter_count(self.clutter_rate)

    def draws(self, n_landmarks: int) -> tuple[int, int]:
        """``(uniforms, normals)`` one scan of ``n_landmarks`` rows consumes."""
        return detection_draws(n_landmarks, self.max_clutter)

    def scan(
        self,
        sensor: LandmarkSensor,
        pose: ArrayLike,
        landmarks: ArrayLike,
        rng: np.random.Generator,
    ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """One scan of ``sensor`` from ``pose`` ``(3,)`` among ``landmarks`` ``(N, 2)``.

        Returns:
            The detections ``(n, 2)`` in random order and the true correspondence of each
            ``(n,)`` (landmark index, or -1 for clutter; for metrics only).
        """
        pose = np.ascontiguousarray(pose, dtype=np.float64).reshape(3)
        landmarks = np.ascontiguousarray(landmarks, dtype=np.float64).reshape(-1, 2)
        n_rows = landmarks.shape[0]
        max_clutter = self.max_clutter
        n_uniforms, n_normals = detection_draws(n_rows, max_clutter)
        uniforms = rng.random(n_uniforms)
        normals = rng.standard_normal(n_normals)
        z = np.empty((n_rows + max_clutter, 2))
        truth = np.empty(n_rows + max_clutter, dtype=np.int64)
        detected = np.empty(n_rows, dtype=np.bool_)
        root = sensor.noise_root
        n = simulate_detections(
            sensor.kind, pose, landmarks, n_rows, float(sensor.fov), float(sensor.max_range),
            (root[0, 0], root[1, 0], root[1, 1]), float(self.miss_probability),
            float(self.clutter_rate), float(self.clutter_range), max_clutter, uniforms,
            normals, z, truth, detected,
        )
        return z[:n].copy(), truth[:n].copy()
