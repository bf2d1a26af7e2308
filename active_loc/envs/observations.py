"""The ``"belief"`` observation: what the filter believes plus the current scan, in [-1, 1].

Layout of the float32 vector (length ``11 + 6 * max_landmarks``):

| index          | content                                                              |
|----------------|----------------------------------------------------------------------|
| 0, 1           | belief mean x, y, normalized by the map bounds to [-1, 1]            |
| 2, 3           | cos, sin of the mean heading                                         |
| 4, 5, 6        | log std of x, y, theta, clipped to [log 1e-3, log 1e2], scaled       |
| 7, 8, 9        | correlation coefficients rho_xy, rho_xtheta, rho_ytheta              |
| 10             | belief entropy / 10 nats, clipped                                    |
| 11 + 6 j + 0   | landmark slot j exists (1) or is padding (0)                         |
| 11 + 6 j + 1,2 | landmark j in the frame of the belief mean, / scale, clipped         |
| 11 + 6 j + 3   | landmark j seen this step (1) or not (0)                             |
| 11 + 6 j + 4,5 | its measurement: range / scale and bearing / pi (range-bearing), or  |
|                | the relative position / scale (relative-position sensor); 0 unseen   |

``scale`` is the sensor's maximum range, or the map diagonal when the range is unlimited.
Everything comes from the belief and the sensor, never from the true pose.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

from active_loc.sensors.landmarks import RANGE_BEARING

BELIEF_HEADER = 11
SLOT_SIZE = 6
LOG_STD_MIN = float(np.log(1e-3))
LOG_STD_MAX = float(np.log(1e2))
ENTROPY_SCALE = 10.0


def belief_observation_size(max_landmarks: int) -> int:
    """Length of the ``"belief"`` observation vector."""
    return BELIEF_HEADER + SLOT_SIZE * max_landmarks


@numba.njit(cache=True, nogil=True, inline="always")
def _clip1(x: float) -> float:
    return min(1.0, max(-1.0, x))


@numba.njit(cache=True, nogil=True, inline="always")
def _scaled_log_std(var: float) -> float:
    log_std = 0.5 * np.log(max(var, 1e-300))
    log_std = min(LOG_STD_MAX, max(LOG_STD_MIN, log_std))
    return 2.0 * (log_std - LOG_STD_MIN) / (LOG_STD_MAX - LOG_STD_MIN) - 1.0


@numba.njit(cache=True, nogil=True)
def write_belief_header(
    mean: NDArray, cov: NDArray, entropy: float, bounds: NDArray, out: NDArray
) -> None:
    """The first :data:`BELIEF_HEADER` entries of an observation row ``out`` (float32): the
    Gaussian summary of a belief (mean ``(3,)``, covariance ``(3, 3)``, entropy in nats)
    normalized by the map bounds ``(4,)``."""
    out[0] = _clip1(2.0 * (mean[0] - bounds[0]) / (bounds[2] - bounds[0]) - 1.0)
    out[1] = _clip1(2.0 * (mean[1] - bounds[1]) / (bounds[3] - bounds[1]) - 1.0)
    out[2] = np.cos(mean[2])
    out[3] = np.sin(mean[2])
    for i in range(3):
        out[4 + i] = _scaled_log_std(cov[i, i])
    pairs = ((0, 1), (0, 2), (1, 2))
    for p in range(3):
        i, j = pairs[p]
        denom = np.sqrt(max(cov[i, i] * cov[j, j], 1e-300))
        out[7 + p] = _clip1(cov[i, j] / denom)
    out[10] = _clip1(entropy / ENTROPY_SCALE)


@numba.njit(cache=True, nogil=True)
def write_landmark_slots(
    mean: NDArray,
    z: NDArray,
    visible: NDArray,
    landmarks: NDArray,
    count: int,
    kind: int,
    scale: float,
    out: NDArray,
) -> None:
    """Landmark slots into ``out`` (float32, ``6 N`` entries): each landmark relative to the
    belief mean ``(3,)`` and this step's measurement with a visibility flag.

    Args:
        z: ``(N, 2)`` scan; visible: ``(N,)``; landmarks: ``(N, 2)`` of which the
            first ``count`` are real.
        kind: sensor kind; scale: distance scale (m).
    """
    c = np.cos(mean[2])
    s = np.sin(mean[2])
    for j in range(landmarks.shape[0]):
        base = SLOT_SIZE * j
        if j >= count:
            for k in range(SLOT_SIZE):
                out[base + k] = 0.0
            continue
        dx = landmarks[j, 0] - mean[0]
        dy = landmarks[j, 1] - mean[1]
        out[base] = 1.0
        out[base + 1] = _clip1((c * dx + s * dy) / scale)
        out[base + 2] = _clip1((-s * dx + c * dy) / scale)
        if visible[j]:
            out[base + 3] = 1.0
            out[base + 4] = _clip1(z[j, 0] / scale)
            if kind == RANGE_BEARING:
                out[base + 5] = _clip1(z[j, 1] / np.pi)
            else:
                out[base + 5] = _clip1(z[j, 1] / scale)
        else:
            out[base + 3] = 0.0
            out[base + 4] = 0.0
            out[base + 5] = 0.0


@numba.njit(cache=True, nogil=True)
def write_belief_observation(
    mean: NDArray,
    cov: NDArray,
    entropy: float,
    z: NDArray,
    visible: NDArray,
    landmarks: NDArray,
    count: int,
    bounds: NDArray,
    kind: int,
    scale: float,
    out: NDArray,
) -> None:
    """Fill one landmark-map observation row ``out`` (float32): the belief header, then the
    landmark slots (arguments as in :func:`write_belief_header` and
    :func:`write_landmark_slots`)."""
    write_belief_header(mean, cov, entropy, bounds, out)
    write_landmark_slots(mean, z, visible, landmarks, count, kind, scale, out[BELIEF_HEADER:])
