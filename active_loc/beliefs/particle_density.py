"""A weighted particle set as a density: the kernel density estimate of mixture MCL.

Mixture MCL weights a pose ``x`` drawn from the measurement by the predicted belief's density
``bel_bar(x)``, which a particle set gives only through a density estimate:
``bel_bar(x) = sum_k w_k K_h(x - p_k)``, ``K_h`` a product of Gaussians of standard deviations
``h`` ``(3,)``, wrapped around the circle in heading. The default bandwidth is Silverman's
rule of thumb per dimension, ``h_d = sigma_d (4 / (d + 2) / n_eff)^(1 / (d + 4))`` with d = 3
and the weights' effective sample size, floored at ``min_bandwidth`` (a converged set has a
spread near 0).

The sum is evaluated binned (Wand 1994): the weights are spread linearly onto a grid of one
bandwidth per cell, convolved along each axis with Gaussian taps out to :data:`TRUNCATION`
bandwidths (circularly in heading), and read at a query by trilinear interpolation. Binning
and interpolation each add about a sixth of a cell's square to the kernel's variance, so the
taps are narrowed by that much. The result is a density (it integrates to 1) close to the
exact sum, and its cost does not depend on how far a kernel reaches: ``K`` to bin, the grid's
cells times the taps to convolve, 8 reads a query. Where a wide set with a narrow bandwidth
would need more than :data:`MAX_CELLS` cells, or the heading more than
:data:`MAX_HEADING_CELLS`, the cells grow, and the estimate is smoother than the sum.
Measured on 2 cores, 5000 particles spread over 20 m x 20 m and 1000 queries: 0.2 ms binned,
18 ms summed over every particle within reach (Silverman's bandwidth there is 1.7 m, so that
every query reaches most of the set).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

#: the kernel's support, in bandwidths
TRUNCATION = 4.0
#: the grid's cell side, in bandwidths
GRID_STEP = 1.0
#: the most grid cells (x cells x y cells x heading cells)
MAX_CELLS = 1 << 16
#: the fewest and the most heading cells
MIN_HEADING_CELLS = 8
MAX_HEADING_CELLS = 64


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
def _taps(bandwidth: float, step: float, reach: int) -> NDArray:
    """The Gaussian's ``2 reach + 1`` taps at ``step`` spacing, summing to 1."""
    taps = np.empty(2 * reach + 1)
    for i in range(2 * reach + 1):
        e = (i - reach) * step / bandwidth
        taps[i] = math.exp(-0.5 * e * e)
    return taps / taps.sum()


@numba.njit(cache=True, nogil=True)
def _narrowed(bandwidth: float, cell: float) -> float:
    """The taps' bandwidth that, with the variance ``cell^2 / 3`` that binning and reading
    add, makes the kernel's: ``sqrt(h^2 - cell^2 / 3)``, at least a quarter cell."""
    return math.sqrt(max(bandwidth * bandwidth - cell * cell / 3.0, (cell / 4.0) ** 2))


@numba.njit(cache=True, nogil=True, inline="always")
def _split(u: float) -> tuple[int, float]:
    """The grid node below ``u`` and the fraction of the way to the next."""
    i = math.floor(u)
    return int(i), u - i


@numba.njit(cache=True, nogil=True, inline="always")
def _x_value(mass: NDArray, taps: NDArray, r: int, cache: NDArray, done: NDArray, i: int,
             j: int, m: int) -> float:
    """The x-smoothed mass at node ``(i, j, m)``, computed on first use."""
    if not done[i, j, m]:
        acc = 0.0
        for a in range(max(-r, -i), min(r, mass.shape[0] - 1 - i) + 1):
            acc += taps[a + r] * mass[i + a, j, m]
        cache[i, j, m] = acc
        done[i, j, m] = True
    return cache[i, j, m]


@numba.njit(cache=True, nogil=True)
def _xy_value(mass: NDArray, taps_x: NDArray, rx: int, taps_y: NDArray, ry: int,
              x_cache: NDArray, x_done: NDArray, cache: NDArray, done: NDArray, i: int, j: int,
              m: int) -> float:
    """The x- then y-smoothed mass at node ``(i, j, m)``, computed on first use."""
    if not done[i, j, m]:
        acc = 0.0
        for b in range(max(-ry, -j), min(ry, mass.shape[1] - 1 - j) + 1):
            acc += taps_y[b + ry] * _x_value(mass, taps_x, rx, x_cache, x_done, i, j + b, m)
        cache[i, j, m] = acc
        done[i, j, m] = True
    return cache[i, j, m]


