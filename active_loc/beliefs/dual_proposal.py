"""The dual proposal of mixture MCL on landmark maps: poses drawn from a scan's detections.

Plain MCL proposes from the motion model and weights by the measurement, so with few
particles a global prior rarely puts one near the truth. Mixture MCL (Thrun, Fox, Burgard and
Dellaert 2001) also proposes from the measurement: a landmark ``m`` detected at ``z`` (range
and bearing, or relative position) puts the robot on the set of poses that see ``m`` at
``z``, whatever its heading. A dual pose is drawn as

1. a pair (detection i, landmark j) uniformly among :func:`dual_pairs` (with known
   correspondences detection i is landmark i; otherwise every landmark is a candidate);
2. a heading ``theta ~ U[-pi, pi)`` and a noisy reading ``z' = z_i + L n``, ``n ~ N(0, I)``,
   ``L L^T = R``;
3. the pose that reads ``m_j`` at exactly ``z'`` with that heading.

Its density is the mixture over pairs ``q(x) = mean_ij N(h(x, m_j); z_i, R) J(x, m_j) / (2 pi)``,
where ``J`` is the Jacobian of the map from ``(z', theta)`` to the pose: 1 for relative
position (a rotation), ``1 / |m_j - p|`` for range and bearing (polar coordinates).
:func:`dual_log_density` evaluates it, so a caller can weight dual poses exactly:
``w = p(z | x) bel_bar(x) / q(x)`` targets the same posterior as the motion proposal's ``p(z | x)``.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from active_loc.geometry import wrap_angle_scalar
from active_loc.sensors.landmarks import RANGE_BEARING, RELATIVE_POSITION, measurement

_LOG_TWO_PI = math.log(2.0 * math.pi)


def dual_pairs(visible: ArrayLike, n_landmarks: int, known_correspondence: bool) -> NDArray:
    """The (detection, landmark) pairs a dual pose can come from, ``(P, 2)`` int64.

    Args:
        visible: ``(N,)`` bool, which measurement rows are real detections.
        n_landmarks: L, the real landmarks (rows of the map).
        known_correspondence: detection i is landmark i (then ``N == L``); otherwise every
            landmark is a candidate of every detection.
    """
    detections = np.flatnonzero(np.asarray(visible, dtype=np.bool_).reshape(-1))
    if known_correspondence:
        return np.stack([detections, detections], axis=1).astype(np.int64)
    grid = np.meshgrid(detections, np.arange(n_landmarks), indexing="ij")
    return np.stack([g.reshape(-1) for g in grid], axis=1).astype(np.int64)


@numba.njit(cache=True, nogil=True)
def dual_sample_kernel(
    z: NDArray, landmarks: NDArray, pairs: NDArray, kind: int, root: NDArray,
    uniforms: NDArray, normals: NDArray, out: NDArray, valid: NDArray,
) -> None:
    """Dual poses from the pairs: ``uniforms`` ``(n, 2)`` pick the pair and the heading,
    ``normals`` ``(n, 2)`` the reading's noise; ``out`` ``(n, 3)`` the poses. ``valid[k]``
    is False when the noisy range of pose k is not positive (no pose reads it)."""
    n_pairs = pairs.shape[0]
    for k in range(out.shape[0]):
        p = min(int(uniforms[k, 0] * n_pairs), n_pairs - 1)
        i = pairs[p, 0]
        j = pairs[p, 1]
        theta = (2.0 * uniforms[k, 1] - 1.0) * math.pi
        z0 = z[i, 0] + root[0, 0] * normals[k, 0]
        z1 = z[i, 1] + root[1, 0] * normals[k, 0] + root[1, 1] * normals[k, 1]
        if kind == RELATIVE_POSITION:
            # m = p + R(theta) z'  =>  p = m - R(theta) z'
            c = math.cos(theta)
            s = math.sin(theta)
            dx = c * z0 - s * z1
            dy = s * z0 + c * z1
            valid[k] = True
        else:
            valid[k] = z0 > 0.0
            dx = z0 * math.cos(theta + z1)
            dy = z0 * math.sin(theta + z1)
        out[k, 0] = landmarks[j, 0] - dx
        out[k, 1] = landmarks[j, 1] - dy
        out[k, 2] = theta


@numba.njit(cache=True, nogil=True)
def dual_log_density_kernel(
    poses: NDArray, z: NDArray, landmarks: NDArray, pairs: NDArray, kind: int, root: NDArray,
    out: NDArray,
) -> None:
    """``log q(x)`` ``(n,)`` of the dual proposal at ``poses`` ``(n, 3)`` (module docstring)."""
    n_pairs = pairs.shape[0]
    l00 = root[0, 0]
    l10 = root[1, 0]
    l11 = root[1, 1]
    log_norm = -_LOG_TWO_PI - math.log(l00) - math.log(l11)
    # the heading's density 1 / (2 pi) and the pair's 1 / P
    log_const = -_LOG_TWO_PI - math.log(n_pairs)
    for k in range(poses.shape[0]):
        x = poses[k, 0]
        y = poses[k, 1]
        th = poses[k, 2]
        best = -np.inf
        terms = np.empty(n_pairs)
        for p in range(n_pairs):
            i = pairs[p, 0]
            j = pairs[p, 1]
            h0, h1 = measurement(kind, x, y, th, landmarks[j, 0], landmarks[j, 1])
            r0 = z[i, 0] - h0
            r1 = z[i, 1] - h1
            log_jac = 0.0
            if kind == RANGE_BEARING:
                r1 = wrap_angle_scalar(r1)
                log_jac = -math.log(max(h0, 1e-300))
            w0 = r0 / l00
            w1 = (r1 - l10 * w0) / l11
            terms[p] = log_norm - 0.5 * (w0 * w0 + w1 * w1) + log_jac
            if terms[p] > best:
                best = terms[p]
        if best == -np.inf:
            out[k] = -np.inf
            continue
        total = 0.0
        for p in range(n_pairs):
            total += math.exp(terms[p] - best)
        out[k] = best + math.log(total) + log_const


def _inputs(
    z: ArrayLike, landmarks: ArrayLike, pairs: ArrayLike, kind: int, noise_cov: ArrayLike
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    z = np.ascontiguousarray(z, dtype=np.float64).reshape(-1, 2)
    landmarks = np.ascontiguousarray(landmarks, dtype=np.float64).reshape(-1, 2)
    pairs = np.ascontiguousarray(pairs, dtype=np.int64).reshape(-1, 2)
    if pairs.shape[0] == 0:
        raise ValueError("dual proposal: no (detection, landmark) pair: nothing was detected")
    if pairs[:, 0].min() < 0 or pairs[:, 0].max() >= z.shape[0]:
        raise ValueError(f"dual proposal: pairs name detections outside z's {z.shape[0]} rows")
    if pairs[:, 1].min() < 0 or pairs[:, 1].max() >= landmarks.shape[0]:
        raise ValueError(f"dual proposal: pairs name landmarks outside the map's "
                         f"{landmarks.shape[0]}")
    if kind not in (RELATIVE_POSITION, RANGE_BEARING):
        raise ValueError(f"dual proposal: kind must be RELATIVE_POSITION (0) or RANGE_BEARING "
                         f"(1), got {kind}")
    try:
        root = np.linalg.cholesky(np.asarray(noise_cov, dtype=np.float64).reshape(2, 2))
    except np.linalg.LinAlgError:
        raise ValueError("dual proposal: noise_cov is not positive definite") from None
    return z, landmarks, pairs, root


def sample_dual_poses(
    n: int, z: ArrayLike, landmarks: ArrayLike, pairs: ArrayLike, kind: int,
    noise_cov: ArrayLike, rng: np.random.Generator,
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """``n`` dual poses ``(n, 3)`` (m, m, rad) and their validity ``(n,)`` (module docstring).

    Draws ``2 n`` uniforms and ``2 n`` normals from ``rng``.

    Args:
        z: ``(N, 2)`` measurements; landmarks: ``(L, 2)`` positions (m);
        pairs: ``(P, 2)`` from :func:`dual_pairs`; kind: the sensor's measurement model;
        noise_cov: ``(2, 2)`` R.
    """
    z, landmarks, pairs, root = _inputs(z, landmarks, pairs, kind, noise_cov)
    n = int(n)
    uniforms = rng.random((n, 2))
    normals = rng.standard_normal((n, 2))
    out = np.empty((n, 3))
    valid = np.empty(n, dtype=np.bool_)
    dual_sample_kernel(z, landmarks, pairs, int(kind), root, uniforms, normals, out, valid)
    return out, valid


def dual_log_density(
    poses: ArrayLike, z: ArrayLike, landmarks: ArrayLike, pairs: ArrayLike, kind: int,
    noise_cov: ArrayLike,
) -> NDArray[np.float64]:
    """``log q(x)`` ``(n,)`` of the dual proposal at ``poses`` ``(n, 3)`` (per m^2 rad)."""
    z, landmarks, pairs, root = _inputs(z, landmarks, pairs, kind, noise_cov)
    poses = np.ascontiguousarray(poses, dtype=np.float64).reshape(-1, 3)
    out = np.empty(poses.shape[0])
    dual_log_density_kernel(poses, z, landmarks, pairs, int(kind), root, out)
    return out
