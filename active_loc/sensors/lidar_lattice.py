"""The lidar likelihood field scored at every pose of a lattice: a grid belief's cell poses.

MCL scores a few thousand scattered particles; a grid belief
(:class:`~active_loc.beliefs.grid.GridBelief`) scores every free cell at every heading bin,
tens of thousands of poses on a lattice laid over the map. There, the end point of beam ``j``
from a cell in heading bin ``h`` is the cell's centre plus an offset that depends on ``(h, j)``
only, so the offsets are rotated once per scan (``H x M`` rotations instead of one per pose and
beam), the map column of each lattice column and the map row of each lattice row are found
once per heading and beam, and each pose and beam costs one lookup in the likelihood field's
per-cell table (:meth:`LidarSensor.log_table
<active_loc.sensors.lidar.LidarSensor.log_table>`, framed by the off-map value). The numbers
are :meth:`LidarSensor.field_log_likelihood
<active_loc.sensors.lidar.LidarSensor.field_log_likelihood>`'s at
:meth:`GridBelief.cell_poses <active_loc.beliefs.grid.GridBelief.cell_poses>` (up to the
rounding of an end point that falls exactly on a map cell's border).

Coordinates are the map's continuous grid coordinates (cells of the map's resolution, origin at
the map's origin, axes along its yaw): the lattice shares the map's origin and yaw, so a grid
belief's heading bin ``h`` has the heading ``2 pi h / H`` in that frame.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from active_loc.parallel import parallel_twin, pick
from active_loc.sensors.lidar import MAX_READING_TOL, PROB_FLOOR, LidarSensor


def padded_table(log_table: NDArray, log_p_off_map: float) -> NDArray[np.float64]:
    """The per-cell table ``(ny, nx)`` transposed and framed by one cell of
    ``log_p_off_map`` on every side: ``(nx + 2, ny + 2)``, indexed ``[ix + 1, iy + 1]``, so
    that an end point off the map reads the frame instead of taking a branch."""
    ny, nx = log_table.shape
    out = np.full((nx + 2, ny + 2), float(log_p_off_map))
    out[1:-1, 1:-1] = np.asarray(log_table, dtype=np.float64).T
    return out


@numba.njit(cache=True, nogil=True)
def lattice_field_kernel(
    z: NDArray,
    beam_angles: NDArray,
    headings: NDArray,
    col_base: NDArray,
    row_base: NDArray,
    free: NDArray,
    table: NDArray,
    inv_resolution: float,
    max_range: float,
    scale: float,
    out: NDArray,
) -> None:
    """Likelihood-field log-likelihood of scan ``z`` ``(M,)`` (m) at every lattice pose, times
    ``scale``.

    The end point of a beam from cell ``(ix, iy)`` lands in map cell
    ``(floor(col_base[ix] + ex), floor(row_base[iy] + ey))`` with ``(ex, ey)`` the beam's
    offset for the heading: per heading and beam, the map column of every lattice column and
    the map row of every lattice row are found once, and each cell adds one table entry.

    Args:
        z: ``(M,)`` ranges (m); max readings (``>= max_range (1 - 1e-6)``) are skipped.
        beam_angles: ``(M,)`` beam directions relative to the heading (rad).
        headings: ``(H,)`` headings of the lattice in the map's grid frame (rad).
        col_base, row_base: ``(X,)`` and ``(Y,)`` the lattice cells' centres in the map's
            continuous grid coordinates (map cells).
        free: ``(X, Y)`` bool: cells to score; the others get ``-inf``.
        table: ``(nx + 2, ny + 2)`` the field's per-cell log-probabilities framed by the
            off-map value (:func:`padded_table`).
        inv_resolution: 1 / the map's resolution (1/m).
        max_range: the sensor's maximum range (m).
        scale: the factor of every log-likelihood (a filter's exponent; > 0).
        out: ``(X, Y, H)`` log-likelihoods (overwritten).
    """
    nx_map = table.shape[0] - 2
    ny_map = table.shape[1] - 2
    n_x = col_base.shape[0]
    n_y = row_base.shape[0]
    nh = headings.shape[0]
    n_beams = z.shape[0]
    threshold = max_range * (1.0 - MAX_READING_TOL)
    for h in numba.prange(nh):  # headings are independent: in parallel in the twin
        cols = np.empty(n_x, dtype=np.int64)
        rows = np.empty(n_y, dtype=np.int64)
        acc = np.zeros((n_x, n_y))
        for m in range(n_beams):
            if z[m] >= threshold:
                continue
            r = max(z[m], 0.0) * inv_resolution
            angle = headings[h] + beam_angles[m]
            ex = r * math.cos(angle)
            ey = r * math.sin(angle)
            for i in range(n_x):
                u = col_base[i] + ex
                cols[i] = int(u) + 1 if 0.0 <= u < nx_map else 0
            for i in range(n_y):
                v = row_base[i] + ey
                rows[i] = int(v) + 1 if 0.0 <= v < ny_map else 0
            for i in range(n_x):
                column = table[cols[i]]
                for k in range(n_y):
                    acc[i, k] += column[rows[k]]
        for i in range(n_x):
            for k in range(n_y):
                out[i, k, h] = acc[i, k] * scale if free[i, k] else -np.inf


lattice_field_kernel_parallel = parallel_twin(lattice_field_kernel)


def lattice_field_log_likelihood(
    sensor: LidarSensor,
    z: NDArray,
    headings: NDArray,
    col_base: NDArray,
    row_base: NDArray,
    free: NDArray,
    resolution: float,
    table: NDArray,
    out: NDArray | None = None,
    beams: NDArray | None = None,
    scale: float = 1.0,
) -> NDArray[np.float64]:
    """The likelihood-field log-likelihood ``(X, Y, H)`` of scan ``z`` ``(M,)`` at the lattice
    of columns ``col_base`` ``(X,)``, rows ``row_base`` ``(Y,)`` (map grid coordinates) and
    ``headings`` ``(H,)`` (rad, map grid frame); ``-inf`` where ``free`` ``(X, Y)`` is False.
    ``table`` is :func:`padded_table` of the sensor's :meth:`~LidarSensor.log_table` on a map
    of ``resolution`` m; ``beams`` (indices) scores a subset of the beams; ``scale`` (> 0)
    multiplies every value (a tempered filter's exponent, applied here rather than in a pass
    of its own). Inputs are trusted (the caller built them)."""
    if out is None:
        out = np.empty((col_base.shape[0], row_base.shape[0], headings.shape[0]))
    angles = sensor.beam_angles
    if beams is not None:
        z, angles = np.ascontiguousarray(z[beams]), np.ascontiguousarray(angles[beams])
    pick(lattice_field_kernel, lattice_field_kernel_parallel)(
        z, angles, headings, col_base, row_base, free, table, 1.0 / resolution,
        sensor.max_range, float(scale), out,
    )
    return out


def off_map_log_probability(sensor: LidarSensor) -> float:
    """The likelihood field's log-probability of an end point off the map,
    ``log(z_rand / max_range)`` (floored as the sensor's)."""
    return math.log(max(sensor.z_rand / sensor.max_range, PROB_FLOOR))