@numba.njit(cache=True, nogil=True)
def _smooth_at_queries(mass: NDArray, taps_x: NDArray, rx: int, taps_y: NDArray, ry: int,
                       taps_h: NDArray, rh: int, nodes: NDArray) -> NDArray:
    """The smoothed grid ``(nx, ny, nh)``, filled in only at the nodes ``(N, 3)`` that the
    queries read (and what those need), with exactly the sums of :func:`_smooth_all`."""
    nh = mass.shape[2]
    x_cache = np.empty_like(mass)
    y_cache = np.empty_like(mass)
    smooth = np.empty_like(mass)
    x_done = np.zeros(mass.shape, dtype=np.bool_)
    y_done = np.zeros(mass.shape, dtype=np.bool_)
    done = np.zeros(mass.shape, dtype=np.bool_)
    for n in range(nodes.shape[0]):
        i, j, m = nodes[n, 0], nodes[n, 1], nodes[n, 2]
        if done[i, j, m]:
            continue
        acc = 0.0
        for c in range(-rh, rh + 1):  # around the circle
            acc += taps_h[c + rh] * _xy_value(mass, taps_x, rx, taps_y, ry, x_cache, x_done,
                                              y_cache, y_done, i, j, (m + c) % nh)
        smooth[i, j, m] = acc
        done[i, j, m] = True
    return smooth


@numba.njit(cache=True, nogil=True)
def _smooth_all(mass: NDArray, taps_x: NDArray, rx: int, taps_y: NDArray, ry: int,
                taps_h: NDArray, rh: int) -> NDArray:
    """The grid ``(nx, ny, nh)`` convolved along x, y and (circularly) heading; ``mass`` is
    overwritten."""
    nx, ny, nh = mass.shape
    smooth = np.zeros((nx, ny, nh))
    for i in range(nx):
        for a in range(max(-rx, -i), min(rx, nx - 1 - i) + 1):
            c = taps_x[a + rx]
            for j in range(ny):
                for m in range(nh):
                    smooth[i, j, m] += c * mass[i + a, j, m]
    mass[:] = 0.0
    for i in range(nx):
        for j in range(ny):
            for b in range(max(-ry, -j), min(ry, ny - 1 - j) + 1):
                c = taps_y[b + ry]
                for m in range(nh):
                    mass[i, j, m] += c * smooth[i, j + b, m]
    ring = np.empty(nh + 2 * rh)  # one heading column, wrapped around at both ends
    for i in range(nx):
        for j in range(ny):
            for m in range(nh + 2 * rh):
                ring[m] = mass[i, j, (m - rh) % nh]
            for m in range(nh):
                acc = 0.0
                for c in range(2 * rh + 1):
                    acc += taps_h[c] * ring[m + c]
                smooth[i, j, m] = acc
    return smooth


