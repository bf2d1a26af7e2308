"""Statistics of weighted particle sets, as numba kernels over plain arrays.

A particle set is ``particles`` ``(K, 3)`` (x m, y m, theta rad in [-pi, pi)) with log-weights
``log_w`` ``(K,)``, not necessarily normalized; ``-inf`` marks a particle of weight zero (a pose
inside a wall, say). Every kernel normalizes with a max-shifted log-sum-exp, so weights as small
as ``exp(-1e300)`` neither underflow to a division by zero nor give NaN; a set whose weights are
all ``-inf`` is treated as uniform by the moment kernels (the filter re-initializes such a set
before anyone asks, but a statistic must still never be NaN).

* :func:`logsumexp`, :func:`normalize_log_weights`, :func:`normalized_weights`;
* :func:`summarize_particles`: what a step reads of a set in one blocked pass: the normalized
  weights, the mean (heading by ``atan2`` of the weighted sines and cosines, the circular mean),
  the covariance (heading residuals wrapped about that mean), the entropy and the effective
  sample size ``1 / sum w^2``;
* :func:`histogram_entropy`: the belief entropy of :mod:`active_loc.beliefs.entropy` for a
  particle set, ``H = -sum_b p_b log p_b + log(dx dy dtheta)`` over the occupied cells of a pose
  grid, in nats (so it is comparable with the Gaussian differential entropy);
* :func:`kld_limit`: the particle count of KLD sampling (Fox 2003) for ``k`` occupied bins, with
  the Wilson-Hilferty approximation of the chi-square quantile as in AMCL's
  ``pf_resample_limit``;
* :func:`assign_bins`: compact ids of the occupied pose bins through a small open-addressing
  hash table (the entropy and KLD sampling both count bins); :func:`dense_binned_entropy`
  counts them on a dense grid over the map instead, when one fits in memory.

Pose bins are ``(floor(x / dx), floor(y / dy), floor((theta + pi) / dtheta))``: anchored at the
map-frame origin and at heading ``-pi``, so that ``dtheta = 2 pi / n`` tiles the circle exactly.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from active_loc.parallel import parallel_twin

#: the default entropy cells (dx m, dy m, dtheta rad)
ENTROPY_BINS = (0.25, 0.25, 2.0 * np.pi / 36.0)


@numba.njit(cache=True, nogil=True)
def logsumexp(a: NDArray) -> float:
    """``log(sum(exp(a)))`` of a 1-D array, shifted by its maximum; ``-inf`` when every entry
    is ``-inf`` (or the array is empty)."""
    m = -np.inf
    for v in a:
        if v > m:
            m = v
    if m == -np.inf or m == np.inf:
        return m
    s = 0.0
    for v in a:
        s += np.exp(v - m)
    return m + np.log(s)


@numba.njit(cache=True, nogil=True)
def normalize_log_weights(log_w: NDArray) -> float:
    """Normalize ``log_w`` ``(K,)`` in place so that ``sum(exp(log_w)) = 1``.

    Returns:
        The log normalizer ``logsumexp(log_w)`` before normalization. When it is ``-inf`` (every
        weight zero) the array is left untouched: the caller decides how to recover.
    """
    lse = logsumexp(log_w)
    if lse == -np.inf:
        return lse
    for i in range(log_w.shape[0]):
        log_w[i] -= lse
    return lse


@numba.njit(cache=True, nogil=True)
def normalized_weights(log_w: NDArray, out: NDArray) -> None:
    """Linear weights ``(K,)`` summing to one into ``out``; uniform if every weight is zero."""
    k = log_w.shape[0]
    lse = logsumexp(log_w)
    if lse == -np.inf:
        for i in range(k):
            out[i] = 1.0 / k
        return
    for i in range(k):
        out[i] = np.exp(log_w[i] - lse)


# --- a hash table of integer pose bins ------------------------------------------------------------


@numba.njit(cache=True, nogil=True)
def table_size(n: int) -> int:
    """Size of a hash table for up to ``n`` distinct bins: a power of two >= 2 n, so that
    linear probing stays short."""
    size = 16
    while size < 2 * n:
        size *= 2
    return size


@numba.njit(cache=True, nogil=True, inline="always")
def pose_bin(x: float, y: float, theta: float, dx: float, dy: float, dth: float) -> tuple:
    """Integer bin ``(ix, iy, ith)`` of a pose on the grid of cells ``(dx, dy, dth)``."""
    return (
        np.int64(np.floor(x / dx)),
        np.int64(np.floor(y / dy)),
        np.int64(np.floor((theta + np.pi) / dth)),
    )


@numba.njit(cache=True, nogil=True, inline="always")
def bin_hash(b0: int, b1: int, b2: int, mask: int) -> int:
    """First probe slot of bin ``(b0, b1, b2)`` in a table of size ``mask + 1``."""
    # int64 products wrap around in numba: fine for a hash
    return ((b0 * 73856093) ^ (b1 * 19349663) ^ (b2 * 83492791)) & mask


# The probing loops are written out in each kernel rather than in a helper taking the table
# arrays: passing arrays to a helper per particle costs numba a reference-count update each
# time, which made these loops several times slower.


@numba.njit(cache=True, nogil=True)
def assign_bins(particles: NDArray, dx: float, dy: float, dth: float, ids: NDArray) -> int:
    """Compact bin ids ``ids`` ``(K,)`` of poses ``(K, 3)`` on the grid of cells
    ``(dx, dy, dth)``, numbered 0, 1, ... in order of first appearance; returns the number of
    distinct bins."""
    k = particles.shape[0]
    size = table_size(k)
    mask = size - 1
    keys = np.empty((size, 3), dtype=np.int64)
    slot_id = np.full(size, -1, dtype=np.int64)
    n_bins = 0
    for i in range(k):
        b0, b1, b2 = pose_bin(particles[i, 0], particles[i, 1], particles[i, 2], dx, dy, dth)
        j = bin_hash(b0, b1, b2, mask)
        while slot_id[j] >= 0 and not (keys[j, 0] == b0 and keys[j, 1] == b1 and keys[j, 2] == b2):
            j = (j + 1) & mask
        if slot_id[j] < 0:
            slot_id[j] = n_bins
            keys[j, 0] = b0
            keys[j, 1] = b1
            keys[j, 2] = b2
            n_bins += 1
        ids[i] = slot_id[j]
    return n_bins


@numba.njit(cache=True, nogil=True)
def histogram_entropy(
    particles: NDArray, log_w: NDArray, dx: float, dy: float, dth: float
) -> float:
    """Entropy (nats) of the weighted particles binned on the pose grid of cells
    ``(dx m, dy m, dth rad)``: ``-sum_b p_b log p_b + log(dx dy dth)``.

    One bin holding everything gives ``log(dx dy dth)``; a uniform density over a region of
    volume V gives about ``log V`` when there are many particles per cell. With K particles
    the value cannot exceed ``log K + log(dx dy dth)``, so a sparse cloud under-reports the
    entropy of a very broad belief.
    """
    w = np.empty(particles.shape[0])
    normalized_weights(log_w, w)
    return binned_entropy(particles, w, dx, dy, dth)


@numba.njit(cache=True, nogil=True)
def kld_limit(k: int, min_particles: int, max_particles: int, err: float, z: float) -> int:
    """Particle count that bounds the KL divergence for ``k`` occupied bins (Fox 2003).

    ``n = (k - 1) / (2 err) * (1 - 2 / (9 (k - 1)) + sqrt(2 / (9 (k - 1))) z)^3``, the
    Wilson-Hilferty approximation of the chi-square quantile, as in AMCL's
    ``pf_resample_limit``; ``z`` is the upper standard normal quantile used as is (AMCL's
    ``kld_z``). Clipped to ``[min_particles, max_particles]``. For ``k <= 1`` Fox's bound is
    0, so the count is ``min_particles`` (AMCL returns ``max_particles`` there, a guard against
    dividing by zero that keeps a fully concentrated belief at the maximum).
    """
    if k <= 1:
        return min_particles
    km1 = float(k - 1)
    b = 2.0 / (9.0 * km1)
    x = 1.0 - b + np.sqrt(b) * z
    n = np.ceil(km1 / (2.0 * err) * x * x * x)
    if n < min_particles:
        return min_particles
    if n > max_particles:
        return max_particles
    return int(n)


# --- everything a step reads of a particle set, in one kernel -----------------------------------

#: particles per block of :func:`summarize_particles`: the sums are taken per block and the
#: blocks added in order, so that the serial and parallel twins give the same numbers
SUMMARY_BLOCK = 2048


@numba.njit(cache=True, nogil=True)
def _summary_blocks(
    particles: NDArray, log_w: NDArray, shift: float, weights: NDArray, partial: NDArray
) -> None:
    """Per block ``i`` of :data:`SUMMARY_BLOCK` particles: ``weights = exp(log_w - shift)``
    (unnormalized) and ``partial[i]`` = the sums of w, w^2, w x, w y, w sin(theta),
    w cos(theta)."""
    k = particles.shape[0]
    n_blocks = partial.shape[0]
    for i in numba.prange(n_blocks):
        s0 = s1 = sx = sy = ss = sc = 0.0
        for j in range(i * SUMMARY_BLOCK, min(k, (i + 1) * SUMMARY_BLOCK)):
            w = np.exp(log_w[j] - shift)
            weights[j] = w
            if w == 0.0:
                continue
            s0 += w
            s1 += w * w
            sx += w * particles[j, 0]
            sy += w * particles[j, 1]
            ss += w * np.sin(particles[j, 2])
            sc += w * np.cos(particles[j, 2])
        partial[i, 0] = s0
        partial[i, 1] = s1
        partial[i, 2] = sx
        partial[i, 3] = sy
        partial[i, 4] = ss
        partial[i, 5] = sc


@numba.njit(cache=True, nogil=True)
def _covariance_blocks(
    particles: NDArray, weights: NDArray, mean: NDArray, partial: NDArray
) -> None:
    """Per block ``i``: ``partial[i]`` = the weighted sums of the residual products r0 r0,
    r0 r1, r0 r2, r1 r1, r1 r2, r2 r2 about ``mean`` (heading residual wrapped)."""
    k = particles.shape[0]
    for i in numba.prange(partial.shape[0]):
        c00 = c01 = c02 = c11 = c12 = c22 = 0.0
        for j in range(i * SUMMARY_BLOCK, min(k, (i + 1) * SUMMARY_BLOCK)):
            w = weights[j]
            if w == 0.0:
                continue
            r0 = particles[j, 0] - mean[0]
            r1 = particles[j, 1] - mean[1]
            r2 = particles[j, 2] - mean[2]
            if not -np.pi <= r2 < np.pi:
                r2 = (r2 + np.pi) % (2.0 * np.pi) - np.pi
            c00 += w * r0 * r0
            c01 += w * r0 * r1
            c02 += w * r0 * r2
            c11 += w * r1 * r1
            c12 += w * r1 * r2
            c22 += w * r2 * r2
        partial[i, 0] = c00
        partial[i, 1] = c01
        partial[i, 2] = c02
        partial[i, 3] = c11
        partial[i, 4] = c12
        partial[i, 5] = c22


_summary_blocks_parallel = parallel_twin(_summary_blocks)
_covariance_blocks_parallel = parallel_twin(_covariance_blocks)


def _weight_sums(
    particles: NDArray, log_w: NDArray, parallel: bool, weights: NDArray
) -> tuple[NDArray, NDArray]:
    """The normalized weights ``(K,)`` into ``weights``; returns the per-block scratch
    ``(blocks, 6)`` and the sums of :func:`_summary_blocks` over the blocks in order
    (unnormalized). Every weight zero: uniform weights."""
    k = particles.shape[0]
    n_blocks = (k + SUMMARY_BLOCK - 1) // SUMMARY_BLOCK
    partial = np.empty((n_blocks, 6))
    shift = float(log_w.max()) if k else -np.inf
    if shift == -np.inf:
        log_w = np.zeros(k)
        shift = 0.0
    (_summary_blocks_parallel if parallel else _summary_blocks)(
        particles, log_w, shift, weights, partial
    )
    sums = partial.sum(axis=0)  # the blocks in order (a new array: partial is reused)
    weights /= sums[0]
    return partial, sums


def summary_weights(
    particles: NDArray, log_w: NDArray, parallel: bool, weights: NDArray
) -> None:
    """The normalized weights ``(K,)`` of :func:`summarize_particles` alone, into ``weights``
    (the same numbers, without the covariance and entropy passes)."""
    _weight_sums(particles, log_w, parallel, weights)


def summarize_particles(
    particles: NDArray, log_w: NDArray, bins: NDArray, parallel: bool,
    weights: NDArray, mean: NDArray, cov: NDArray,
    grid: tuple[NDArray, NDArray, NDArray] | None = None,
) -> tuple[float, float]:
    """What a step reads of the particle set ``(K, 3)`` with log-weights ``(K,)``, in two
    passes of exp, sin and cos instead of one per statistic.

    Writes the normalized weights ``(K,)``, the mean ``(3,)`` (circular in theta) and the
    covariance ``(3, 3)`` (heading residuals wrapped) as the plug-in estimates define them
    (arithmetic in x and y, ``atan2(sum w sin, sum w cos)`` in theta, so that a cloud across
    the +-pi seam averages to about pi, not 0; ``sum_k w_k r_k r_k^T``, singular when every
    particle sits at one pose); returns ``(entropy, ess)``: the histogram entropy
    on the pose grid ``bins`` ``(dx m, dy m, dtheta rad)`` (nats, as
    :func:`histogram_entropy`) and Kish's effective sample size. ``parallel`` runs the block
    sums on numba's threads (the same numbers). Every weight zero: uniform weights.
    """
    partial, sums = _weight_sums(particles, log_w, parallel, weights)
    total = sums[0]
    mean[0] = sums[2] / total
    mean[1] = sums[3] / total
    heading = math.atan2(sums[4], sums[5])
    mean[2] = heading if heading < math.pi else -math.pi
    (_covariance_blocks_parallel if parallel else _covariance_blocks)(
        particles, weights, mean, partial
    )
    c = partial.sum(axis=0)
    cov[0, 0], cov[0, 1], cov[0, 2] = c[0], c[1], c[2]
    cov[1, 0], cov[1, 1], cov[1, 2] = c[1], c[3], c[4]
    cov[2, 0], cov[2, 1], cov[2, 2] = c[2], c[4], c[5]
    entropy = math.nan
    if grid is not None:
        entropy = dense_binned_entropy(particles, weights, bins[0], bins[1], bins[2], *grid)
    if math.isnan(entropy):
        entropy = binned_entropy(particles, weights, bins[0], bins[1], bins[2])
    return float(entropy), float(total * total / sums[1])


@numba.njit(cache=True, nogil=True)
def binned_entropy(
    particles: NDArray, weights: NDArray, dx: float, dy: float, dth: float
) -> float:
    """:func:`histogram_entropy` from normalized linear ``weights`` ``(K,)``."""
    k = particles.shape[0]
    ids = np.empty(k, dtype=np.int64)
    n_bins = assign_bins(particles, dx, dy, dth, ids)
    acc = np.zeros(n_bins)
    for i in range(k):
        acc[ids[i]] += weights[i]
    h = 0.0
    for b in range(n_bins):
        p = acc[b]
        if p > 0.0:
            h -= p * np.log(p)
    return h + np.log(dx * dy * dth)


#: the most cells a dense entropy grid may have (float64 each): beyond it, the hash table
MAX_DENSE_BINS = 4_000_000


@numba.njit(cache=True, nogil=True)
def dense_binned_entropy(
    particles: NDArray, weights: NDArray, dx: float, dy: float, dth: float, origin: NDArray,
    acc: NDArray, touched: NDArray,
) -> float:
    """:func:`binned_entropy` on a dense grid of bins instead of a hash table: the same
    number (the bins are summed in the same order of first appearance), without probing.

    Args:
        origin: ``(5,)`` int64: the bin indices ``(ix0, iy0)`` of the grid's first cell and its
            size ``(nx, ny, nh)``.
        acc: ``(nx ny nh,)`` zeros (left as zeros).
        touched: ``(>= K,)`` int64 scratch.

    Returns:
        The entropy (nats), or NaN when a particle of positive weight lies off the grid (the
        caller then takes the hash table).
    """
    ix0, iy0, nx, ny, nh = origin[0], origin[1], origin[2], origin[3], origin[4]
    n_bins = 0
    off_grid = False
    for i in range(particles.shape[0]):
        w = weights[i]
        if w == 0.0:
            continue
        b0, b1, b2 = pose_bin(particles[i, 0], particles[i, 1], particles[i, 2], dx, dy, dth)
        ix = b0 - ix0
        iy = b1 - iy0
        if ix < 0 or iy < 0 or b2 < 0 or ix >= nx or iy >= ny or b2 >= nh:
            off_grid = True
            break
        j = (ix * ny + iy) * nh + b2
        if acc[j] == 0.0:
            touched[n_bins] = j
            n_bins += 1
        acc[j] += w
    h = 0.0
    for t in range(n_bins):
        j = touched[t]
        p = acc[j]
        acc[j] = 0.0
        if p > 0.0:
            h -= p * np.log(p)
    if off_grid:
        return np.nan
    return h + np.log(dx * dy * dth)
