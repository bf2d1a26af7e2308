"""Fractional motion on a pose grid: the unicycle model as per-heading transition kernels.

A grid belief (:class:`active_loc.beliefs.grid.GridBelief`) stands for a piecewise-constant
density: a cell's mass is spread uniformly over its square and its heading bin. Moving that
density by a translation of ``s`` cells (a real number) along one axis puts the fraction
``tent(s - k) = max(0, 1 - |s - k|)`` of a cell's mass into the cell ``k`` cells away: the
overlap of the shifted square with cell ``k``. Adding Gaussian motion noise ``N(0, sigma^2)``
(cells) turns that into the tent convolved with the Gaussian,

    w_k = E[tent(s - k + n)] = R(s - k + 1) - 2 R(s - k) + R(s - k - 1),
    R(t) = E[max(0, t + n)] = t Phi(t / sigma) + sigma phi(t / sigma),

which is the exact transition of the piecewise-constant density along that axis (Phi and phi
the standard normal CDF and density). The unicycle (:mod:`active_loc.motion`) translates by
``V dt`` along the heading before the turn, so a robot in heading bin ``h`` (heading
``theta_h = h 2 pi / H`` in the grid's frame) moves by ``(V dt cos theta_h, V dt sin theta_h)
/ cell_size`` cells and turns by ``omega dt / (2 pi / H)`` bins; x, y and heading are
independent given the bin (the noise covariance is diagonal), so the kernel of bin ``h`` is
the product of the three one-axis weights. The weights of the headings wrap around.

Approximations, both second order at the sizes used here: the heading within a bin is taken
as its centre for the direction of the translation (a 10 degree bin moves a 0.2 m step by at
most 1.7 cm sideways), and on a yawed grid the noise's x and y standard deviations are used
per grid axis (exact when they are equal, as in every scenario).

The kernels are built once per step (numba, tens of microseconds for 36 headings). Because the
turn does not depend on the translation (a blocked robot still turns), the kernel of a heading
factors into a translation part and a turn part (:func:`fractional_kernels`), which the belief
applies one after the other (:func:`active_loc.beliefs.grid.translate_kernel`, then
:func:`active_loc.beliefs.grid.turn_kernel`): about 3 times fewer operations per pose than the
product kernel (:func:`fractional_kernel`, the same transition in one pass).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

#: one-axis weights below this are dropped (then each axis is renormalized): a Gaussian tail
#: this far out is under 1e-9 of the mass, and dropping it keeps the kernels short
WEIGHT_TOL = 1e-9
#: the one-axis window reaches this many noise standard deviations past the tent
_SIGMAS = 7.0
_INV_SQRT_2PI = 1.0 / math.sqrt(2.0 * math.pi)
_INV_SQRT_2 = 1.0 / math.sqrt(2.0)


@numba.njit(cache=True, nogil=True, inline="always")
def _ramp_expectation(t: float, std: float) -> float:
    """``R(t) = E[max(0, t + n)]``, ``n ~ N(0, std^2)`` (std > 0)."""
    u = t / std
    return t * 0.5 * math.erfc(-u * _INV_SQRT_2) + std * _INV_SQRT_2PI * math.exp(-0.5 * u * u)


@numba.njit(cache=True, nogil=True)
def axis_kernel(s: float, std: float, tol: float, margin: int, out: NDArray) -> int:
    """One axis: the weights ``out`` ``(2 + 2 margin,)`` of the cells ``first + j`` (returned
    ``first``) that a cell's mass reaches under a shift ``s`` with noise ``std`` (see
    :func:`axis_weights`); ``margin`` >= ceil(7 std)."""
    first = math.floor(s) - margin
    total = 0.0
    for j in range(out.shape[0]):
        t = s - (first + j)
        if std == 0.0:
            w = max(0.0, 1.0 - abs(t))
        else:
            w = (_ramp_expectation(t + 1.0, std) - 2.0 * _ramp_expectation(t, std)
                 + _ramp_expectation(t - 1.0, std))
        if w < tol:
            w = 0.0
        out[j] = w
        total += w
    for j in range(out.shape[0]):
        out[j] /= total
    return first


def _margin(std: float) -> int:
    return math.ceil(_SIGMAS * std)


def axis_weights(
    shift: ArrayLike, std: float, tol: float = WEIGHT_TOL
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Where one axis's fractional shifts send a cell's mass.

    Args:
        shift: ``(N,)`` shifts (cells or heading bins), finite.
        std: noise standard deviation (same unit), >= 0; 0 gives the plain tent (linear
            interpolation between the two neighbouring cells).
        tol: weights below it are set to 0 and each row renormalized.

    Returns:
        ``first`` ``(N,)`` int64 and ``weights`` ``(N, W)``: row ``i`` puts ``weights[i, j]``
        of the mass ``first[i] + j`` cells away; rows sum to 1.
    """
    s = np.asarray(shift, dtype=np.float64).reshape(-1)
    if not np.all(np.isfinite(s)):
        raise ValueError(f"shift must be finite, got {s}")
    std = float(std)
    if not (math.isfinite(std) and std >= 0.0):
        raise ValueError(f"std must be finite and >= 0, got {std}")
    margin = _margin(std)
    weights = np.empty((s.shape[0], 2 + 2 * margin))
    first = np.empty(s.shape[0], dtype=np.int64)
    for i in range(s.shape[0]):
        first[i] = axis_kernel(float(s[i]), std, tol, margin, weights[i])
    return first, weights


