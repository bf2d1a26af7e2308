"""The maze depth sensor: how many cells ahead until the first wall.

On a grid of cells with 4 headings (0 east = +x, 1 north = +y, 2 west, 3 south), the depth seen
from pose ``(ix, iy, h)`` is the number of free cells from the robot's own cell (counted as 1)
up to the first wall straight ahead; leaving the grid counts as a wall. A robot facing a wall
reads 1. The sensor is exact (no noise), as in the maze benchmark of Active Neural Localization
(Chaplot et al., ICLR 2018), so its likelihood is 1 on the poses whose depth equals the reading
and 0 elsewhere.

The depth of every pose is computed once per map (:func:`depth_table`), and with it the
likelihood array of every possible reading (:attr:`DepthSensor.likelihoods`), so a filter update
is one lookup. Arrays are indexed ``[ix, iy, h]``, the axis order of the grid belief
(:class:`~active_loc.beliefs.grid.GridBelief`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from active_loc.maps.occupancy import FREE, OccupancyGrid

N_HEADINGS = 4


@numba.njit(cache=True, nogil=True)
def depth_table_kernel(free: NDArray, out: NDArray) -> None:
    """Depth ``out[ix, iy, h]`` (int64) of every pose of a ``(X, Y)`` bool free mask; 0 on
    occupied cells."""
    nx, ny = free.shape
    for x in range(nx):
        for y in range(ny):
            for h in range(N_HEADINGS):
                dx = 1 if h == 0 else (-1 if h == 2 else 0)
                dy = 1 if h == 1 else (-1 if h == 3 else 0)
                d = 0
                cx, cy = x, y
                while 0 <= cx < nx and 0 <= cy < ny and free[cx, cy]:
                    d += 1
                    cx += dx
                    cy += dy
                out[x, y, h] = d


@numba.njit(cache=True, nogil=True)
def reading_likelihood(table: NDArray, z: int, out: NDArray) -> None:
    """``p(z | pose)`` of the exact sensor for every pose of a depth ``table`` ``(X, Y, 4)``,
    into ``out`` ``(X, Y, 4)`` float64: 1.0 where the table equals ``z``, else 0.0 (a reading
    of 0 has likelihood 0 everywhere: no free pose reads it)."""
    nx, ny, nh = table.shape
    for x in range(nx):
        for y in range(ny):
            for h in range(nh):
                out[x, y, h] = 1.0 if z >= 1 and table[x, y, h] == z else 0.0


def _free_mask(free: ArrayLike) -> NDArray[np.bool_]:
    mask = np.asarray(free)
    if mask.ndim != 2 or mask.size == 0:
        raise ValueError(f"free must be a non-empty (X, Y) bool array, got shape {mask.shape}")
    if mask.dtype != np.bool_:
        raise ValueError(f"free must be a bool array (True = free cell), got dtype {mask.dtype}")
    return np.ascontiguousarray(mask)


def depth_table(free: ArrayLike) -> NDArray[np.int64]:
    """Depth ``(X, Y, 4)`` int64 of every pose ``(ix, iy, h)`` of the free mask ``(X, Y)``
    (True = free, indexed ``[ix, iy]``); 0 on occupied cells, >= 1 on free ones."""
    mask = _free_mask(free)
    out = np.empty((*mask.shape, N_HEADINGS), dtype=np.int64)
    depth_table_kernel(mask, out)
    return out


@dataclass(frozen=True, eq=False)
class DepthSensor:
    """The exact depth sensor of one map, with every pose's reading precomputed.

    Build it with :meth:`from_free` or :meth:`from_grid`.

    Attributes:
        table: ``(X, Y, 4)`` int64 read-only: the depth of every pose ``(ix, iy, h)``, 0 on
            occupied cells.
        likelihoods: ``(D + 1, X, Y, 4)`` float64 read-only, ``D`` = the largest depth:
            ``likelihoods[z]`` is the likelihood of reading ``z`` (``likelihoods[0]`` is all
            zeros).
    """

    table: NDArray[np.int64]
    likelihoods: NDArray[np.float64]

    @classmethod
    def from_free(cls, free: ArrayLike) -> DepthSensor:
        """The sensor of a free mask ``(X, Y)`` bool, indexed ``[ix, iy]``."""
        table = depth_table(free)
        likelihoods = np.empty((int(table.max()) + 1, *table.shape))
        for z in range(likelihoods.shape[0]):
            reading_likelihood(table, z, likelihoods[z])
        table.setflags(write=False)
        likelihoods.setflags(write=False)
        return cls(table, likelihoods)

    @classmethod
    def from_grid(cls, grid: OccupancyGrid) -> DepthSensor:
        """The sensor of an occupancy grid: FREE cells are free, every other cell a wall."""
        return cls.from_free(np.ascontiguousarray(grid.values.T == FREE))

    @property
    def max_depth(self) -> int:
        """The largest reading any pose of the map gives (cells)."""
        return int(self.likelihoods.shape[0] - 1)

    def measure(self, pose: ArrayLike) -> int:
        """The reading (cells) at pose ``(ix, iy, h)`` (integers); 0 on an occupied cell."""
        ix, iy, h = (int(v) for v in np.asarray(pose).reshape(3))
        return int(self.table[ix, iy, h])

    def likelihood(self, z: int) -> NDArray[np.float64]:
        """``p(z | pose)`` for every pose, ``(X, Y, 4)`` read-only; all zeros for a reading no
        pose of the map gives."""
        z = int(z)
        if 1 <= z <= self.max_depth:
            return self.likelihoods[z]
        return self.likelihoods[0]

    def __setstate__(self, state: dict) -> None:
        for value in state.values():
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
        self.__dict__.update(state)
