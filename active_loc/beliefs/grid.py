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
   (:func:`active_loc.motion.move_within_bounds`).
2. **Correction** (:meth:`GridBelief.update`), ``bel(x) = eta p(z | x) bel_bar(x)``, with a
   per-pose likelihood array ``(B, X, Y, H)`` from any sensor model: the maze depth sensor
   (:class:`~active_loc.sensors.depth.DepthSensor`), or the lidar and landmark models evaluated
   at :meth:`GridBelief.cell_poses` (log-likelihoods go through :meth:`GridBelief.update_log`).
   When no pose explains the measurement (total mass 0) the member is re-initialized uniform
   over its free poses instead of dividing by zero.

Entropy (nats) is the histogram entropy plus ``log(cell volume)``, the cell volume being
``cell_size^2 * 2 pi / H`` (m^2 rad), as :mod:`active_loc.beliefs.entropy` defines it for every
filter. For the maze (1 m cells, 4 headings) that is ``log(pi / 2)``.

The loops are numba kernels over plain arrays; a 21 x 21 x 4 belief predicts or updates in a
few microseconds.
"""

from __future__ import annotations

import copy as _copy
import math
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from active_loc.maps.occupancy import FREE, OccupancyGrid

# --- kernels ---------------------------------------------------------------------------------


@numba.njit(cache=True)
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


@numba.njit(cache=True)
def predict_kernel(
    prob: NDArray,
    free: NDArray,
    shift: NDArray,
    turn: NDArray,
    offsets: NDArray,
    weights: NDArray,
    out: NDArray,
) -> None:
    """Map-aware prediction: ``out = sum_x p(x' | u, x) prob(x)``.

    Args:
        prob: ``(B, X, Y, H)`` belief before the motion.
        free: ``(B, X, Y)`` bool, True = free cell.
        shift: ``(B, H, 2)`` int64 commanded translation (cells) per heading bin.
        turn: ``(B,)`` int64 commanded turn (heading bins).
        offsets: ``(K, 3)`` int64 noise outcomes ``(dx, dy, dh)`` added to the command.
        weights: ``(K,)`` probabilities of the outcomes.
        out: ``(B, X, Y, H)`` predicted belief (overwritten).
    """
    nb, nx, ny, nh = prob.shape
    nk = offsets.shape[0]
    # per member, heading and outcome: the translation and the new heading bin
    move_x = np.empty((nh, nk), dtype=np.int64)
    move_y = np.empty((nh, nk), dtype=np.int64)
    new_h = np.empty((nh, nk), dtype=np.int64)
    out[:] = 0.0
    for b in range(nb):
        for h in range(nh):
            for k in range(nk):
                move_x[h, k] = shift[b, h, 0] + offsets[k, 0]
                move_y[h, k] = shift[b, h, 1] + offsets[k, 1]
                new_h[h, k] = (h + turn[b] + offsets[k, 2]) % nh
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
                        tx = x + dx
                        ty = y + dy
                        if dx == 0 and dy == 0:
                            blocked = True
                        elif abs(dx) <= 1 and abs(dy) <= 1:  # one step: only the target
                            blocked = not (0 <= tx < nx and 0 <= ty < ny and free[b, tx, ty])
                        else:
                            blocked = not _path_free(free, b, x, y, dx, dy)
                        if blocked:
                            out[b, x, y, th] += p * weights[k]
                        else:
                            out[b, tx, ty, th] += p * weights[k]


@numba.njit(cache=True)
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


@numba.njit(cache=True)
def update_kernel(prob: NDArray, likelihood: NDArray, free: NDArray, evidence: NDArray) -> bool:
    """Correction in place: ``prob *= likelihood``, normalized per member.

    The product is formed with the likelihood divided by its largest value, so it can neither
    overflow nor depend on the likelihood's scale; ``evidence[b]`` receives the unscaled
    ``sum_x p(z | x) bel_bar(x)``. A member whose mass vanishes (evidence 0) is re-initialized
    uniform over its free poses.

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
        top = tops[b]
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
            evidence[b] = total * top
        else:
            uniform_kernel(prob, free, b)
            evidence[b] = 0.0
    return True


@numba.njit(cache=True)
def entropy_kernel(prob: NDArray, log_cell_volume: float, out: NDArray) -> None:
    """``out[b] = -sum p log p + log_cell_volume`` (nats) of ``prob`` ``(B, X, Y, H)``."""
    nb, nx, ny, nh = prob.shape
    for b in range(nb):
        s = 0.0
        for x in range(nx):
            for y in range(ny):
                for h in range(nh):
                    p = prob[b, x, y, h]
                    if p > 0.0:
                        s -= p * math.log(p)
        out[b] = s + log_cell_volume


@numba.njit(cache=True)
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


@numba.njit(cache=True)
def stats_kernel(
    prob: NDArray, log_cell_volume: float, entropy: NDArray, index: NDArray, top: NDArray
) -> None:
    """:func:`entropy_kernel` and :func:`mode_kernel` in one pass."""
    nb, nx, ny, nh = prob.shape
    for b in range(nb):
        s = 0.0
        best = -1.0
        for x in range(nx):
            for y in range(ny):
                for h in range(nh):
                    p = prob[b, x, y, h]
                    if p > 0.0:
                        s -= p * math.log(p)
                    if p > best:
                        best = p
                        index[b, 0] = x
                        index[b, 1] = y
                        index[b, 2] = h
        entropy[b] = s + log_cell_volume
        top[b] = best


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
        cls, grid: OccupancyGrid, n_headings: int = 4, batch_size: int = 1
    ) -> GridBelief:
        """A uniform belief over the FREE cells of an occupancy grid (its resolution, origin
        and yaw)."""
        free = np.ascontiguousarray(grid.values.T == FREE)
        return cls(free, n_headings, grid.resolution, grid.origin, batch_size)

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
        if np.any(np.isnan(ll)) or np.any(ll == np.inf):
            raise ValueError("log_likelihood must not hold NaN or +inf")
        top = ll.reshape(shape[0], -1).max(axis=1)
        finite_top = np.where(np.isfinite(top), top, 0.0)
        with np.errstate(invalid="ignore"):
            lik = np.exp(ll - finite_top[:, None, None, None])
        evidence = self.update(lik)
        with np.errstate(divide="ignore"):
            return np.where(evidence > 0.0, np.log(evidence) + finite_top, -np.inf)

    # -- statistics -----------------------------------------------------------------------------

    def entropy(self) -> NDArray[np.float64]:
        """``(B,)`` entropy (nats): histogram entropy + log(cell volume)."""
        out = np.empty(self._prob.shape[0])
        entropy_kernel(self._prob, self.log_cell_volume, out)
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

    def marginal_xy(self) -> NDArray[np.float64]:
        """``(B, X, Y)`` probability of each cell, headings summed."""
        return self._prob.sum(axis=3)

    def cell_poses(self) -> NDArray[np.float64]:
        """``(X, Y, H, 3)`` world poses ``(x, y, theta)`` (m, m, rad in [-pi, pi)) of the cell
        centres and heading bins, for sensor models that score poses (lidar, landmarks):
        ``belief.update_log(sensor_ll(poses.reshape(-1, 3)).reshape(X, Y, H))``."""
        _, nx, ny, nh = self.shape
        ox, oy, yaw = self.origin
        c, s = math.cos(yaw), math.sin(yaw)
        gx = (np.arange(nx) + 0.5) * self.cell_size
        gy = (np.arange(ny) + 0.5) * self.cell_size
        u, v = np.meshgrid(gx, gy, indexing="ij")
        theta = yaw + 2.0 * np.pi * np.arange(nh) / nh
        theta = (theta + np.pi) % (2.0 * np.pi) - np.pi
        out = np.empty((nx, ny, nh, 3))
        out[..., 0] = (ox + c * u - s * v)[..., None]
        out[..., 1] = (oy + s * u + c * v)[..., None]
        out[..., 2] = theta
        return out

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

    def __deepcopy__(self, memo: dict) -> GridBelief:
        return self.copy()

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._free.setflags(write=False)
