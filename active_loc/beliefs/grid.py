"""Markov localization on a pose grid (the chapter's Algorithm 1), batch-first.

The belief is a histogram ``prob`` ``(B, X, Y, H)`` over the cells ``(ix, iy)`` of a map and
``H`` heading bins: B beliefs, one per map (``free`` ``(B, X, Y)`` bool, True = free cell,
indexed ``[ix, iy]``: the transpose of :attr:`OccupancyGrid.values
<active_loc.maps.occupancy.OccupancyGrid.values>`). Heading bin ``h`` is the heading
``h 2 pi / H`` (plus the map's yaw); cell ``(ix, iy)`` is the map's grid cell, of side
``cell_size`` m. Occupied cells never hold mass.

One step of Algorithm 1:

1. **Prediction** (:meth:`GridBelief.predict`), ``bel_bar(x') = sum_x p(x' | u, x) bel(x)``,
   with a map-aware motion model given as a per-heading integer shift: a robot in heading bin
   ``h`` is commanded to move by ``shift[h] = (dx, dy)`` cells and turn by ``turn`` bins. An
   optional :class:`MotionKernel` adds noise: outcome ``k`` (probability ``w_k``) adds
   ``(dx_k, dy_k, dh_k)`` to the commanded motion. Where the straight path of a translation
   crosses an occupied cell or leaves the grid, the translation is blocked and the mass stays
   in its cell (it still turns), as a blocked robot does
   (:func:`active_loc.motion.move_within_bounds`). A motion of a fraction of a cell, as a
   robot's step usually is, goes through :meth:`GridBelief.predict_fractional` (or
   :meth:`GridBelief.predict_unicycle`): a kernel per heading bin that spreads the mass over
   the neighbouring shifts and heading bins with the exact weights of the piecewise-constant
   density under the motion and its Gaussian noise (:mod:`active_loc.beliefs.grid_motion`),
   with the same blocking rule per outcome (:meth:`GridBelief.predict_per_heading`).
2. **Correction** (:meth:`GridBelief.update`), ``bel(x) = eta p(z | x) bel_bar(x)``, with a
   per-pose likelihood array ``(B, X, Y, H)`` from any sensor model: the maze depth sensor
   (:class:`~active_loc.sensors.depth.DepthSensor`), or the lidar and landmark models evaluated
   at :meth:`GridBelief.cell_poses` (log-likelihoods go through :meth:`GridBelief.update_log`).
   When no pose explains the measurement (total mass 0) the member is re-initialized uniform
   over its free poses instead of dividing by zero.

Entropy (nats) is the histogram entropy plus ``log(cell volume)``, the cell volume being
``cell_size^2 * 2 pi / H`` (m^2 rad), as :mod:`active_loc.beliefs.entropy` defines it for every
filter. For the maze (1 m cells, 4 headings) that is ``log(pi / 2)``.

:meth:`GridBelief.moments` gives the mean (circular in heading) and the covariance of that
density, the cell's own spread included. The loops are numba kernels over plain arrays; a
21 x 21 x 4 belief predicts or updates in a few microseconds.
"""

from __future__ import annotations

import copy as _copy
import math
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from active_loc.beliefs.grid_motion import (
    checked_fractional_kernels,
    noise_in_cells,
    unicycle_shifts,
)
from active_loc.maps.occupancy import FREE, OccupancyGrid
from active_loc.parallel import parallel_twin, pick

# --- kernels ---------------------------------------------------------------------------------


@numba.njit(cache=True, nogil=True)
def _path_free(free: NDArray, b: int, x: int, y: int, dx: int, dy: int) -> bool:
    """Whether every cell of the straight path from ``(x, y)`` to ``(x + dx, y + dy)`` (the
    start excluded, cells rounded from the segment at ``max(|dx|, |dy|)`` evenly spaced
    points) is inside the grid and free."""
    n = max(abs(dx), abs(dy))
    nx = free.shape[1]
    ny = free.shape[2]
    for i in range(1, n + 1):
        # floor(d i / n + 1/2) in integers (floor division)
        cx = x + (2 * dx * i + n) // (2 * n)
        cy = y + (2 * dy * i + n) // (2 * n)
        if cx < 0 or cx >= nx or cy < 0 or cy >= ny or not free[b, cx, cy]:
            return False
    return True


@numba.njit(cache=True, nogil=True, inline="always")
def _stays(free: NDArray, b: int, x: int, y: int, dx: int, dy: int) -> bool:
    """Whether mass of cell ``(x, y)`` commanded to move by ``(dx, dy)`` cells stays where it
    is: no move, or a blocked one (one step: the target cell; longer: :func:`_path_free`)."""
    if dx == 0 and dy == 0:
        return True
    if abs(dx) <= 1 and abs(dy) <= 1:
        tx = x + dx
        ty = y + dy
        return not (0 <= tx < free.shape[1] and 0 <= ty < free.shape[2] and free[b, tx, ty])
    return not _path_free(free, b, x, y, dx, dy)


@numba.njit(cache=True, nogil=True)
def predict_member(
    prob: NDArray,
    free: NDArray,
    b: int,
    shift: NDArray,
    turn: int,
    offsets: NDArray,
    weights: NDArray,
    out: NDArray,
) -> None:
    """Map-aware prediction of member ``b``: ``out[b] = sum_x p(x' | u, x) prob[b](x)``.

    Args:
        prob: ``(B, X, Y, H)`` belief before the motion.
        free: ``(B, X, Y)`` bool, True = free cell.
        b: the member.
        shift: ``(H, 2)`` int64 commanded translation (cells) per heading bin.
        turn: commanded turn (heading bins).
        offsets: ``(K, 3)`` int64 noise outcomes ``(dx, dy, dh)`` added to the command.
        weights: ``(K,)`` probabilities of the outcomes.
        out: ``(B, X, Y, H)``: member ``b`` is overwritten with the predicted belief.
    """
    _, nx, ny, nh = prob.shape
    nk = offsets.shape[0]
    # per heading and outcome: the translation and the new heading bin
    move_x = np.empty((nh, nk), dtype=np.int64)
    move_y = np.empty((nh, nk), dtype=np.int64)
    new_h = np.empty((nh, nk), dtype=np.int64)
    out[b] = 0.0
    for h in range(nh):
        for k in range(nk):
            move_x[h, k] = shift[h, 0] + offsets[k, 0]
            move_y[h, k] = shift[h, 1] + offsets[k, 1]
            new_h[h, k] = (h + turn + offsets[k, 2]) % nh
    for x in range(nx):
        for y in range(ny):
            if not free[b, x, y]:
                continue
            for h in range(nh):
                p = prob[b, x, y, h]
                if p == 0.0:
                    continue
                for k in range(nk):
                    dx = move_x[h, k]
                    dy = move_y[h, k]
                    th = new_h[h, k]
                    if _stays(free, b, x, y, dx, dy):
                        out[b, x, y, th] += p * weights[k]
                    else:
                        out[b, x + dx, y + dy, th] += p * weights[k]