@numba.njit(cache=True, nogil=True)
def binned_kde_kernel(
    particles: NDArray, weights: NDArray, bandwidth: NDArray, queries: NDArray, out: NDArray
) -> None:
    """``log bel_bar`` ``(Q,)`` at ``queries`` ``(Q, 3)`` (module docstring); particles
    ``(K, 3)`` with headings in ``[-pi, pi)``, weights ``(K,)`` summing to 1, ``bandwidth``
    ``(3,)`` with a heading bandwidth of at most pi.

    The convolved grid is needed only at the 8 nodes around each query: where the queries
    are few against the grid's cells, only those nodes (and the sums they need) are computed,
    with the same sums in the same order, so both ways give the same numbers."""
    k = particles.shape[0]
    x0 = y0 = np.inf
    x1 = y1 = -np.inf
    for i in range(k):
        x0 = min(x0, particles[i, 0])
        x1 = max(x1, particles[i, 0])
        y0 = min(y0, particles[i, 1])
        y1 = max(y1, particles[i, 1])
    nh = min(MAX_HEADING_CELLS,
             max(MIN_HEADING_CELLS, math.floor(2.0 * math.pi / (GRID_STEP * bandwidth[2]))))
    dh = 2.0 * math.pi / nh
    dx = GRID_STEP * bandwidth[0]
    dy = GRID_STEP * bandwidth[1]
    while True:  # grow the cells until the grid fits
        rx = math.ceil(TRUNCATION * bandwidth[0] / dx)
        ry = math.ceil(TRUNCATION * bandwidth[1] / dy)
        nx = int((x1 - x0) / dx) + 2 + 2 * rx
        ny = int((y1 - y0) / dy) + 2 + 2 * ry
        if nx * ny * nh <= MAX_CELLS:
            break
        grow = 1.05 * math.sqrt(nx * ny * nh / MAX_CELLS)
        dx *= grow
        dy *= grow
    rh = math.ceil(TRUNCATION * bandwidth[2] / dh)
    gx = x0 - rx * dx  # the grid's first node; nodes at gx + i dx, and heading -pi + (j + 1/2) dh
    gy = y0 - ry * dy
    mass = np.zeros((nx, ny, nh))
    for i in range(k):  # linear binning
        ix, fx = _split((particles[i, 0] - gx) / dx)
        iy, fy = _split((particles[i, 1] - gy) / dy)
        ih, fh = _split((particles[i, 2] + math.pi) / dh - 0.5)
        h0 = ih % nh
        h1 = (ih + 1) % nh
        for a in range(2):
            wa = weights[i] * (fx if a else 1.0 - fx)
            for b in range(2):
                wb = wa * (fy if b else 1.0 - fy)
                mass[ix + a, iy + b, h0] += wb * (1.0 - fh)
                mass[ix + a, iy + b, h1] += wb * fh
    taps_x = _taps(_narrowed(bandwidth[0], dx), dx, rx)
    taps_y = _taps(_narrowed(bandwidth[1], dy), dy, ry)
    taps_h = _taps(_narrowed(bandwidth[2], dh), dh, rh)
    q_count = queries.shape[0]
    nodes = np.empty((8 * q_count, 3), dtype=np.int64)  # the grid nodes each query reads
    n_nodes = 0
    for q in range(q_count):
        u = (queries[q, 0] - gx) / dx
        v = (queries[q, 1] - gy) / dy
        if 0.0 <= u < nx - 1 and 0.0 <= v < ny - 1:
            ih = _split((queries[q, 2] + math.pi) / dh - 0.5)[0]
            for a in range(2):
                for b in range(2):
                    for c in range(2):
                        nodes[n_nodes, 0] = int(u) + a
                        nodes[n_nodes, 1] = int(v) + b
                        nodes[n_nodes, 2] = (ih + c) % nh
                        n_nodes += 1
    # the sums a node needs at most, read lazily, against every cell's three convolutions
    per_node = (2 * rh + 1) * (1 + (2 * ry + 1) * (1 + (2 * rx + 1)))
    if n_nodes * per_node < nx * ny * nh * (2 * (rx + ry + rh) + 3):
        smooth = _smooth_at_queries(mass, taps_x, rx, taps_y, ry, taps_h, rh, nodes[:n_nodes])
    else:
        smooth = _smooth_all(mass, taps_x, rx, taps_y, ry, taps_h, rh)
    log_cell = math.log(dx * dy * dh)
    for q in range(q_count):
        u = (queries[q, 0] - gx) / dx
        v = (queries[q, 1] - gy) / dy
        if not (0.0 <= u < nx - 1 and 0.0 <= v < ny - 1):
            out[q] = -np.inf
            continue
        ix, fx = _split(u)
        iy, fy = _split(v)
        ih, fh = _split((queries[q, 2] + math.pi) / dh - 0.5)
        h0 = ih % nh
        h1 = (ih + 1) % nh
        acc = 0.0
        for a in range(2):
            wa = fx if a else 1.0 - fx
            for b in range(2):
                wb = wa * (fy if b else 1.0 - fy)
                acc += wb * ((1.0 - fh) * smooth[ix + a, iy + b, h0]
                             + fh * smooth[ix + a, iy + b, h1])
        out[q] = math.log(acc) - log_cell if acc > 0.0 else -np.inf


def kde_log_density(
    particles: ArrayLike, weights: ArrayLike, bandwidth: ArrayLike, queries: ArrayLike
) -> NDArray[np.float64]:
    """``log bel_bar(x)`` ``(Q,)`` (per m^2 rad) of the weighted set ``(K, 3)``, ``(K,)`` with
    the Gaussian kernel of ``bandwidth`` ``(3,)`` (m, m, rad), at ``queries`` ``(Q, 3)``,
    binned (module docstring)."""
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
    binned_kde_kernel(p, w, np.minimum(h, np.array([np.inf, np.inf, np.pi])), qs, out)
    return out
