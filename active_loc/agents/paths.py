"""Shortest paths on an occupancy grid, for planners that choose where to go.

The robot is a disc: a cell is traversable when it is free and its centre is at least
``clearance`` (m) from the nearest obstacle (the map's distance field). Paths run between cell
centres with 8-connectivity (a step costs ``resolution`` or ``sqrt(2) resolution`` metres),
computed with scipy's Dijkstra on a sparse graph that is built once per map and clearance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from active_loc.maps import FREE, OccupancyGrid

#: the 4 of the 8 neighbour offsets (row, column) that, with their opposites, make every edge
_HALF_NEIGHBOURS = ((0, 1), (1, 0), (1, 1), (1, -1))


@dataclass(frozen=True)
class PathGraph:
    """The traversable cells of one map as a graph.

    Attributes:
        grid: the map.
        clearance: the least distance (m) from a traversable cell's centre to an obstacle.
        node_of: ``(ny, nx)`` int64, the node index of each cell, -1 where not traversable.
        cells: ``(N, 2)`` int64 ``(ix, iy)`` of each node.
        centres: ``(N, 2)`` world centres (m) of the nodes.
        matrix: the ``(N, N)`` sparse matrix of edge lengths (m).
    """

    grid: OccupancyGrid
    clearance: float
    node_of: NDArray[np.int64]
    cells: NDArray[np.int64]
    centres: NDArray[np.float64]
    matrix: coo_matrix

    @classmethod
    def build(cls, grid: OccupancyGrid, clearance: float) -> PathGraph:
        """The graph of ``grid``'s cells at least ``clearance`` (m, >= 0) from an obstacle."""
        if not (math.isfinite(clearance) and clearance >= 0.0):
            raise ValueError(f"PathGraph: clearance must be finite and >= 0 (m), got {clearance}")
        traversable = (grid.values == FREE) & (grid.distance_field() >= clearance)
        ny, nx = traversable.shape
        node_of = np.full((ny, nx), -1, dtype=np.int64)
        iy, ix = np.nonzero(traversable)
        node_of[iy, ix] = np.arange(iy.size)
        rows, cols, lengths = [], [], []
        for dy, dx in _HALF_NEIGHBOURS:
            y0, y1 = max(0, -dy), ny - max(0, dy)
            x0, x1 = max(0, -dx), nx - max(0, dx)
            a = node_of[y0:y1, x0:x1]
            b = node_of[y0 + dy:y1 + dy, x0 + dx:x1 + dx]
            both = (a >= 0) & (b >= 0)
            rows.append(a[both])
            cols.append(b[both])
            lengths.append(np.full(int(both.sum()), grid.resolution * math.hypot(dx, dy)))
        r, c, w = np.concatenate(rows), np.concatenate(cols), np.concatenate(lengths)
        matrix = coo_matrix((np.concatenate([w, w]), (np.concatenate([r, c]),
                                                      np.concatenate([c, r]))),
                            shape=(iy.size, iy.size))
        cells = np.stack([ix, iy], axis=-1)
        return cls(grid, float(clearance), node_of, cells, grid.cell_to_world(cells),
                   matrix.tocsr())

    @property
    def n_nodes(self) -> int:
        return int(self.cells.shape[0])

    def nearest_node(self, point: NDArray[np.float64], max_distance: float) -> int:
        """The node whose centre is nearest ``point`` ``(2,)`` (m), or -1 if none lies within
        ``max_distance`` (m)."""
        if self.n_nodes == 0:
            return -1
        d2 = np.sum((self.centres - np.asarray(point)[None, :2]) ** 2, axis=1)
        best = int(np.argmin(d2))
        return best if d2[best] <= max_distance**2 else -1

    def shortest_paths(self, start: int) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """Path lengths ``(N,)`` (m; inf where unreachable) from node ``start`` and each node's
        predecessor ``(N,)`` on its shortest path (negative for the start and unreachable)."""
        lengths, predecessors = dijkstra(self.matrix, indices=start, return_predecessors=True)
        return lengths, predecessors.astype(np.int64)

    def path_to(self, predecessors: NDArray[np.int64], node: int) -> NDArray[np.float64]:
        """The world centres ``(P, 2)`` (m) of the nodes from the start to ``node``."""
        chain = [node]
        while predecessors[chain[-1]] >= 0:
            chain.append(int(predecessors[chain[-1]]))
        return self.centres[chain[::-1]]


def farthest_points(points: NDArray[np.float64], first: int, count: int) -> NDArray[np.int64]:
    """Indices of ``count`` of ``points`` ``(N, 2)`` spread out by farthest-point sampling,
    starting with ``first`` (fewer when there are fewer points)."""
    count = min(int(count), points.shape[0])
    chosen = [int(first)]
    nearest = np.sum((points - points[first]) ** 2, axis=1)
    while len(chosen) < count:
        pick = int(np.argmax(nearest))
        if nearest[pick] == 0.0:
            break
        chosen.append(pick)
        nearest = np.minimum(nearest, np.sum((points - points[pick]) ** 2, axis=1))
    return np.array(chosen, dtype=np.int64)


def thin_path(path: NDArray[np.float64], spacing: float) -> NDArray[np.float64]:
    """Waypoints ``(W, 2)`` along ``path`` ``(P, 2)`` about ``spacing`` m apart; the last
    point is kept, the first (where the robot stands) dropped."""
    if path.shape[0] <= 1:
        return path[-1:].copy()
    steps = np.hypot(*np.diff(path, axis=0).T)
    along = np.concatenate([[0.0], np.cumsum(steps)])
    marks = np.arange(spacing, along[-1], spacing)
    picks = np.searchsorted(along, marks)
    keep = np.unique(np.concatenate([picks, [path.shape[0] - 1]]))
    return path[keep]