@numba.njit(cache=True, nogil=True)
def predict_kernel(
    prob: NDArray,
    free: NDArray,
    shift: NDArray,
    turn: NDArray,
    offsets: NDArray,
    weights: NDArray,
    out: NDArray,
) -> None:
    """:func:`predict_member` of every member: ``shift`` ``(B, H, 2)`` and ``turn`` ``(B,)``
    int64 per member; ``out`` ``(B, X, Y, H)`` is overwritten."""
    for b in range(prob.shape[0]):
        predict_member(prob, free, b, shift[b], turn[b], offsets, weights, out)


@numba.njit(cache=True, nogil=True)
def predict_heading_kernel(
    prob: NDArray, free: NDArray, offsets: NDArray, weights: NDArray, out: NDArray
) -> None:
    """Map-aware prediction with a kernel per heading bin (fractional motion, see
    :mod:`active_loc.beliefs.grid_motion`): ``out = sum_x p(x' | u, x) prob(x)``.

    Outcome ``k`` of heading bin ``h`` moves the mass of every cell in that bin by
    ``offsets[b, h, k] = (dx, dy, dh)`` with probability ``weights[b, h, k]``; the translation
    is blocked as in :func:`predict_kernel` (the mass stays in its cell and still turns).

    Args:
        prob: ``(B, X, Y, H)`` belief before the motion.
        free: ``(B, X, Y)`` bool, True = free cell.
        offsets: ``(B, H, K, 3)`` int64 outcomes ``(dx cells, dy cells, dh bins)``.
        weights: ``(B, H, K)`` their probabilities (0 for padding).
        out: ``(B, X, Y, H)`` predicted belief (overwritten).
    """
    nb, nx, ny, nh = prob.shape
    nk = offsets.shape[2]
    out[:] = 0.0
    for b in range(nb):
        for x in range(nx):
            for y in range(ny):
                if not free[b, x, y]:
                    continue
                for h in range(nh):
                    p = prob[b, x, y, h]
                    if p == 0.0:
                        continue
                    for k in range(nk):
                        w = weights[b, h, k]
                        if w == 0.0:
                            continue
                        dx = offsets[b, h, k, 0]
                        dy = offsets[b, h, k, 1]
                        th = (h + offsets[b, h, k, 2]) % nh
                        tx = x + dx
                        ty = y + dy
                        if _stays(free, b, x, y, dx, dy):
                            out[b, x, y, th] += p * w
                        else:
                            out[b, tx, ty, th] += p * w


@numba.njit(cache=True, nogil=True)
def translate_kernel(
    prob: NDArray,
    free: NDArray,
    clearance: NDArray,
    offsets: NDArray,
    weights: NDArray,
    out: NDArray,
) -> None:
    """The translation of :func:`predict_heading_kernel` alone: outcome ``k`` of heading bin
    ``h`` moves the mass by ``offsets[b, h, k] = (dx, dy)`` cells with probability
    ``weights[b, h, k]`` (shapes ``(B, H, K, 2)`` int64 and ``(B, H, K)``), blocked as there;
    headings are kept. ``prob`` and ``out`` ``(B, X, Y, H)``, ``out`` overwritten.

    ``clearance`` ``(B, X, Y)`` int64 (:func:`clearance_map`) lets a cell skip the blocking
    test when every outcome of a heading stays inside its free square, as most cells away
    from walls do; the result is the same."""
    nb, nx, ny, nh = prob.shape
    nk = offsets.shape[2]
    reach = np.zeros(nh, dtype=np.int64)  # the longest outcome of each heading (cells)
    out[:] = 0.0
    for b in range(nb):
        for h in range(nh):
            r = 0
            for k in range(nk):
                if weights[b, h, k] != 0.0:
                    r = max(r, abs(offsets[b, h, k, 0]), abs(offsets[b, h, k, 1]))
            reach[h] = r
        # headings never mix here, so each heading bin is a loop of its own (in parallel in
        # the twin); within one, the sums run in the order of the cells as before
        for h in numba.prange(nh):
            for x in range(nx):
                for y in range(ny):
                    if not free[b, x, y]:
                        continue
                    p = prob[b, x, y, h]
                    if p == 0.0:
                        continue
                    if reach[h] <= clearance[b, x, y]:  # nothing in reach is blocked
                        for k in range(nk):
                            w = weights[b, h, k]
                            out[b, x + offsets[b, h, k, 0], y + offsets[b, h, k, 1], h] += p * w
                        continue
                    for k in range(nk):
                        w = weights[b, h, k]
                        if w == 0.0:
                            continue
                        dx = offsets[b, h, k, 0]
                        dy = offsets[b, h, k, 1]
                        if _stays(free, b, x, y, dx, dy):
                            out[b, x, y, h] += p * w
                        else:
                            out[b, x + dx, y + dy, h] += p * w


translate_kernel_parallel = parallel_twin(translate_kernel)


@numba.njit(cache=True, nogil=True)
def turn_kernel(
    prob: NDArray, free: NDArray, offsets: NDArray, weights: NDArray, out: NDArray
) -> None:
    """Every heading of member ``b`` turns by ``offsets[b, k]`` bins with probability
    ``weights[b, k]`` (``(B, K)`` int64 and float64), wrapping around; cells keep their mass.
    ``prob`` and ``out`` ``(B, X, Y, H)``, ``out`` overwritten."""
    nb, nx, ny, nh = prob.shape
    nk = offsets.shape[1]
    out[:] = 0.0
    for b in range(nb):
        for x in numba.prange(nx):  # cells never mix: in parallel in the twin
            for y in range(ny):
                if not free[b, x, y]:
                    continue
                for h in range(nh):
                    p = prob[b, x, y, h]
                    if p == 0.0:
                        continue
                    for k in range(nk):
                        w = weights[b, k]
                        if w != 0.0:
                            out[b, x, y, (h + offsets[b, k]) % nh] += p * w


turn_kernel_parallel = parallel_twin(turn_kernel)


