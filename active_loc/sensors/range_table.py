"""Precomputed ray casting for the beam model: a range per grid cell and heading bin.

The beam model needs the expected range ``z*`` of every particle and beam, one ray cast each
(60 beams x 1000 particles is 60,000 casts a step). For a map that does not change, every
cast can be done once: :class:`RangeTable` holds the range from the centre of each free cell
along ``n_angles`` world directions, computed with the exact :func:`~.lidar.cast_ray`, and a
particle's ray is looked up at its cell and nearest direction (the "giant lookup table" of
Walsh and Karaman, "CDDT: Fast approximate 2D ray casting for accelerated localization",
ICRA 2018). The price is quantization: a ray starts at the cell centre (at most
``resolution / sqrt(2)`` from the particle) and leaves along the nearest bin direction (at
most ``pi / n_angles`` off).

The beam model's log-probability is tabulated too, over quantized measured and expected ranges
(:func:`beam_log_prob_table`), so that scoring a beam is two lookups instead of two ``exp``, an
``expm1`` and a ``log``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from active_loc.sensors.lidar import (
    _PARALLEL,
    GridArrays,
    LidarSensor,
    _reflects,
    _unpack_grid,
    beam_probability,
    cast_ray,
)

#: the range step of the tables (m): ranges are stored as multiples of it
RANGE_QUANTUM = 0.01
_TWO_PI = 2.0 * math.pi


@numba.njit(cache=True, nogil=True, parallel=_PARALLEL)
def build_range_table(
    values: NDArray,
    resolution: float,
    ox: float,
    oy: float,
    cos_yaw: float,
    sin_yaw: float,
    n_angles: int,
    max_range: float,
    quantum: float,
    unknown_reflects: bool,
    out: NDArray,
) -> None:
    """Ray-cast from every cell centre along every bin direction.

    Args:
        values, resolution, ox, oy, cos_yaw, sin_yaw: the grid, as in :func:`~.lidar.cast_ray`.
        n_angles: A, world directions ``-pi + 2 pi a / A`` for ``a = 0 .. A - 1``.
        max_range: range of a ray that hits nothing (m).
        quantum: range unit of the table (m).
        unknown_reflects: whether unknown cells stop a ray.
        out: ``(ny, nx, A)`` uint16 out: ranges in units of ``quantum``, rounded; 0 in cells
            that reflect (a particle there has weight 0 anyway).
    """
    ny, nx = values.shape
    step = _TWO_PI / n_angles
    for iy in numba.prange(ny):
        for ix in range(nx):
            if _reflects(values[iy, ix], unknown_reflects):
                out[iy, ix, :] = 0
                continue
            gx = (ix + 0.5) * resolution
            gy = (iy + 0.5) * resolution
            x = ox + cos_yaw * gx - sin_yaw * gy
            y = oy + sin_yaw * gx + cos_yaw * gy
            for a in range(n_angles):
                r = cast_ray(values, resolution, ox, oy, cos_yaw, sin_yaw, x, y,
                             -math.pi + a * step, max_range, unknown_reflects)
                out[iy, ix, a] = int(r / quantum + 0.5)


@numba.njit(cache=True, nogil=True)
def beam_log_prob_table(
    n_levels: int,
    quantum: float,
    max_range: float,
    z_hit: float,
    z_short: float,
    z_max: float,
    z_rand: float,
    sigma_hit: float,
    lambda_short: float,
) -> NDArray:
    """``log p(z | z*)`` of the beam model at ``z = i quantum``, ``z* = j quantum`` for
    ``i, j < n_levels``: shape ``(n_levels, n_levels)``; row i is one measured range.
    The model's parameters are those of :func:`~.lidar.beam_probability`."""
    out = np.empty((n_levels, n_levels))
    for i in range(n_levels):
        for j in range(n_levels):
            out[i, j] = math.log(beam_probability(
                i * quantum, j * quantum, max_range, z_hit, z_short, z_max, z_rand, sigma_hit,
                lambda_short,
            ))
    return out


@numba.njit(cache=True, nogil=True, parallel=_PARALLEL)
def range_table_log_likelihood(
    z_levels: NDArray,
    beam_angles: NDArray,
    poses: NDArray,
    ranges: NDArray,
    log_probs: NDArray,
    resolution: float,
    ox: float,
    oy: float,
    cos_yaw: float,
    sin_yaw: float,
    out: NDArray,
) -> None:
    """Beam-model log-likelihood of one scan per pose, with the expected ranges looked up.

    Args:
        z_levels: ``(M,)`` int64 measured ranges in units of the table's quantum.
        beam_angles: ``(M,)`` beam directions relative to the heading (rad).
        poses: ``(K, 3)`` particle poses (m, rad).
        ranges: ``(ny, nx, A)`` uint16 table of :func:`build_range_table`.
        log_probs: ``(L, L)`` table of :func:`beam_log_prob_table`, L above every level.
        resolution, ox, oy, cos_yaw, sin_yaw: the grid the table was built on.
        out: ``(K,)`` out: ``sum_m log p(z_m | z*_km)`` (nats). A pose off the map scores as
            if every beam expected ``max_range`` (the filter gives it weight 0 anyway).
    """
    ny, nx, n_angles = ranges.shape
    n_beams = z_levels.shape[0]
    top = log_probs.shape[1] - 1
    bins_per_rad = n_angles / _TWO_PI
    inv_res = 1.0 / resolution
    for k in numba.prange(poses.shape[0]):
        rx = poses[k, 0] - ox
        ry = poses[k, 1] - oy
        gx = (cos_yaw * rx + sin_yaw * ry) * inv_res
        gy = (-sin_yaw * rx + cos_yaw * ry) * inv_res
        total = 0.0
        if 0.0 <= gx < nx and 0.0 <= gy < ny:
            cell = ranges[int(gy), int(gx)]
            # bin of the heading's world direction, rounded: beams then offset from it
            base = (poses[k, 2] + math.pi) * bins_per_rad + 0.5
            for m in range(n_beams):
                a = math.floor(base + beam_angles[m] * bins_per_rad) % n_angles
                total += log_probs[z_levels[m], min(int(cell[a]), top)]
        else:
            for m in range(n_beams):
                total += log_probs[z_levels[m], top]
        out[k] = total