@numba.njit(cache=True, nogil=True)
def translation_kernel_arrays(
    shift: NDArray, std_x: float, std_y: float, tol: float, margin_x: int, margin_y: int
) -> tuple[NDArray, NDArray]:
    """The translation part of :func:`fractional_kernels` on checked arrays: ``shift``
    ``(B, H, 2)`` (cells), noise stds (cells) and their margins (ceil(7 std))."""
    nb, nh, _ = shift.shape
    wx = np.empty(2 + 2 * margin_x)
    wy = np.empty(2 + 2 * margin_y)
    full = wx.shape[0] * wy.shape[0]
    offsets = np.zeros((nb, nh, full, 2), dtype=np.int64)
    weights = np.zeros((nb, nh, full))
    k_max = 1
    for b in range(nb):
        for h in range(nh):
            x0 = axis_kernel(shift[b, h, 0], std_x, tol, margin_x, wx)
            y0 = axis_kernel(shift[b, h, 1], std_y, tol, margin_y, wy)
            k = 0
            for i in range(wx.shape[0]):
                if wx[i] == 0.0:
                    continue
                for j in range(wy.shape[0]):
                    if wy[j] == 0.0:
                        continue
                    offsets[b, h, k, 0] = x0 + i
                    offsets[b, h, k, 1] = y0 + j
                    weights[b, h, k] = wx[i] * wy[j]
                    k += 1
            k_max = max(k_max, k)
    return (np.ascontiguousarray(offsets[:, :, :k_max]),
            np.ascontiguousarray(weights[:, :, :k_max]))


@numba.njit(cache=True, nogil=True)
def turn_kernel_arrays(
    turn: NDArray, std: float, tol: float, margin: int
) -> tuple[NDArray, NDArray]:
    """The turn part of :func:`fractional_kernels` on checked arrays: ``turn`` ``(B,)``
    (bins), its noise std (bins) and margin (ceil(7 std))."""
    nb = turn.shape[0]
    w = np.empty(2 + 2 * margin)
    offsets = np.zeros((nb, w.shape[0]), dtype=np.int64)
    weights = np.zeros((nb, w.shape[0]))
    k_max = 1
    for b in range(nb):
        t0 = axis_kernel(turn[b], std, tol, margin, w)
        k = 0
        for m in range(w.shape[0]):
            if w[m] == 0.0:
                continue
            offsets[b, k] = t0 + m
            weights[b, k] = w[m]
            k += 1
        k_max = max(k_max, k)
    return np.ascontiguousarray(offsets[:, :k_max]), np.ascontiguousarray(weights[:, :k_max])