@numba.njit(cache=True, nogil=True)
def moments_kernel(
    prob: NDArray, xs: NDArray, ys: NDArray, thetas: NDArray, mean: NDArray, cov: NDArray
) -> None:
    """Mean ``(B, 3)`` and covariance ``(B, 3, 3)`` of the cell poses weighted by ``prob``
    ``(B, X, Y, H)``: cell centres ``xs``, ``ys`` ``(X, Y)`` (m, world), bin headings
    ``thetas`` ``(H,)`` (rad); the heading mean is circular and its residuals are wrapped to
    [-pi, pi)."""
    nb, nx, ny, nh = prob.shape
    cos_t = np.cos(thetas)
    sin_t = np.sin(thetas)
    for b in range(nb):
        sx = 0.0
        sy = 0.0
        sc = 0.0
        ss = 0.0
        for x in range(nx):
            for y in range(ny):
                for h in range(nh):
                    p = prob[b, x, y, h]
                    if p == 0.0:
                        continue
                    sx += p * xs[x, y]
                    sy += p * ys[x, y]
                    sc += p * cos_t[h]
                    ss += p * sin_t[h]
        mt = math.atan2(ss, sc)
        residual = np.empty(nh)
        for h in range(nh):
            r = thetas[h] - mt
            residual[h] = r - 2.0 * math.pi * math.floor((r + math.pi) / (2.0 * math.pi))
        cxx = 0.0
        cxy = 0.0
        cyy = 0.0
        cxt = 0.0
        cyt = 0.0
        ctt = 0.0
        for x in range(nx):
            for y in range(ny):
                for h in range(nh):
                    p = prob[b, x, y, h]
                    if p == 0.0:
                        continue
                    ex = xs[x, y] - sx
                    ey = ys[x, y] - sy
                    et = residual[h]
                    cxx += p * ex * ex
                    cxy += p * ex * ey
                    cyy += p * ey * ey
                    cxt += p * ex * et
                    cyt += p * ey * et
                    ctt += p * et * et
        mean[b, 0] = sx
        mean[b, 1] = sy
        mean[b, 2] = mt - 2.0 * math.pi * math.floor((mt + math.pi) / (2.0 * math.pi))
        cov[b, 0, 0] = cxx
        cov[b, 0, 1] = cxy
        cov[b, 1, 0] = cxy
        cov[b, 1, 1] = cyy
        cov[b, 0, 2] = cxt
        cov[b, 2, 0] = cxt
        cov[b, 1, 2] = cyt
        cov[b, 2, 1] = cyt
        cov[b, 2, 2] = ctt


def clearance_map(free: NDArray[np.bool_]) -> NDArray[np.int64]:
    """``(B, X, Y)`` int64: for each free cell the largest ``r`` such that every cell within
    ``r`` cells (Chebyshev distance) is inside the grid and free; -1 on occupied cells. A
    translation of at most ``r`` cells in x and in y from there is never blocked."""
    out = np.empty(free.shape, dtype=np.int64)
    for b in range(free.shape[0]):
        padded = np.pad(free[b], 1, constant_values=False)
        distance = ndimage.distance_transform_cdt(padded, metric="chessboard")
        out[b] = distance[1:-1, 1:-1] - 1
    return out


@numba.njit(cache=True, nogil=True)
def uniform_kernel(prob: NDArray, free: NDArray, b: int) -> None:
    """Member ``b`` of ``prob`` ``(B, X, Y, H)`` uniform over its free poses."""
    nh = prob.shape[3]
    count = 0
    for x in range(free.shape[1]):
        for y in range(free.shape[2]):
            if free[b, x, y]:
                count += 1
    value = 1.0 / (count * nh)
    for x in range(free.shape[1]):
        for y in range(free.shape[2]):
            v = value if free[b, x, y] else 0.0
            for h in range(nh):
                prob[b, x, y, h] = v


@numba.njit(cache=True, nogil=True)
def update_member(
    prob: NDArray, likelihood: NDArray, top: float, free: NDArray, b: int
) -> float:
    """Correction of member ``b`` in place: ``prob[b] *= likelihood[b]``, normalized.

    The product is formed with the likelihood divided by its largest value ``top`` (>= 0,
    the caller's), so it can neither overflow nor depend on the likelihood's scale. A member
    whose mass vanishes is re-initialized uniform over its free poses.

    Returns:
        The unscaled evidence ``sum_x p(z | x) bel_bar(x)``; 0 where the member was
        re-initialized.
    """
    _, nx, ny, nh = prob.shape
    total = 0.0
    if top > 0.0:
        scale = 1.0 / top
        for x in range(nx):
            for y in range(ny):
                for h in range(nh):
                    p = prob[b, x, y, h]
                    if p != 0.0:
                        p *= likelihood[b, x, y, h] * scale
                        prob[b, x, y, h] = p
                        total += p
    if total > 0.0:
        # a division, not a product with 1 / total: a single pose left gets exactly 1.0
        for x in range(nx):
            for y in range(ny):
                for h in range(nh):
                    prob[b, x, y, h] /= total
        return total * top
    uniform_kernel(prob, free, b)
    return 0.0


@numba.njit(cache=True, nogil=True)
def update_kernel(prob: NDArray, likelihood: NDArray, free: NDArray, evidence: NDArray) -> bool:
    """:func:`update_member` of every member with ``likelihood`` ``(B, X, Y, H)``;
    ``evidence[b]`` receives its evidence.

    Returns:
        False (and ``prob`` untouched) if a likelihood is negative, NaN or infinite.
    """
    nb, nx, ny, nh = prob.shape
    tops = np.zeros(nb)
    for b in range(nb):
        top = 0.0
        for x in range(nx):
            for y in range(ny):
                for h in range(nh):
                    v = likelihood[b, x, y, h]
                    if not (v >= 0.0 and v < np.inf):
                        return False
                    if v > top:
                        top = v
        tops[b] = top
    for b in range(nb):
        evidence[b] = update_member(prob, likelihood, tops[b], free, b)
    return True


@numba.njit(cache=True, nogil=True)
def update_log_kernel(
    prob: NDArray, log_likelihood: NDArray, free: NDArray, lik: NDArray, evidence: NDArray,
    shifts: NDArray,
) -> bool:
    """:func:`update_member` of every member with the likelihood ``exp(log_likelihood[b] -
    shifts[b])`` ``(B, X, Y, H)``, ``shifts[b]`` (out) the member's largest log-likelihood (0
    if all are ``-inf``), so that the largest likelihood is exactly 1; ``lik`` receives the
    likelihoods (the exps in parallel over the cells in the twin), ``evidence[b]`` the
    evidence of the shifted likelihood.

    Returns:
        False (and ``prob`` untouched) if a log-likelihood is NaN or ``+inf``.
    """
    nb, nx, ny, nh = prob.shape
    explained = np.zeros(nb, dtype=np.bool_)  # some log-likelihood above -inf
    for b in range(nb):
        top = -np.inf
        for x in range(nx):
            for y in range(ny):
                for h in range(nh):
                    v = log_likelihood[b, x, y, h]
                    if not v < np.inf:  # NaN or +inf
                        return False
                    if v > top:
                        top = v
        explained[b] = top > -np.inf
        shifts[b] = top if explained[b] else 0.0
    for b in range(nb):
        shift = shifts[b]
        for x in numba.prange(nx):
            for y in range(ny):
                for h in range(nh):
                    lik[b, x, y, h] = math.exp(log_likelihood[b, x, y, h] - shift)
        # the largest likelihood: exp(top - top) = 1, or 0 when every one is
        evidence[b] = update_member(prob, lik, 1.0 if explained[b] else 0.0, free, b)
    return True


