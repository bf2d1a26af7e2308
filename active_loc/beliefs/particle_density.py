"""A weighted particle set as a density: the kernel density estimate of mixture MCL.

Mixture MCL weights a pose ``x`` drawn from the measurement by the predicted belief's density
``bel_bar(x)``, which a particle set gives only through a kernel density estimate:
``bel_bar(x) = sum_k w_k K_h(x - p_k)``, ``K_h`` a Gaussian of standard deviations ``h``
``(3,)``, the heading residual wrapped to ``[-pi, pi)``. The default bandwidth is Silverman's
rule of thumb per dimension, ``h_d = sigma_d (4 / (d + 2) / n_eff)^(1 / (d + 4))`` with d = 3
and the weights' effective sample size, floored at ``min_bandwidth`` (a converged set has a
spread near 0).

The kernel is the Gaussian truncated to the ball of ``TRUNCATION`` bandwidths (where it has
fallen to 3.4e-4 of its peak) and renormalized, so that its support is compact and the sum
is exact over the particles near a query: particles are sorted into cells of
``TRUNCATION / 2`` bandwidths, and a query visits the 5 x 5 x 5 cells around its own, each
found by binary search in the sorted cell keys. A query costs 125 searches plus the particles
near it, not K (measured on 2 cores, 500 queries: 12 ms on 5000 particles spread uniformly
over 20 m x 20 m, where Silverman's bandwidth is 1.7 m and a query reaches a tenth of the
set; 2.8 ms on 500 particles of a converged set). The density integrates to 1 when
``TRUNCATION h_theta <= pi`` (a wider heading kernel overlaps itself around the circle;
mixture MCL normalizes its weights anyway).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

#: kernel support, in bandwidths
TRUNCATION = 4.0
#: cells per axis of the search window on either side of the query's cell
_REACH = 2
_LOG_NORM_1D = -0.5 * math.log(2.0 * math.pi)
#: log of the standard 3-D Gaussian's mass inside the ball of radius TRUNCATION
_LOG_BALL_MASS = math.log(
    math.erf(TRUNCATION / math.sqrt(2.0))
    - math.sqrt(2.0 / math.pi) * TRUNCATION * math.exp(-0.5 * TRUNCATION**2)
)


def silverman_bandwidth(
    particles: ArrayLike, weights: ArrayLike, min_bandwidth: ArrayLike
) -> NDArray[np.float64]:
    """Silverman's bandwidth ``(3,)`` (m, m, rad) of a weighted set ``(K, 3)``, ``(K,)``
    (weights summing to 1), floored at ``min_bandwidth`` ``(3,)``."""
    p = np.asarray(particles, dtype=np.float64).reshape(-1, 3)
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    mean_xy = w @ p[:, :2]
    var_xy = w @ (p[:, :2] - mean_xy) ** 2
    # the heading's circular spread: sqrt(-2 log R), R the mean resultant length
    resultant = math.hypot(float(w @ np.cos(p[:, 2])), float(w @ np.sin(p[:, 2])))
    heading_std = math.sqrt(-2.0 * math.log(min(max(resultant, 1e-300), 1.0)))  # R <= 1
    sigma = np.array([math.sqrt(var_xy[0]), math.sqrt(var_xy[1]), min(heading_std, math.pi)])
    n_eff = 1.0 / float(w @ w)
    factor = (4.0 / (5.0 * n_eff)) ** (1.0 / 7.0)
    return np.maximum(sigma * factor, np.asarray(min_bandwidth, dtype=np.float64))


@numba.njit(cache=True, nogil=True)
def _cell(value: float, origin: float, size: float) -> int:
    return math.floor((value - origin) / size)


@numba.njit(cache=True, nogil=True)
def _key(ix: int, iy: int, ih: int, ny: int, nh: int) -> int:
    return (ix * ny + iy) * nh + ih


@numba.njit(cache=True, nogil=True)
def kde_log_density_kernel(
    particles: NDArray, weights: NDArray, bandwidth: NDArray, queries: NDArray, out: NDArray
) -> None:
    """``log bel_bar`` ``(Q,)`` at ``queries`` ``(Q, 3)`` (module docstring); particles
    ``(K, 3)`` with headings in ``[-pi, pi)``, weights ``(K,)`` summing to 1."""
    k = particles.shape[0]
    size = np.empty(3)
    for d in range(3):
        size[d] = bandwidth[d] * TRUNCATION / _REACH
    x0 = np.inf
    y0 = np.inf
    x1 = -np.inf
    y1 = -np.inf
    for i in range(k):
        x0 = min(x0, particles[i, 0])
        y0 = min(y0, particles[i, 1])
        x1 = max(x1, particles[i, 0])
        y1 = max(y1, particles[i, 1])
    nx = _cell(x1, x0, size[0]) + 1
    ny = _cell(y1, y0, size[1]) + 1
    # heading cells wrap: at least one, and no more than fit in a turn
    nh = max(1, math.floor(2.0 * math.pi / size[2]))
    h_size = 2.0 * math.pi / nh
    keys = np.empty(k, dtype=np.int64)
    for i in range(k):
        ih = min(_cell(particles[i, 2], -math.pi, h_size), nh - 1)
        keys[i] = _key(_cell(particles[i, 0], x0, size[0]), _cell(particles[i, 1], y0, size[1]),
                       ih, ny, nh)
    order = np.argsort(keys)
    sorted_keys = keys[order]
    log_norm = (3.0 * _LOG_NORM_1D - math.log(bandwidth[0] * bandwidth[1] * bandwidth[2])
                - _LOG_BALL_MASS)
    cutoff = TRUNCATION * TRUNCATION
    reach_h = min(_REACH, nh // 2)
    for q in range(queries.shape[0]):
        qx = queries[q, 0]
        qy = queries[q, 1]
        qh = queries[q, 2]
        cx = _cell(qx, x0, size[0])
        cy = _cell(qy, y0, size[1])
        ch = min(_cell(qh - 2.0 * math.pi * math.floor((qh + math.pi) / (2.0 * math.pi)),
                       -math.pi, h_size), nh - 1)
        total = 0.0
        for ix in range(max(cx - _REACH, 0), min(cx + _REACH, nx - 1) + 1):
            for iy in range(max(cy - _REACH, 0), min(cy + _REACH, ny - 1) + 1):
                for dh in range(-reach_h, reach_h + 1):
                    if nh > 1 and 2 * reach_h + 1 > nh and dh == reach_h and nh % 2 == 0:
                        continue  # the window wrapped onto itself: visit each cell once
                    ih = (ch + dh) % nh
                    key = _key(ix, iy, ih, ny, nh)
                    j = np.searchsorted(sorted_keys, key)
                    while j < k and sorted_keys[j] == key:
                        p = order[j]
                        j += 1
                        ex = (qx - particles[p, 0]) / bandwidth[0]
                        ey = (qy - particles[p, 1]) / bandwidth[1]
                        r = qh - particles[p, 2]
                        r = r - 2.0 * math.pi * math.floor((r + math.pi) / (2.0 * math.pi))
                        eh = r / bandwidth[2]
                        s = ex * ex + ey * ey + eh * eh
                        if s <= cutoff:
                            total += weights[p] * math.exp(-0.5 * s)
        out[q] = math.log(total) + log_norm if total > 0.0 else -np.inf


def kde_log_density(
    particles: ArrayLike, weights: ArrayLike, bandwidth: ArrayLike, queries: ArrayLike
) -> NDArray[np.float64]:
    """``log bel_bar(x)`` ``(Q,)`` (per m^2 rad) of the weighted set ``(K, 3)``, ``(K,)`` with
    the Gaussian kernel of ``bandwidth`` ``(3,)`` (m, m, rad), at ``queries`` ``(Q, 3)``."""
    p = np.ascontiguousarray(particles, dtype=np.float64).reshape(-1, 3).copy()
    w = np.ascontiguousarray(weights, dtype=np.float64).reshape(-1)
    h = np.ascontiguousarray(bandwidth, dtype=np.float64).reshape(-1)
    qs = np.ascontiguousarray(queries, dtype=np.float64).reshape(-1, 3)
    if w.shape[0] != p.shape[0] or p.shape[0] == 0:
        raise ValueError(f"kde_log_density: {p.shape[0]} particles but {w.shape[0]} weights "
                         f"(at least one of each)")
    if h.shape != (3,) or not np.all(np.isfinite(h)) or np.any(h <= 0.0):
        raise ValueError(f"kde_log_density: bandwidth must be 3 finite numbers > 0, got "
                         f"{bandwidth}")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(w)) and np.all(np.isfinite(qs))):
        raise ValueError("kde_log_density: particles, weights and queries must be finite")
    p[:, 2] = (p[:, 2] + np.pi) % (2.0 * np.pi) - np.pi
    out = np.empty(qs.shape[0])
    kde_log_density_kernel(p, w, np.minimum(h, np.array([np.inf, np.inf, np.pi])), qs, out)
    return out