@dataclass(frozen=True, eq=False)
class RangeTable:
    """A lidar's beam model on one fixed grid, with ray casting and scoring precomputed.

    Build it once per map with :meth:`build` (about ``nx ny n_angles`` casts: seconds for a
    200 x 200 grid at 360 bins, and ``2 nx ny n_angles`` bytes), then score scans with
    :meth:`log_likelihood`.

    Attributes:
        lidar: the sensor (its beam-model parameters and beam geometry).
        grid_arrays: the grid, as ``(values, resolution, ox, oy, cos_yaw, sin_yaw)``.
        ranges: ``(ny, nx, A)`` uint16 ranges in units of ``quantum``.
        log_probs: ``(L, L)`` beam-model log-probabilities over quantized (z, z*).
        quantum: range unit (m).
    """

    lidar: LidarSensor
    grid_arrays: GridArrays
    ranges: NDArray[np.uint16]
    log_probs: NDArray[np.float64]
    quantum: float

    @classmethod
    def build(
        cls, lidar: LidarSensor, grid_arrays: GridArrays, n_angles: int = 360,
        quantum: float = RANGE_QUANTUM,
    ) -> RangeTable:
        """Cast every cell centre x ``n_angles`` directions and tabulate the beam model.

        Raises:
            ValueError: on a bad grid, ``n_angles < 4``, or a quantum outside (0, max_range).
        """
        values, res, ox, oy, c, s = _unpack_grid(grid_arrays)
        if isinstance(n_angles, (bool, np.bool_)) or not isinstance(n_angles, (int, np.integer)) \
                or n_angles < 4:
            raise ValueError(f"RangeTable.n_angles must be an integer >= 4, got {n_angles!r}")
        quantum = float(quantum)
        if not (np.isfinite(quantum) and 0.0 < quantum < lidar.max_range):
            raise ValueError(f"RangeTable.quantum must be in (0, max_range = "
                             f"{lidar.max_range}) m, got {quantum}")
        n_levels = math.ceil(lidar.max_range / quantum) + 1
        if n_levels > np.iinfo(np.uint16).max:
            raise ValueError(f"RangeTable: max_range / quantum = {n_levels - 1} levels do not "
                             f"fit in uint16; use a larger quantum")
        ranges = np.empty((*values.shape, int(n_angles)), dtype=np.uint16)
        build_range_table(values, res, ox, oy, c, s, int(n_angles), lidar.max_range, quantum,
                          lidar.unknown_reflects, ranges)
        log_probs = beam_log_prob_table(
            n_levels, quantum, lidar.max_range, lidar.z_hit, lidar.z_short, lidar.z_max,
            lidar.z_rand, lidar.sigma_hit, lidar.lambda_short,
        )
        ranges.setflags(write=False)
        log_probs.setflags(write=False)
        return cls(lidar, (values, res, ox, oy, c, s), ranges, log_probs, quantum)

    @property
    def n_angles(self) -> int:
        """Number of direction bins A."""
        return int(self.ranges.shape[2])

    def levels(self, z: NDArray) -> NDArray[np.int64]:
        """Measured ranges ``(M,)`` (m; ``inf`` is a max reading) as table rows."""
        top = self.log_probs.shape[0] - 1
        clipped = np.clip(np.nan_to_num(z, posinf=self.lidar.max_range), 0.0,
                          self.lidar.max_range)
        return np.minimum(np.rint(clipped / self.quantum).astype(np.int64), top)

    def log_likelihood(
        self, z: NDArray, poses: NDArray, out: NDArray | None = None
    ) -> NDArray[np.float64]:
        """Beam-model log-likelihoods ``(K,)`` (nats) of scan ``z`` ``(M,)`` for poses
        ``(K, 3)``. Inputs are trusted (the caller validated them), as on the filter's path."""
        if out is None:
            out = np.empty(poses.shape[0])
        _, res, ox, oy, c, s = self.grid_arrays
        range_table_log_likelihood(self.levels(z), self.lidar.beam_angles, poses, self.ranges,
                                   self.log_probs, res, ox, oy, c, s, out)
        return out