update_log_kernel_parallel = parallel_twin(update_log_kernel)


@numba.njit(cache=True, nogil=True)
def entropy_kernel(prob: NDArray, log_cell_volume: float, out: NDArray) -> None:
    """``out[b] = -sum p log p + log_cell_volume`` (nats) of ``prob`` ``(B, X, Y, H)``,
    summed a column of cells (one ``x``) at a time, then over the columns in order (in
    parallel over the columns in the twin, with the same sums)."""
    nb, nx, ny, nh = prob.shape
    columns = np.empty(nx)
    for b in range(nb):
        for x in numba.prange(nx):
            s = 0.0
            for y in range(ny):
                for h in range(nh):
                    p = prob[b, x, y, h]
                    if p > 0.0:
                        s -= p * math.log(p)
            columns[x] = s
        total = 0.0
        for x in range(nx):
            total += columns[x]
        out[b] = total + log_cell_volume


entropy_kernel_parallel = parallel_twin(entropy_kernel)


@numba.njit(cache=True, nogil=True)
def mode_kernel(prob: NDArray, index: NDArray, top: NDArray) -> None:
    """Most probable pose ``index[b] = (ix, iy, h)`` (the first in C order on ties) and its
    probability ``top[b]``."""
    nb, nx, ny, nh = prob.shape
    for b in range(nb):
        best = -1.0
        for x in range(nx):
            for y in range(ny):
                for h in range(nh):
                    p = prob[b, x, y, h]
                    if p > best:
                        best = p
                        index[b, 0] = x
                        index[b, 1] = y
                        index[b, 2] = h
        top[b] = best


@numba.njit(cache=True, nogil=True)
def stats_member(prob: NDArray, b: int, log_cell_volume: float, index: NDArray) -> tuple:
    """Entropy (nats, :func:`entropy_kernel`) and largest probability of member ``b`` in
    one pass; its most probable pose goes to ``index`` ``(3,)`` (:func:`mode_kernel`)."""
    _, nx, ny, nh = prob.shape
    total = 0.0
    best = -1.0
    for x in range(nx):
        s = 0.0  # the entropy by columns of cells, summed as entropy_kernel sums them
        for y in range(ny):
            for h in range(nh):
                p = prob[b, x, y, h]
                if p > 0.0:
                    s -= p * math.log(p)
                if p > best:
                    best = p
                    index[0] = x
                    index[1] = y
                    index[2] = h
        total += s
    return total + log_cell_volume, best


@numba.njit(cache=True, nogil=True)
def stats_kernel(
    prob: NDArray, log_cell_volume: float, entropy: NDArray, index: NDArray, top: NDArray
) -> None:
    """:func:`stats_member` of every member: ``entropy`` and ``top`` ``(B,)``, ``index``
    ``(B, 3)`` (out)."""
    for b in range(prob.shape[0]):
        entropy[b], top[b] = stats_member(prob, b, log_cell_volume, index[b])


# --- motion noise ----------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class MotionKernel:
    """Noise of a grid motion: ``K`` outcomes added to the commanded shift and turn.

    Attributes:
        offsets: ``(K, 3)`` int ``(dx cells, dy cells, dh heading bins)`` in the map frame,
            added to the commanded translation and turn. Stored read-only as int64.
        weights: ``(K,)`` probabilities of the outcomes, each >= 0, summing to 1 (within
            1e-9; renormalized exactly). Stored read-only as float64.

    ``MotionKernel.deterministic()`` is the single outcome ``(0, 0, 0)``.
    """

    offsets: NDArray[np.int64]
    weights: NDArray[np.float64]

    def __post_init__(self) -> None:
        offsets = np.asarray(self.offsets)
        weights = np.asarray(self.weights, dtype=np.float64)
        if offsets.ndim != 2 or offsets.shape[1] != 3 or offsets.shape[0] < 1:
            raise ValueError(
                f"MotionKernel.offsets must have shape (K >= 1, 3), got {offsets.shape}"
            )
        if offsets.dtype.kind not in "iu":
            raise ValueError(
                f"MotionKernel.offsets must be integers (cells, heading bins), got "
                f"{offsets.dtype}"
            )
        if weights.shape != (offsets.shape[0],):
            raise ValueError(
                f"MotionKernel.weights must have shape ({offsets.shape[0]},), got "
                f"{weights.shape}"
            )
        if not np.all(np.isfinite(weights)) or np.any(weights < 0.0):
            raise ValueError("MotionKernel.weights must be finite and >= 0")
        if abs(weights.sum() - 1.0) > 1e-9:
            raise ValueError(f"MotionKernel.weights must sum to 1, got {weights.sum()}")
        offsets = np.ascontiguousarray(offsets, dtype=np.int64)
        weights = np.ascontiguousarray(weights / weights.sum())
        offsets.setflags(write=False)
        weights.setflags(write=False)
        object.__setattr__(self, "offsets", offsets)
        object.__setattr__(self, "weights", weights)

    @classmethod
    def deterministic(cls) -> MotionKernel:
        """No noise: the commanded motion with probability 1."""
        return _DETERMINISTIC

    def __setstate__(self, state: dict[str, Any]) -> None:
        for value in state.values():
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
        self.__dict__.update(state)


_DETERMINISTIC = MotionKernel(np.zeros((1, 3), dtype=np.int64), np.ones(1))


# --- the belief ------------------------------------------------------------------------------


def coarse_free_mask(grid: OccupancyGrid, cell_size: float) -> NDArray[np.bool_]:
    """``(X, Y)`` bool, indexed ``[ix, iy]``: the cells of side ``cell_size`` (m) laid over
    ``grid`` from its origin (``X = ceil(width / cell_size)``, likewise Y) that hold the centre
    of at least one FREE map cell. Such a cell can hold the robot, so a belief over these
    cells never rules out the true pose; cells of walls or unknown space only are occupied."""
    cell_size = float(cell_size)
    if not (math.isfinite(cell_size) and cell_size > 0.0):
        raise ValueError(f"cell_size must be finite and > 0 (m), got {cell_size}")
    ny, nx = grid.shape
    ratio = grid.resolution / cell_size
    n_x = max(1, math.ceil(nx * ratio - 1e-9))
    n_y = max(1, math.ceil(ny * ratio - 1e-9))
    ix = np.minimum(((np.arange(nx) + 0.5) * ratio).astype(np.int64), n_x - 1)
    iy = np.minimum(((np.arange(ny) + 0.5) * ratio).astype(np.int64), n_y - 1)
    free = np.zeros((n_x, n_y), dtype=np.bool_)
    rows, cols = np.nonzero(grid.values == FREE)
    free[ix[cols], iy[rows]] = True
    return free



def _as_int_array(value: ArrayLike, name: str) -> NDArray[np.int64]:
    arr = np.asarray(value)
    if arr.dtype.kind not in "iu":
        raise ValueError(f"{name} must be integers, got dtype {arr.dtype}")
    return arr.astype(np.int64, copy=False)