def fractional_kernels(
    shift: ArrayLike, turn: ArrayLike, noise_std: ArrayLike = (0.0, 0.0, 0.0),
    tol: float = WEIGHT_TOL,
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
    """The transition of fractional translations and turns with noise, in two factors.

    Args:
        shift: ``(B, H, 2)`` translation (cells, grid frame) of a robot in each heading bin.
        turn: ``(B,)`` turn (heading bins, counterclockwise).
        noise_std: ``(3,)`` motion noise standard deviations (cells, cells, heading bins),
            each >= 0.
        tol: one-axis weights below it are dropped (see :func:`axis_weights`).

    Returns:
        ``move`` ``(B, H, K, 2)`` int64 and ``move_weights`` ``(B, H, K)``: outcome ``k`` of
        heading bin ``h`` translates the mass by ``move[b, h, k]`` cells (the product of the x
        and y weights); ``turns`` ``(B, J)`` int64 and ``turn_weights`` ``(B, J)``: then every
        heading turns by ``turns[b, j]`` bins. Rows sum to 1; padding outcomes have weight 0
        and offset 0. The full kernel of a heading is the product of the two
        (:func:`fractional_kernel`): a turn never depends on the translation, blocked or not.
    """
    sh = np.ascontiguousarray(shift, dtype=np.float64)
    if sh.ndim != 3 or sh.shape[2] != 2:
        raise ValueError(f"shift must have shape (B, H, 2), got {sh.shape}")
    tr = np.ascontiguousarray(turn, dtype=np.float64).reshape(-1)
    if tr.shape != (sh.shape[0],):
        raise ValueError(f"turn must have shape ({sh.shape[0]},), got {tr.shape}")
    std = np.asarray(noise_std, dtype=np.float64).reshape(-1)
    if std.shape != (3,) or not np.all(np.isfinite(std)) or np.any(std < 0.0):
        raise ValueError(f"noise_std must be 3 finite numbers >= 0, got {noise_std!r}")
    if not (np.all(np.isfinite(sh)) and np.all(np.isfinite(tr))):
        raise ValueError("shift and turn must be finite")
    return checked_fractional_kernels(sh, tr, std, tol)


def checked_fractional_kernels(
    shift: NDArray[np.float64], turn: NDArray[np.float64], noise_std: NDArray[np.float64],
    tol: float = WEIGHT_TOL,
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
    """:func:`fractional_kernels` of inputs its caller has checked: C-contiguous float64
    ``shift`` ``(B, H, 2)`` and ``turn`` ``(B,)``, finite, and ``noise_std`` ``(3,)`` finite
    and >= 0."""
    sx, sy, st = (float(v) for v in noise_std)
    move, move_w = translation_kernel_arrays(shift, sx, sy, float(tol), _margin(sx),
                                             _margin(sy))
    turns, turn_w = turn_kernel_arrays(turn, st, float(tol), _margin(st))
    return move, move_w, turns, turn_w


def fractional_kernel(
    shift: ArrayLike, turn: ArrayLike, noise_std: ArrayLike = (0.0, 0.0, 0.0),
    tol: float = WEIGHT_TOL,
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """:func:`fractional_kernels` as one kernel per heading: ``offsets`` ``(B, H, K, 3)``
    int64 ``(dx, dy, dh)`` and ``weights`` ``(B, H, K)`` (the products of the translation and
    turn weights), for :meth:`GridBelief.predict_per_heading
    <active_loc.beliefs.grid.GridBelief.predict_per_heading>`."""
    move, move_w, turns, turn_w = fractional_kernels(shift, turn, noise_std, tol)
    nb, nh, k_move, _ = move.shape
    k_turn = turns.shape[1]
    offsets = np.empty((nb, nh, k_move, k_turn, 3), dtype=np.int64)
    offsets[..., :2] = move[:, :, :, None, :]
    offsets[..., 2] = turns[:, None, None, :]
    weights = move_w[:, :, :, None] * turn_w[:, None, None, :]
    offsets = np.where(weights[..., None] > 0.0, offsets, 0)
    return (np.ascontiguousarray(offsets.reshape(nb, nh, -1, 3)),
            np.ascontiguousarray(weights.reshape(nb, nh, -1)))


def unicycle_shifts(
    v: NDArray[np.float64], omega: NDArray[np.float64], dt: float, cell_size: float,
    n_headings: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The unicycle's mean motion on a grid, for B controls: ``shift`` ``(B, H, 2)`` (cells,
    grid frame) of a robot in each heading bin moving at ``v`` ``(B,)`` (m/s) for ``dt`` (s),
    and the turn ``(B,)`` (bins) of ``omega`` ``(B,)`` (rad/s)."""
    theta = 2.0 * np.pi * np.arange(n_headings) / n_headings
    step = v * dt / cell_size
    shift = np.empty((v.shape[0], n_headings, 2))
    shift[:, :, 0] = step[:, None] * np.cos(theta)
    shift[:, :, 1] = step[:, None] * np.sin(theta)
    return shift, omega * dt * n_headings / (2.0 * math.pi)


def noise_in_cells(
    noise_std: ArrayLike, cell_size: float, n_headings: int
) -> NDArray[np.float64]:
    """Motion noise standard deviations ``(3,)`` (m, m, rad) in grid units (cells, cells,
    heading bins)."""
    std = np.asarray(noise_std, dtype=np.float64).reshape(3)
    return np.array([std[0] / cell_size, std[1] / cell_size,
                     std[2] * n_headings / (2.0 * math.pi)])