class GridBelief:
    """A batch of B Markov (histogram) beliefs over ``(ix, iy, heading bin)``.

    Args:
        free: ``(X, Y)`` or ``(B, X, Y)`` bool, True = free cell, indexed ``[ix, iy]``; each
            member needs at least one free cell. A 2-D mask is shared by ``batch_size``
            members.
        n_headings: H, the number of heading bins (bin h is heading ``h 2 pi / H``), >= 1.
        cell_size: side of a cell (m), > 0.
        origin: ``(x, y, yaw)`` (m, m, rad): world pose of the bottom-left corner of cell
            ``(0, 0)``, as an occupancy grid's origin.
        batch_size: B when ``free`` is 2-D (default 1); must match a 3-D ``free``.

    The belief starts uniform over the free poses. ``prob`` is a read-only view of the state;
    :meth:`copy` is deep (the free mask is immutable and shared).
    """

    def __init__(
        self,
        free: ArrayLike,
        n_headings: int = 4,
        cell_size: float = 1.0,
        origin: tuple[float, float, float] = (0.0, 0.0, 0.0),
        batch_size: int | None = None,
    ) -> None:
        mask = np.asarray(free)
        if mask.dtype != np.bool_:
            raise ValueError(f"GridBelief.free must be a bool array, got dtype {mask.dtype}")
        if mask.ndim == 2:
            b = 1 if batch_size is None else batch_size
            if isinstance(b, (bool, np.bool_)) or not isinstance(b, (int, np.integer)) or b < 1:
                raise ValueError(f"GridBelief.batch_size must be an integer >= 1, got {b!r}")
            mask = mask[None] if b == 1 else np.repeat(mask[None], int(b), axis=0)
        elif mask.ndim == 3:
            if batch_size is not None and batch_size != mask.shape[0]:
                raise ValueError(
                    f"GridBelief.batch_size ({batch_size}) differs from free.shape[0] "
                    f"({mask.shape[0]})"
                )
        else:
            raise ValueError(
                f"GridBelief.free must have shape (X, Y) or (B, X, Y), got {mask.shape}"
            )
        if mask.shape[1] == 0 or mask.shape[2] == 0:
            raise ValueError(f"GridBelief.free is empty (shape {mask.shape})")
        if not all(member.any() for member in mask):
            raise ValueError("GridBelief.free: every member needs at least one free cell")
        if (
            isinstance(n_headings, (bool, np.bool_))
            or not isinstance(n_headings, (int, np.integer))
            or n_headings < 1
        ):
            raise ValueError(f"GridBelief.n_headings must be an integer >= 1, got {n_headings!r}")
        cell_size = float(cell_size)
        if not (math.isfinite(cell_size) and cell_size > 0.0):
            raise ValueError(f"GridBelief.cell_size must be finite and > 0 (m), got {cell_size}")
        origin_t = tuple(float(v) for v in origin)
        if len(origin_t) != 3 or not all(math.isfinite(v) for v in origin_t):
            raise ValueError(f"GridBelief.origin must be 3 finite numbers, got {origin!r}")

        self._free = np.array(mask, dtype=np.bool_, order="C")
        self._free.setflags(write=False)
        self.n_headings = int(n_headings)
        self.cell_size = cell_size
        self.origin: tuple[float, float, float] = origin_t  # type: ignore[assignment]
        shape = (*self._free.shape, self.n_headings)
        self._prob = np.empty(shape)
        self._scratch = np.empty(shape)
        self._evidence = np.empty(shape[0])
        self.log_cell_volume = math.log(cell_size * cell_size * 2.0 * math.pi / self.n_headings)
        self.reinitialize()

    @classmethod
    def from_grid(
        cls, grid: OccupancyGrid, n_headings: int = 4, batch_size: int = 1,
        cell_size: float | None = None,
    ) -> GridBelief:
        """A uniform belief over the free cells of an occupancy grid (its origin and yaw).

        With ``cell_size`` None the belief's cells are the map's; otherwise cells of
        ``cell_size`` m over the map, each free when it holds a FREE map cell
        (:func:`coarse_free_mask`)."""
        if cell_size is None:
            free = np.ascontiguousarray(grid.values.T == FREE)
            return cls(free, n_headings, grid.resolution, grid.origin, batch_size)
        free = coarse_free_mask(grid, cell_size)
        return cls(free, n_headings, cell_size, grid.origin, batch_size)

    # -- state ----------------------------------------------------------------------------------

    @property
    def batch_size(self) -> int:
        """B."""
        return int(self._prob.shape[0])

    @property
    def shape(self) -> tuple[int, int, int, int]:
        """``(B, X, Y, H)``."""
        b, x, y, h = self._prob.shape
        return int(b), int(x), int(y), int(h)

    @property
    def prob(self) -> NDArray[np.float64]:
        """``(B, X, Y, H)`` probabilities (read-only view), each member summing to 1, zero on
        occupied cells."""
        view = self._prob.view()
        view.setflags(write=False)
        return view

    @property
    def free(self) -> NDArray[np.bool_]:
        """``(B, X, Y)`` bool (read-only): the free cells of every member's map."""
        return self._free

    @property
    def evidence(self) -> NDArray[np.float64]:
        """``(B,)`` ``p(z | z_1:t-1)`` of the last :meth:`update` (0 where it re-initialized);
        read-only copy."""
        return self._evidence.copy()

    def reinitialize(self, members: ArrayLike | None = None) -> None:
        """Make members (all by default; or a ``(B,)`` bool mask / index list) uniform over
        their free poses."""
        if members is None:
            indices = range(self.batch_size)
        else:
            sel = np.asarray(members)
            indices = np.flatnonzero(sel) if sel.dtype == np.bool_ else sel.reshape(-1)
        for b in indices:
            uniform_kernel(self._prob, self._free, int(b))
        self._evidence.fill(np.nan)

    def set_member_free(self, b: int, free: NDArray[np.bool_]) -> None:
        """Give member ``b`` a new map, ``free`` ``(X, Y)`` bool with at least one free cell
        (the caller checks), and make it uniform over its free poses. The masks are replaced,
        not written: copies made before keep theirs."""
        masks = self._free.copy()
        masks[b] = free
        masks.setflags(write=False)
        self._free = masks
        self.__dict__.pop("_clearance_cache", None)
        uniform_kernel(self._prob, self._free, b)

    def set_member(self, b: int, source: GridBelief) -> None:
        """Make member ``b`` a copy of the one-member belief ``source``: its free mask (and
        clearance), probabilities and evidence. ``source`` must have this belief's cells,
        headings and origin. The masks are replaced, not written, as in
        :meth:`set_member_free`."""
        if source.shape[1:] != self.shape[1:] or source.batch_size != 1:
            expected = (1, *self.shape[1:])
            raise ValueError(
                f"set_member needs a one-member belief of shape {expected}, got "
                f"{source.shape}: the members of a batch share the map's grid"
            )
        if source.cell_size != self.cell_size or source.origin != self.origin:
            raise ValueError(
                f"set_member: the source's cells ({source.cell_size} m from {source.origin}) "
                f"differ from this belief's ({self.cell_size} m from {self.origin})"
            )
        masks = self._free.copy()
        masks[b] = source._free[0]
        masks.setflags(write=False)
        self._free = masks
        cached = self.__dict__.get("_clearance_cache")
        if cached is not None:
            clearance = cached.copy()
            clearance[b] = source.clearance[0]
            clearance.setflags(write=False)
            self._clearance_cache = clearance
        self._prob[b] = source._prob[0]
        self._evidence[b] = source._evidence[0]

    def state_arrays(
        self,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_], NDArray[np.float64]]:
        """The writable state for a kernel that steps these beliefs together with its own
        state in one call (the maze core): ``prob`` and a scratch array ``(B, X, Y, H)``, the
        free masks ``(B, X, Y)`` (read-only) and the evidence ``(B,)``. The kernel keeps every
        member normalized, as :func:`predict_member` and :func:`update_member` do."""
        return self._prob, self._scratch, self._free, self._evidence

    def set_prob(self, prob: ArrayLike) -> None:
        """Replace the state with ``prob`` ``(B, X, Y, H)`` (non-negative, finite, zero on
        occupied cells); each member is normalized, and one with no mass is made uniform."""
        arr = np.asarray(prob, dtype=np.float64)
        if arr.shape != self._prob.shape:
            raise ValueError(f"prob must have shape {self._prob.shape}, got {arr.shape}")
        if not np.all(np.isfinite(arr)) or np.any(arr < 0.0):
            raise ValueError("prob must be finite and >= 0")
        if np.any(arr[~self._free] > 0.0):
            raise ValueError("prob must be 0 on occupied cells")
        self._prob[...] = arr
        update_kernel(self._prob, np.ones_like(self._prob), self._free, self._evidence)
        self._evidence.fill(np.nan)

    def initialize_gaussian(self, mean: ArrayLike, cov: ArrayLike) -> None:
        """Every member proportional to ``N(pose; mean, cov)`` at its free cell poses
        (:meth:`cell_poses`; heading residual wrapped): ``mean`` ``(3,)`` or ``(B, 3)`` (m, m,
        rad), ``cov`` ``(3, 3)`` positive definite. A member whose Gaussian vanishes on every
        free pose is made uniform."""
        b = self.batch_size
        mu = np.asarray(mean, dtype=np.float64)
        mu = np.broadcast_to(mu, (b, 3)) if mu.shape == (3,) else mu
        sigma = np.asarray(cov, dtype=np.float64)
        if mu.shape != (b, 3) or not np.all(np.isfinite(mu)):
            raise ValueError(f"mean must be finite with shape (3,) or ({b}, 3), got {mu.shape}")
        if sigma.shape != (3, 3) or not np.all(np.isfinite(sigma)):
            raise ValueError(f"cov must be a finite (3, 3) matrix, got shape {sigma.shape}")
        try:
            root = np.linalg.cholesky(0.5 * (sigma + sigma.T))
        except np.linalg.LinAlgError:
            raise ValueError("cov must be positive definite") from None
        poses = self.cell_poses()
        prob = np.empty(self._prob.shape)
        for member in range(b):
            r = poses - mu[member]
            r[..., 2] = (r[..., 2] + np.pi) % (2.0 * np.pi) - np.pi
            u = np.linalg.solve(root, r.reshape(-1, 3).T)
            log_p = -0.5 * np.sum(u * u, axis=0).reshape(poses.shape[:3])
            log_p -= log_p.max()
            prob[member] = np.exp(log_p) * self._free[member][:, :, None]
        self.set_prob(prob)

    # -- Algorithm 1 ----------------------------------------------------------------------------

    def predict(
        self, shift: ArrayLike, turn: ArrayLike = 0, kernel: MotionKernel | None = None
    ) -> None:
        """Prediction step: move every pose's mass by the map-aware motion model.

        Args:
            shift: ``(H, 2)`` or ``(B, H, 2)`` int: commanded translation ``(dx, dy)`` (cells)
                of a robot in each heading bin.
            turn: int or ``(B,)`` int: commanded turn (heading bins, counterclockwise).
            kernel: motion noise (default: none).

        A translation whose straight path meets an occupied cell or the grid's edge is blocked:
        that mass stays in its cell (and still turns).
        """
        b, _, _, h = self._prob.shape
        shift_arr = _as_int_array(shift, "shift")
        if shift_arr.shape == (h, 2):
            shift_arr = np.broadcast_to(shift_arr, (b, h, 2))
        elif shift_arr.shape != (b, h, 2):
            raise ValueError(f"shift must have shape ({h}, 2) or ({b}, {h}, 2), got "
                             f"{shift_arr.shape}")
        turn_arr = _as_int_array(turn, "turn")
        if turn_arr.shape == ():
            turn_arr = np.broadcast_to(turn_arr, (b,))
        elif turn_arr.shape != (b,):
            raise ValueError(f"turn must be an int or have shape ({b},), got {turn_arr.shape}")
        k = _DETERMINISTIC if kernel is None else kernel
        self.predict_arrays(
            np.ascontiguousarray(shift_arr), np.ascontiguousarray(turn_arr), k.offsets, k.weights
        )

    def predict_arrays(
        self, shift: NDArray[np.int64], turn: NDArray[np.int64], offsets: NDArray, weights: NDArray
    ) -> None:
        """:meth:`predict` without input checks, for a step's hot path: C-contiguous int64
        ``shift`` ``(B, H, 2)`` and ``turn`` ``(B,)``, and a kernel's ``offsets`` ``(K, 3)``
        int64 and ``weights`` ``(K,)`` (:class:`MotionKernel` attributes)."""
        predict_kernel(self._prob, self._free, shift, turn, offsets, weights, self._scratch)
        self._prob, self._scratch = self._scratch, self._prob

    def predict_per_heading(self, offsets: ArrayLike, weights: ArrayLike) -> None:
        """Prediction step with a transition kernel per heading bin.

        Args:
            offsets: ``(H, K, 3)`` or ``(B, H, K, 3)`` int: outcome ``k`` of a robot in heading
                bin ``h`` moves it by ``(dx, dy)`` cells and turns it by ``dh`` bins.
            weights: ``(H, K)`` or ``(B, H, K)`` probabilities of the outcomes, >= 0, each
                heading's summing to 1 (within 1e-9).

        Translations are blocked as in :meth:`predict`: the mass stays in its cell (and still
        turns) where the path meets an occupied cell or the grid's edge.
        """
        b, _, _, h = self._prob.shape
        off = _as_int_array(offsets, "offsets")
        w = np.asarray(weights, dtype=np.float64)
        if off.ndim == 3:
            off = np.broadcast_to(off[None], (b, *off.shape))
        if w.ndim == 2:
            w = np.broadcast_to(w[None], (b, *w.shape))
        if off.ndim != 4 or off.shape[:2] != (b, h) or off.shape[3] != 3:
            raise ValueError(
                f"offsets must have shape ({h}, K, 3) or ({b}, {h}, K, 3), got {off.shape}"
            )
        if w.shape != off.shape[:3]:
            raise ValueError(f"weights must have shape {off.shape[:3]}, got {w.shape}")
        if not np.all(np.isfinite(w)) or np.any(w < 0.0):
            raise ValueError("weights must be finite and >= 0")
        if np.any(np.abs(w.sum(axis=2) - 1.0) > 1e-9):
            raise ValueError("weights of every heading must sum to 1")
        self.predict_per_heading_arrays(np.ascontiguousarray(off), np.ascontiguousarray(w))

    def predict_per_heading_arrays(self, offsets: NDArray[np.int64], weights: NDArray) -> None:
        """:meth:`predict_per_heading` without input checks: C-contiguous int64 ``offsets``
        ``(B, H, K, 3)`` and float64 ``weights`` ``(B, H, K)``."""
        predict_heading_kernel(self._prob, self._free, offsets, weights, self._scratch)
        self._prob, self._scratch = self._scratch, self._prob

    def predict_fractional(
        self, shift: ArrayLike, turn: ArrayLike = 0.0, noise_std: ArrayLike = (0.0, 0.0, 0.0)
    ) -> None:
        """Prediction step with a fractional motion: the exact transition of the
        piecewise-constant density (:mod:`active_loc.beliefs.grid_motion`).

        Args:
            shift: ``(H, 2)`` or ``(B, H, 2)`` real translation (cells, grid frame) of a
                robot in each heading bin.
            turn: real or ``(B,)`` turn (heading bins, counterclockwise).
            noise_std: ``(3,)`` Gaussian motion noise standard deviations (cells, cells,
                heading bins), >= 0.

        The same transition as :meth:`predict_per_heading` with
        :func:`~active_loc.beliefs.grid_motion.fractional_kernel`, applied in its two factors
        (translation, then turn). Integer shifts and turns without noise equal :meth:`predict`.
        """
        b, _, _, h = self._prob.shape
        sh = np.asarray(shift, dtype=np.float64)
        if sh.shape == (h, 2):
            sh = np.broadcast_to(sh, (b, h, 2))
        elif sh.shape != (b, h, 2):
            raise ValueError(f"shift must have shape ({h}, 2) or ({b}, {h}, 2), got {sh.shape}")
        tr = np.asarray(turn, dtype=np.float64)
        if tr.shape == ():
            tr = np.broadcast_to(tr, (b,))
        elif tr.shape != (b,):
            raise ValueError(f"turn must be a number or have shape ({b},), got {tr.shape}")
        if not (np.all(np.isfinite(sh)) and np.all(np.isfinite(tr))):
            raise ValueError("shift and turn must be finite")
        std = np.asarray(noise_std, dtype=np.float64)
        if std.shape != (3,) or not np.all(np.isfinite(std)) or np.any(std < 0.0):
            raise ValueError(f"noise_std must be 3 finite numbers >= 0, got {noise_std!r}")
        move, move_w, turns, turn_w = checked_fractional_kernels(
            np.ascontiguousarray(sh), np.ascontiguousarray(tr), std)
        # translate with the heading before the turn, then turn (blocked or not)
        pick(translate_kernel, translate_kernel_parallel)(
            self._prob, self._free, self.clearance, move, move_w, self._scratch
        )
        pick(turn_kernel, turn_kernel_parallel)(self._scratch, self._free, turns, turn_w,
                                                self._prob)

    def predict_unicycle(
        self, v: ArrayLike, omega: ArrayLike, dt: float, noise_std: ArrayLike = (0.0, 0.0, 0.0)
    ) -> None:
        """Prediction step of the unicycle (:mod:`active_loc.motion`) on the grid: speed ``v``
        (m/s) and turn rate ``omega`` (rad/s) for ``dt`` (s), with the per-step noise standard
        deviations ``noise_std`` ``(3,)`` (m, m, rad); ``v`` and ``omega`` are numbers (the
        same control for every member) or ``(B,)`` (one per member)."""
        b = self.batch_size
        speeds = np.broadcast_to(np.asarray(v, dtype=np.float64), (b,))
        rates = np.broadcast_to(np.asarray(omega, dtype=np.float64), (b,))
        shift, turn = unicycle_shifts(speeds, rates, dt, self.cell_size, self.n_headings)
        self.predict_fractional(
            shift, turn, noise_in_cells(noise_std, self.cell_size, self.n_headings)
        )

    def update(self, likelihood: ArrayLike) -> NDArray[np.float64]:
        """Correction step: multiply by a per-pose likelihood and normalize.

        Args:
            likelihood: ``(B, X, Y, H)`` (or ``(X, Y, H)``, shared by every member) values of
                ``p(z | pose)``, finite and >= 0; any common scale.

        Returns:
            ``(B,)`` evidence ``sum_x p(z | x) bel_bar(x)``; 0 marks a member that no pose
            could explain, which was re-initialized uniform over its free poses.

        Raises:
            ValueError: wrong shape, or a negative, NaN or infinite likelihood.
        """
        lik = np.asarray(likelihood, dtype=np.float64)
        shape = self._prob.shape
        if lik.shape == shape[1:]:
            lik = lik[None]
            if shape[0] > 1:
                lik = np.broadcast_to(lik, shape)
        elif lik.shape != shape:
            raise ValueError(
                f"likelihood must have shape {shape} or {shape[1:]}, got {lik.shape}"
            )
        if not update_kernel(self._prob, lik, self._free, self._evidence):
            raise ValueError("likelihood must be finite and >= 0")
        return self._evidence.copy()

    def update_log(self, log_likelihood: ArrayLike) -> NDArray[np.float64]:
        """Correction with log-likelihoods ``(B, X, Y, H)`` or ``(X, Y, H)`` (nats; ``-inf``
        allowed, ``+inf`` and NaN not), shifted by each member's maximum before
        exponentiating so that values like -1000 do not underflow.

        Returns:
            ``(B,)`` log evidence ``log sum_x p(z | x) bel_bar(x)``; ``-inf`` marks a
            re-initialized member.
        """
        ll = np.asarray(log_likelihood, dtype=np.float64)
        shape = self._prob.shape
        if ll.shape == shape[1:]:
            ll = np.broadcast_to(ll[None], shape)
        elif ll.shape != shape:
            raise ValueError(
                f"log_likelihood must have shape {shape} or {shape[1:]}, got {ll.shape}"
            )
        shifts = np.empty(shape[0])
        # the scratch array is free between predictions: it takes the likelihoods
        if not pick(update_log_kernel, update_log_kernel_parallel)(
            self._prob, ll, self._free, self._scratch, self._evidence, shifts
        ):
            raise ValueError("log_likelihood must not hold NaN or +inf")
        evidence = self._evidence
        with np.errstate(divide="ignore"):
            return np.where(evidence > 0.0, np.log(evidence) + shifts, -np.inf)

    # -- statistics -----------------------------------------------------------------------------

    def entropy(self) -> NDArray[np.float64]:
        """``(B,)`` entropy (nats): histogram entropy + log(cell volume)."""
        out = np.empty(self._prob.shape[0])
        pick(entropy_kernel, entropy_kernel_parallel)(self._prob, self.log_cell_volume, out)
        return out

    def mode(self) -> NDArray[np.int64]:
        """``(B, 3)`` int64 ``(ix, iy, h)`` of the most probable pose (first in C order on
        ties)."""
        index = np.empty((self._prob.shape[0], 3), dtype=np.int64)
        mode_kernel(self._prob, index, np.empty(self._prob.shape[0]))
        return index

    def max_prob(self) -> NDArray[np.float64]:
        """``(B,)`` probability of the most probable pose."""
        return self._prob.reshape(self._prob.shape[0], -1).max(axis=1)

    def mode_and_max(self) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """:meth:`mode` and :meth:`max_prob` in one pass."""
        b = self._prob.shape[0]
        index = np.empty((b, 3), dtype=np.int64)
        top = np.empty(b)
        mode_kernel(self._prob, index, top)
        return index, top

    def summary(self) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
        """:meth:`entropy`, :meth:`mode` and :meth:`max_prob` in one pass: ``(B,)`` nats,
        ``(B, 3)`` int64 ``(ix, iy, h)`` and ``(B,)``."""
        b = self._prob.shape[0]
        entropy = np.empty(b)
        index = np.empty((b, 3), dtype=np.int64)
        top = np.empty(b)
        stats_kernel(self._prob, self.log_cell_volume, entropy, index, top)
        return entropy, index, top

    def moments(
        self, within_cell: bool = True
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Mean ``(B, 3)`` (m, m, rad) and covariance ``(B, 3, 3)`` of the pose.

        The heading mean is circular and heading residuals are wrapped. With ``within_cell``
        (the default) the covariance is that of the piecewise-constant density the histogram
        stands for, the one whose entropy :meth:`entropy` reports: the cell poses' covariance
        plus the spread inside a cell, ``diag(c^2 / 12, c^2 / 12, (2 pi / H)^2 / 12)``
        (``c`` = cell size); without it, that of the cell poses alone.
        """
        b, _, _, nh = self._prob.shape
        mean = np.empty((b, 3))
        cov = np.empty((b, 3, 3))
        moments_kernel(self._prob, *self._cell_geometry(), mean, cov)
        if within_cell:
            bin_width = 2.0 * math.pi / nh
            cov += np.diag([self.cell_size**2, self.cell_size**2, bin_width**2]) / 12.0
        return mean, cov

    def marginal_xy(self) -> NDArray[np.float64]:
        """``(B, X, Y)`` probability of each cell, headings summed."""
        return self._prob.sum(axis=3)

    def cell_poses(self) -> NDArray[np.float64]:
        """``(X, Y, H, 3)`` world poses ``(x, y, theta)`` (m, m, rad in [-pi, pi)) of the cell
        centres and heading bins, for sensor models that score poses (lidar, landmarks):
        ``belief.update_log(sensor_ll(poses.reshape(-1, 3)).reshape(X, Y, H))``."""
        _, nx, ny, nh = self.shape
        xs, ys, theta = self._cell_geometry()
        out = np.empty((nx, ny, nh, 3))
        out[..., 0] = xs[..., None]
        out[..., 1] = ys[..., None]
        out[..., 2] = theta
        return out

    @property
    def clearance(self) -> NDArray[np.int64]:
        """``(B, X, Y)`` int64 :func:`clearance_map` of the free mask: how far (cells) mass
        can move from each cell without meeting a wall; computed once, read-only, shared by
        copies."""
        cached = self.__dict__.get("_clearance_cache")
        if cached is None:
            cached = clearance_map(self._free)
            cached.setflags(write=False)
            self._clearance_cache = cached
        return cached

    def _cell_geometry(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray]:
        """World x ``(X, Y)``, y ``(X, Y)`` (m) of the cell centres and headings ``(H,)`` (rad)
        of the bins; computed once, read-only, shared by copies."""
        cached = self.__dict__.get("_geometry")
        if cached is None:
            _, nx, ny, nh = self.shape
            ox, oy, yaw = self.origin
            c, s = math.cos(yaw), math.sin(yaw)
            gx = (np.arange(nx) + 0.5) * self.cell_size
            gy = (np.arange(ny) + 0.5) * self.cell_size
            u, v = np.meshgrid(gx, gy, indexing="ij")
            theta = yaw + 2.0 * np.pi * np.arange(nh) / nh
            theta = (theta + np.pi) % (2.0 * np.pi) - np.pi
            cached = (np.ascontiguousarray(ox + c * u - s * v),
                      np.ascontiguousarray(oy + s * u + c * v), theta)
            for array in cached:
                array.setflags(write=False)
            self._geometry = cached
        return cached

    @property
    def mean(self) -> NDArray[np.float64]:
        """``(B, 3)`` weighted mean pose (m, m, rad): cell centres averaged, heading averaged
        circularly."""
        poses = self.cell_poses()
        w = self._prob
        xy = np.einsum("bxyh,xyhk->bk", w, poses[..., :2])
        cos = np.einsum("bxyh,xyh->b", w, np.cos(poses[..., 2]))
        sin = np.einsum("bxyh,xyh->b", w, np.sin(poses[..., 2]))
        return np.column_stack([xy, np.arctan2(sin, cos)])

    # -- copies ---------------------------------------------------------------------------------

    def copy(self) -> GridBelief:
        """A deep copy (the read-only free mask is shared)."""
        out = _copy.copy(self)
        out._prob = self._prob.copy()
        out._scratch = np.empty_like(self._scratch)
        out._evidence = self._evidence.copy()
        return out

    def member(self, b: int) -> GridBelief:
        """A deep copy of member ``b`` alone (B = 1)."""
        out = _copy.copy(self)
        out._prob = self._prob[b : b + 1].copy()
        out._scratch = np.empty_like(out._prob)
        out._evidence = self._evidence[b : b + 1].copy()
        out._free = self._free[b : b + 1]  # a view of an array never written again
        out.__dict__.pop("_clearance_cache", None)
        return out

    def __deepcopy__(self, memo: dict) -> GridBelief:
        return self.copy()

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._free.setflags(write=False)
        for array in self.__dict__.get("_geometry") or ():
            array.setflags(write=False)
        if "_clearance_cache" in self.__dict__:
            self._clearance_cache.setflags(write=False)
