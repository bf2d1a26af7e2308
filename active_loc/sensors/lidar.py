"""A planar lidar on an occupancy grid: exact ray casting and the two range-finder models.

The measurement models are those of Thrun, Burgard and Fox, *Probabilistic Robotics* (MIT
Press, 2005), chapter 6:

* the **beam model** (section 6.3, table 6.1): each beam's range is a mixture of a Gaussian hit
  around the ray-cast range ``z*`` (truncated to ``[0, z_max]``), an exponential for unexpected
  short readings (truncated to ``[0, z*]``), a point mass at the maximum range and a uniform
  random reading;
* the **likelihood field** (section 6.4, table 6.3; the default of ROS AMCL): a beam's end point
  is scored by its distance ``d`` to the nearest obstacle, ``z_hit N(d; 0, sigma_hit^2) +
  z_rand / z_max``; max readings carry no end point and are skipped.

Grid convention (shared with :class:`active_loc.maps.OccupancyGrid`, which the kernels do not
import; they take plain arrays):

* ``values`` is an ``(ny, nx)`` int8 array, FREE = 0, OCCUPIED = 100, UNKNOWN = -1. A cell
  reflects a beam when its value is ``>= OCCUPIED_THRESHOLD`` (50; ROS percentages), or when it
  is negative (unknown) and ``unknown_reflects`` is set. Values 0..49 are free.
* Row ``iy = 0`` is at the bottom: world y grows with the row index. Cell ``(ix, iy)`` is
  ``values[iy, ix]`` and covers ``[ix, ix + 1) x [iy, iy + 1)`` in continuous grid coordinates.
* The origin ``(ox, oy, yaw)`` is the world pose of the bottom-left corner of cell (0, 0); a
  world point maps to grid coordinates by ``gx = (c (x - ox) + s (y - oy)) / res``,
  ``gy = (-s (x - ox) + c (y - oy)) / res`` with ``c, s = cos(yaw), sin(yaw)``.
* Outside the grid nothing reflects: a beam that leaves the map before hitting anything reads
  ``max_range`` (no return), and a beam that starts off the map travels until it enters it.

A sensor's configuration is the frozen dataclass :class:`LidarSensor`; the map is passed as the
tuple ``grid_arrays = (values, resolution, ox, oy, cos_yaw, sin_yaw)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from active_loc.parallel import parallel_twin, pick

#: a cell whose value is at least this (percent) reflects a beam
OCCUPIED_THRESHOLD = 50
#: a reading ``z >= max_range * (1 - MAX_READING_TOL)`` is a max reading (no return); relative,
#: so that a max range that went through float32 (rel. precision 6e-8) still counts
MAX_READING_TOL = 1e-6
#: each beam's probability is floored here so that its log is finite even when z_rand = 0
PROB_FLOOR = 1e-300

# a direction component this small is treated as exactly 0: cos(pi/2) is 6e-17, not 0, and
# without the snap a beam along a grid line would wander to the neighbouring row or column
_AXIS_SNAP = 1e-12
# two cell-border crossings closer than this (cells) along a ray are one crossing of a corner
_TIE_TOL = 1e-9
_SQRT_2 = math.sqrt(2.0)
_SQRT_2PI = math.sqrt(2.0 * math.pi)

# Serial on purpose. Measured on 2 cores (1000 poses x 60 beams, 200 x 200 grid), prange over
# the poses was ~2x faster for the ray cast and the beam model and ~1.5x for the likelihood
# field, but the only threading layer here is GNU OpenMP, which kills a child forked after a
# parallel kernel ran ("fork() called from a process already using GNU OpenMP"): that breaks
# fork-based vector envs (gymnasium AsyncVectorEnv's default context on Linux, SB3's
# SubprocVecEnv with fork). Vector envs parallelize across processes anyway.
_PARALLEL = False

GridArrays = tuple[NDArray[np.int8], float, float, float, float, float]


# --------------------------------------------------------------------------- ray casting


@numba.njit(cache=True, nogil=True, inline="always")
def _reflects(value: int, unknown_reflects: bool) -> bool:
    """Whether a cell with occupancy ``value`` stops a beam."""
    return value >= OCCUPIED_THRESHOLD or (unknown_reflects and value < 0)


@numba.njit(cache=True, nogil=True)
def cast_ray(
    values: NDArray,
    resolution: float,
    ox: float,
    oy: float,
    cos_yaw: float,
    sin_yaw: float,
    x: float,
    y: float,
    angle: float,
    max_range: float,
    unknown_reflects: bool,
) -> float:
    """Range (m) from ``(x, y)`` along world direction ``angle`` to the first reflecting cell.

    Exact grid traversal (Amanatides and Woo, "A fast voxel traversal algorithm", 1987) in grid
    coordinates: the cells the ray crosses are visited in order and the distance returned is
    where the ray enters the first reflecting one (its boundary), or ``max_range`` if there is
    none within range or the ray leaves the map. A start inside a reflecting cell returns 0.

    Exact ties, which only arise for beams along grid lines or through cell corners:

    * a beam exactly along a grid line stays in the half-open row (column) of its start;
    * a beam through a cell corner (within ``1e-9`` cells: cos and sin of 45 degrees differ in
      the last bit) is stopped there if either cell it touches at the corner reflects, so
      rasterized diagonal walls do not leak and a diagonal beam does not depend on rounding.

    Args:
        values: ``(ny, nx)`` int8 occupancy, row 0 at the bottom (see the module docstring).
        resolution: cell size (m).
        ox, oy: world position (m) of the bottom-left corner of cell (0, 0).
        cos_yaw, sin_yaw: cosine and sine of the grid's yaw in the world.
        x, y: ray start in the world (m).
        angle: ray direction in the world (rad).
        max_range: range returned when nothing reflects (m).
        unknown_reflects: whether unknown cells (negative values) stop the beam.

    Returns:
        Range in ``[0, max_range]`` (m); NaN for a non-finite start or angle.
    """
    ny, nx = values.shape
    rx = x - ox
    ry = y - oy
    gx = (cos_yaw * rx + sin_yaw * ry) / resolution
    gy = (-sin_yaw * rx + cos_yaw * ry) / resolution
    ca = np.cos(angle)
    sa = np.sin(angle)
    # the direction in grid coordinates is still a unit vector: ray parameter t is in cells
    dx = cos_yaw * ca + sin_yaw * sa
    dy = -sin_yaw * ca + cos_yaw * sa
    if not (np.isfinite(gx) and np.isfinite(gy) and np.isfinite(dx) and np.isfinite(dy)):
        return np.nan
    if abs(dx) < _AXIS_SNAP:
        dx = 0.0
    if abs(dy) < _AXIS_SNAP:
        dy = 0.0
    max_t = max_range / resolution

    t = 0.0
    if 0.0 <= gx < nx and 0.0 <= gy < ny:
        ix = int(np.floor(gx))
        iy = int(np.floor(gy))
    else:
        # off-map start: jump to where the ray enters the box [0, nx] x [0, ny] (slab test)
        t_enter = 0.0
        t_exit = np.inf
        if dx == 0.0:
            if gx < 0.0 or gx >= nx:
                return max_range
        else:
            t1 = -gx / dx
            t2 = (nx - gx) / dx
            t_enter = max(t_enter, min(t1, t2))
            t_exit = min(t_exit, max(t1, t2))
        if dy == 0.0:
            if gy < 0.0 or gy >= ny:
                return max_range
        else:
            t1 = -gy / dy
            t2 = (ny - gy) / dy
            t_enter = max(t_enter, min(t1, t2))
            t_exit = min(t_exit, max(t1, t2))
        if t_enter >= t_exit or t_enter > max_t:
            return max_range
        t = t_enter
        # the entry point lies on the border: clamp to the cell inside
        ix = min(max(int(np.floor(gx + t * dx)), 0), nx - 1)
        iy = min(max(int(np.floor(gy + t * dy)), 0), ny - 1)

    step_x = 1 if dx > 0.0 else -1
    step_y = 1 if dy > 0.0 else -1
    inv_dx = 1.0 / dx if dx != 0.0 else 0.0
    inv_dy = 1.0 / dy if dy != 0.0 else 0.0
    # ray parameter of the next x (y) cell border, recomputed from the start at every step
    # rather than accumulated, so that rounding does not build up along long rays
    t_max_x = ((ix + 1 if dx > 0.0 else ix) - gx) * inv_dx if dx != 0.0 else np.inf
    t_max_y = ((iy + 1 if dy > 0.0 else iy) - gy) * inv_dy if dy != 0.0 else np.inf

    while True:
        if _reflects(values[iy, ix], unknown_reflects):
            return min(t * resolution, max_range)
        if t_max_x < t_max_y - _TIE_TOL:
            t = max(t, t_max_x)
            ix += step_x
            if ix < 0 or ix >= nx:
                return max_range
            t_max_x = ((ix + 1 if dx > 0.0 else ix) - gx) * inv_dx
        elif t_max_y < t_max_x - _TIE_TOL:
            t = max(t, t_max_y)
            iy += step_y
            if iy < 0 or iy >= ny:
                return max_range
            t_max_y = ((iy + 1 if dy > 0.0 else iy) - gy) * inv_dy
        else:
            # through a corner: the ray touches both side cells at one point
            t = max(t, min(t_max_x, t_max_y))
            if t > max_t:
                return max_range
            jx = ix + step_x
            jy = iy + step_y
            if (0 <= jx < nx and _reflects(values[iy, jx], unknown_reflects)) or (
                0 <= jy < ny and _reflects(values[jy, ix], unknown_reflects)
            ):
                return min(t * resolution, max_range)
            ix = jx
            iy = jy
            if ix < 0 or ix >= nx or iy < 0 or iy >= ny:
                return max_range
            t_max_x = ((ix + 1 if dx > 0.0 else ix) - gx) * inv_dx
            t_max_y = ((iy + 1 if dy > 0.0 else iy) - gy) * inv_dy
        if t > max_t:
            return max_range


@numba.njit(cache=True, nogil=True, parallel=_PARALLEL)
def cast_rays(
    values: NDArray,
    resolution: float,
    ox: float,
    oy: float,
    cos_yaw: float,
    sin_yaw: float,
    poses: NDArray,
    beam_angles: NDArray,
    max_range: float,
    unknown_reflects: bool,
    out: NDArray,
) -> None:
    """Ray-cast every pose x beam into ``out``.

    Args:
        values, resolution, ox, oy, cos_yaw, sin_yaw: the grid, as in :func:`cast_ray`.
        poses: ``(K, 3)`` sensor poses ``(x, y, theta)`` in the world (m, rad).
        beam_angles: ``(M,)`` beam directions relative to the heading (rad).
        max_range: range of a beam that hits nothing (m).
        unknown_reflects: whether unknown cells stop a beam.
        out: ``(K, M)`` out: ranges (m).
    """
    for k in numba.prange(poses.shape[0]):
        x = poses[k, 0]
        y = poses[k, 1]
        theta = poses[k, 2]
        for m in range(beam_angles.shape[0]):
            out[k, m] = cast_ray(
                values, resolution, ox, oy, cos_yaw, sin_yaw, x, y, theta + beam_angles[m],
                max_range, unknown_reflects,
            )


# --------------------------------------------------------------------------- beam model


@numba.njit(cache=True, nogil=True)
def beam_probability(
    z: float,
    expected: float,
    max_range: float,
    z_hit: float,
    z_short: float,
    z_max: float,
    z_rand: float,
    sigma_hit: float,
    lambda_short: float,
) -> float:
    """p(z | z*) of one beam under the beam model (Probabilistic Robotics, section 6.3).

    ``p = z_hit p_hit + z_short p_short + z_max p_max + z_rand p_rand`` with

    * ``p_hit``: N(z; z*, sigma_hit^2) normalized over ``[0, max_range]`` (eq. 6.4-6.6);
    * ``p_short``: ``lambda exp(-lambda z) / (1 - exp(-lambda z*))`` on ``[0, z*]`` (eq. 6.7);
      it vanishes for ``z* = 0`` (an empty interval, e.g. a particle inside a wall);
    * ``p_max``: the point mass at the maximum range, counted as a *probability* of 1 when
      ``z >= max_range (1 - MAX_READING_TOL)`` and 0 otherwise (as the book and AMCL do; the
      other terms are densities per metre);
    * ``p_rand``: ``1 / max_range`` on ``[0, max_range]``.

    ``z`` and ``z*`` are clipped to ``[0, max_range]`` (so ``inf`` is a max reading). The
    result is at least ``z_rand / max_range`` and never below ``PROB_FLOOR``.
    """
    z = min(max(z, 0.0), max_range)
    expected = min(max(expected, 0.0), max_range)
    p = z_rand / max_range
    if z >= max_range * (1.0 - MAX_READING_TOL):
        p += z_max
    # the hit Gaussian's mass inside [0, max_range] (its eta, eq. 6.6)
    mass = 0.5 * (
        math.erf((max_range - expected) / (_SQRT_2 * sigma_hit))
        + math.erf(expected / (_SQRT_2 * sigma_hit))
    )
    if mass > 0.0:
        e = (z - expected) / sigma_hit
        p += z_hit * math.exp(-0.5 * e * e) / (_SQRT_2PI * sigma_hit * mass)
    if z <= expected:
        # 1 - exp(-lambda z*) with expm1, accurate for short expected ranges; 0 when z* = 0
        norm = -math.expm1(-lambda_short * expected)
        if norm > 0.0:
            p += z_short * lambda_short * math.exp(-lambda_short * z) / norm
    return max(p, PROB_FLOOR)


@numba.njit(cache=True, nogil=True, parallel=_PARALLEL)
def beam_model_log_likelihood(
    z: NDArray,
    expected: NDArray,
    max_range: float,
    z_hit: float,
    z_short: float,
    z_max: float,
    z_rand: float,
    sigma_hit: float,
    lambda_short: float,
    out: NDArray,
) -> None:
    """Log-likelihood of one scan for each particle under the beam model.

    Args:
        z: ``(M,)`` measured ranges (m); clipped to ``[0, max_range]``.
        expected: ``(K, M)`` ray-cast ranges z* of each particle (m).
        max_range, z_hit, z_short, z_max, z_rand, sigma_hit, lambda_short: the model
            (see :func:`beam_probability`).
        out: ``(K,)`` out: ``sum_m log p(z_m | z*_km)`` (nats), always finite.
    """
    n_beams = z.shape[0]
    for k in numba.prange(expected.shape[0]):
        total = 0.0
        for m in range(n_beams):
            total += math.log(
                beam_probability(
                    z[m], expected[k, m], max_range, z_hit, z_short, z_max, z_rand, sigma_hit,
                    lambda_short,
                )
            )
        out[k] = total


# --------------------------------------------------------------------------- likelihood field


@numba.njit(cache=True, nogil=True)
def likelihood_field_log_likelihood(
    z: NDArray,
    beam_angles: NDArray,
    poses: NDArray,
    distance_field: NDArray,
    resolution: float,
    ox: float,
    oy: float,
    cos_yaw: float,
    sin_yaw: float,
    max_range: float,
    z_hit: float,
    z_rand: float,
    sigma_hit: float,
    out: NDArray,
) -> None:
    """Log-likelihood of one scan for each particle under the likelihood field model.

    Per beam that is not a max reading, its end point ``pose (+) z (cos b, sin b)`` is looked up
    in the distance field (the cell that contains it, no interpolation, as AMCL does) and scored
    ``p = z_hit N(d; 0, sigma_hit^2) + z_rand / max_range`` (Probabilistic Robotics, table 6.3).
    An end point off the map has ``d = inf``, so only the ``z_rand`` term is left. Max readings
    (``z >= max_range (1 - MAX_READING_TOL)``, including ``inf``) are skipped, as in AMCL; a
    negative reading counts as 0. The sensor is at the pose (no mounting offset).

    Args:
        z: ``(M,)`` measured ranges (m).
        beam_angles: ``(M,)`` beam directions relative to the heading (rad).
        poses: ``(K, 3)`` particle poses (m, rad).
        distance_field: ``(ny, nx)`` float64 distance (m) from each cell to the nearest obstacle,
            same layout as the occupancy values.
        resolution, ox, oy, cos_yaw, sin_yaw: the grid, as in :func:`cast_ray`.
        max_range: the sensor's maximum range (m).
        z_hit, z_rand, sigma_hit: the model's weights and hit standard deviation (m).
        out: ``(K,)`` out: ``sum_m log p_m`` (nats), always finite.

    It scores through the per-cell table of :func:`likelihood_field_log_table`, built here for
    the whole grid; a filter that weighs many scans on one map builds it once instead.
    """
    table = likelihood_field_log_table(distance_field, max_range, z_hit, z_rand, sigma_hit)
    log_off_map = math.log(max(z_rand / max_range, PROB_FLOOR))
    likelihood_field_table_log_likelihood(
        z, beam_angles, poses, table, log_off_map, resolution, ox, oy, cos_yaw, sin_yaw,
        max_range, out,
    )


@numba.njit(cache=True, nogil=True)
def likelihood_field_log_table(
    distance_field: NDArray, max_range: float, z_hit: float, z_rand: float, sigma_hit: float
) -> NDArray:
    """The per-cell log-probability of a beam end point under the likelihood field,
    ``log(z_hit N(d; 0, sigma_hit^2) + z_rand / max_range)`` for every cell's distance ``d``:
    computed once per map (AMCL precomputes its field the same way), it turns the per-beam
    ``exp`` and ``log`` into one lookup. Shape of ``distance_field`` ``(ny, nx)``."""
    hit_scale = z_hit / (_SQRT_2PI * sigma_hit)
    half_inv_var = 0.5 / (sigma_hit * sigma_hit)
    p_rand = z_rand / max_range
    out = np.empty(distance_field.shape)
    for i in range(distance_field.shape[0]):
        for j in range(distance_field.shape[1]):
            d = distance_field[i, j]
            out[i, j] = math.log(max(p_rand + hit_scale * math.exp(-d * d * half_inv_var),
                                     PROB_FLOOR))
    return out


@numba.njit(cache=True, nogil=True)
def _end_points_in_sensor_frame(
    z: NDArray, beam_angles: NDArray, max_range: float
) -> tuple[NDArray, NDArray, int]:
    """End points ``(ex, ey)`` (m) in the sensor frame of the beams with a return (max
    readings carry no end point), packed at the front; returns them and their count."""
    n_beams = z.shape[0]
    ex = np.empty(n_beams)
    ey = np.empty(n_beams)
    n_used = 0
    threshold = max_range * (1.0 - MAX_READING_TOL)
    for m in range(n_beams):
        if z[m] >= threshold:
            continue
        r = max(z[m], 0.0)
        ex[n_used] = r * np.cos(beam_angles[m])
        ey[n_used] = r * np.sin(beam_angles[m])
        n_used += 1
    return ex, ey, n_used


@numba.njit(cache=True, nogil=True, parallel=_PARALLEL)
def likelihood_field_table_log_likelihood(
    z: NDArray,
    beam_angles: NDArray,
    poses: NDArray,
    log_table: NDArray,
    log_p_off_map: float,
    resolution: float,
    ox: float,
    oy: float,
    cos_yaw: float,
    sin_yaw: float,
    max_range: float,
    out: NDArray,
) -> None:
    """:func:`likelihood_field_log_likelihood` with the per-cell log-probabilities of
    :func:`likelihood_field_log_table` (same result, one lookup per beam); end points off the
    map score ``log_p_off_map`` = ``log(z_rand / max_range)``. Shapes as there."""
    ny, nx = log_table.shape
    # the end points in the sensor frame are the same for every particle: compute them once
    # and rotate per particle, instead of a sin/cos per particle and beam
    ex, ey, n_used = _end_points_in_sensor_frame(z, beam_angles, max_range)
    inv_res = 1.0 / resolution
    for k in numba.prange(poses.shape[0]):
        c = np.cos(poses[k, 2])
        s = np.sin(poses[k, 2])
        rx0 = poses[k, 0] - ox
        ry0 = poses[k, 1] - oy
        total = 0.0
        for j in range(n_used):
            rx = rx0 + c * ex[j] - s * ey[j]
            ry = ry0 + s * ex[j] + c * ey[j]
            gx = (cos_yaw * rx + sin_yaw * ry) * inv_res
            gy = (-sin_yaw * rx + cos_yaw * ry) * inv_res
            if 0.0 <= gx < nx and 0.0 <= gy < ny:
                total += log_table[int(gy), int(gx)]
            else:
                total += log_p_off_map
        out[k] = total


likelihood_field_table_parallel = parallel_twin(likelihood_field_table_log_likelihood)


@numba.njit(cache=True, nogil=True)
def likelihood_field_skip_log_likelihood(
    z: NDArray,
    beam_angles: NDArray,
    poses: NDArray,
    log_table: NDArray,
    distance_field: NDArray,
    log_p_off_map: float,
    resolution: float,
    ox: float,
    oy: float,
    cos_yaw: float,
    sin_yaw: float,
    max_range: float,
    skip_distance: float,
    skip_threshold: float,
    skip_error_threshold: float,
    out: NDArray,
) -> int:
    """:func:`likelihood_field_table_log_likelihood` with AMCL's beam skipping, the likelihood
    field's outlier rejection for what the map does not hold (people, open doors).

    A beam whose end point lies within ``skip_distance`` (m) of a mapped obstacle for fewer than
    ``skip_threshold`` of the particles is left out for every particle: most hypotheses agree
    it hit something unmapped. If that would leave out more than ``skip_error_threshold`` of
    the beams, the map itself is in doubt (or the particles are spread out), and every beam is
    used. Shapes as in :func:`likelihood_field_table_log_likelihood`; ``distance_field`` is
    ``(ny, nx)`` (m). Returns the number of beams skipped.
    """
    ny, nx = log_table.shape
    n_poses = poses.shape[0]
    ex, ey, n_used = _end_points_in_sensor_frame(z, beam_angles, max_range)
    inv_res = 1.0 / resolution
    # cell of every end point (-1 off the map), and per beam how many particles it agrees with
    cells = np.empty((n_poses, n_used), dtype=np.int64)
    agree = np.zeros(n_used, dtype=np.int64)
    for k in range(n_poses):
        c = np.cos(poses[k, 2])
        s = np.sin(poses[k, 2])
        rx0 = poses[k, 0] - ox
        ry0 = poses[k, 1] - oy
        for j in range(n_used):
            rx = rx0 + c * ex[j] - s * ey[j]
            ry = ry0 + s * ex[j] + c * ey[j]
            gx = (cos_yaw * rx + sin_yaw * ry) * inv_res
            gy = (-sin_yaw * rx + cos_yaw * ry) * inv_res
            if 0.0 <= gx < nx and 0.0 <= gy < ny:
                cell = int(gy) * nx + int(gx)
                cells[k, j] = cell
                if distance_field.flat[cell] < skip_distance:
                    agree[j] += 1
            else:
                cells[k, j] = -1
    keep = np.empty(n_used, dtype=np.bool_)
    n_skipped = 0
    for j in range(n_used):
        keep[j] = agree[j] >= skip_threshold * n_poses
        n_skipped += not keep[j]
    if n_skipped > skip_error_threshold * n_used:
        keep[:] = True
        n_skipped = 0
    flat = log_table.ravel()
    for k in range(n_poses):
        total = 0.0
        for j in range(n_used):
            if keep[j]:
                cell = cells[k, j]
                total += flat[cell] if cell >= 0 else log_p_off_map
        out[k] = total
    return n_skipped


@numba.njit(cache=True, nogil=True)
def occlude_ranges(
    x: float, y: float, theta: float, beam_angles: NDArray, discs: NDArray, ranges: NDArray
) -> None:
    """Shorten ``ranges`` ``(M,)`` (m) in place where a beam from ``(x, y)`` along
    ``theta + beam_angles[m]`` meets one of ``discs`` ``(P, 3)`` (centre x, y and radius, m)
    before its current range; a sensor inside a disc reads 0 on every beam."""
    for m in range(beam_angles.shape[0]):
        a = theta + beam_angles[m]
        dx = np.cos(a)
        dy = np.sin(a)
        for p in range(discs.shape[0]):
            ex = discs[p, 0] - x
            ey = discs[p, 1] - y
            r = discs[p, 2]
            c = ex * ex + ey * ey - r * r
            if c <= 0.0:
                ranges[m] = 0.0
                continue
            b = ex * dx + ey * dy
            disc = b * b - c
            if b <= 0.0 or disc < 0.0:
                continue
            t = b - math.sqrt(disc)
            if t < ranges[m]:
                ranges[m] = t


# --------------------------------------------------------------------------- the sensor


def _unpack_grid(grid_arrays: GridArrays) -> GridArrays:
    """Validate ``(values, resolution, ox, oy, cos_yaw, sin_yaw)``; plain floats out."""
    try:
        values, resolution, ox, oy, cos_yaw, sin_yaw = grid_arrays
    except (TypeError, ValueError):
        raise ValueError(
            "grid_arrays must be the tuple (values, resolution, ox, oy, cos_yaw, sin_yaw)"
        ) from None
    values = np.asarray(values)
    if values.ndim != 2 or values.size == 0 or values.dtype != np.int8:
        raise ValueError(
            f"grid_arrays.values must be a non-empty (ny, nx) int8 array, got shape "
            f"{values.shape} dtype {values.dtype}"
        )
    resolution, ox, oy, cos_yaw, sin_yaw = (
        float(v) for v in (resolution, ox, oy, cos_yaw, sin_yaw)
    )
    if not (np.isfinite(resolution) and resolution > 0):
        raise ValueError(f"grid_arrays.resolution must be a finite number > 0 m, got {resolution}")
    if not (np.isfinite(ox) and np.isfinite(oy)):
        raise ValueError(f"grid_arrays origin (ox, oy) must be finite, got ({ox}, {oy})")
    if not abs(cos_yaw**2 + sin_yaw**2 - 1.0) < 1e-6:
        raise ValueError(
            f"grid_arrays (cos_yaw, sin_yaw) must be a unit vector, got ({cos_yaw}, {sin_yaw})"
        )
    return values, resolution, ox, oy, cos_yaw, sin_yaw


def _as_poses(poses: ArrayLike, name: str = "poses") -> NDArray[np.float64]:
    poses = np.asarray(poses, dtype=np.float64)
    if poses.ndim != 2 or poses.shape[1] != 3:
        raise ValueError(f"{name} must have shape (K, 3), got {poses.shape}")
    if not np.all(np.isfinite(poses)):
        raise ValueError(f"{name} must be finite")
    return np.ascontiguousarray(poses)


def _nonnegative(name: str, value: float, positive: bool = False) -> float:
    value = float(value)
    ok = np.isfinite(value) and (value > 0 if positive else value >= 0)
    if not ok:
        bound = "> 0" if positive else ">= 0"
        raise ValueError(f"LidarSensor.{name} must be a finite number {bound}, got {value}")
    return value


@dataclass(frozen=True)
class LidarSensor:
    """A planar lidar: beam geometry, noise mixture and the measurement model used to weigh
    particles.

    The same four mixture weights drive the simulation (:meth:`measure`) and the beam model;
    the likelihood field uses ``z_hit`` and ``z_rand`` only (max readings are skipped and short
    readings are not modelled, as in the book's table 6.3).

    Attributes:
        n_beams: number of beams M, >= 1.
        fov: field of view (rad) in ``(0, 2 pi]``, centred on the heading; the beams are evenly
            spaced, end to end for ``fov < 2 pi`` and without duplicating the first beam for
            ``2 pi``.
        max_range: maximum range (m), finite and > 0; the reading of a beam with no return.
        sigma_hit: standard deviation of the hit noise (m), > 0.
        z_hit, z_short, z_max, z_rand: mixture weights, each >= 0, summing to 1.
        lambda_short: rate of the short-reading exponential (1/m), > 0.
        model: ``"likelihood_field"`` (AMCL's default) or ``"beam"``.
        unknown_reflects: whether unknown cells stop a beam in the ray cast (AMCL's ray cast
            does stop at unknown cells).
    """

    n_beams: int = 60
    fov: float = 2 * np.pi
    max_range: float = 10.0
    sigma_hit: float = 0.2
    z_hit: float = 0.85
    z_short: float = 0.05
    z_max: float = 0.05
    z_rand: float = 0.05
    lambda_short: float = 0.1
    model: Literal["likelihood_field", "beam"] = "likelihood_field"
    unknown_reflects: bool = True

    def __post_init__(self) -> None:
        n = self.n_beams
        if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"LidarSensor.n_beams must be an integer >= 1, got {n!r}")
        object.__setattr__(self, "n_beams", int(n))
        fov = float(self.fov)
        # allow a 2 pi computed another way (e.g. np.deg2rad(360)) to differ by rounding
        if not (np.isfinite(fov) and 0 < fov <= 2 * np.pi * (1 + 1e-12)):
            raise ValueError(f"LidarSensor.fov must be in (0, 2*pi] rad, got {fov}")
        object.__setattr__(self, "fov", fov)
        for name in ("max_range", "sigma_hit", "lambda_short"):
            object.__setattr__(self, name, _nonnegative(name, getattr(self, name), True))
        weights = []
        for name in ("z_hit", "z_short", "z_max", "z_rand"):
            value = _nonnegative(name, getattr(self, name))
            object.__setattr__(self, name, value)
            weights.append(value)
        if abs(sum(weights) - 1.0) > 1e-6:
            raise ValueError(
                f"LidarSensor.z_hit + z_short + z_max + z_rand must sum to 1, got {sum(weights)}"
            )
        if self.model not in ("likelihood_field", "beam"):
            raise ValueError(
                f"LidarSensor.model must be 'likelihood_field' or 'beam', got {self.model!r}"
            )
        if not isinstance(self.unknown_reflects, (bool, np.bool_)):
            raise ValueError(
                f"LidarSensor.unknown_reflects must be a bool, got {self.unknown_reflects!r}"
            )
        object.__setattr__(self, "unknown_reflects", bool(self.unknown_reflects))

        if fov >= 2 * np.pi * (1 - 1e-12):
            angles = -np.pi + 2 * np.pi * np.arange(self.n_beams) / self.n_beams
        elif self.n_beams == 1:
            angles = np.zeros(1)
        else:
            angles = np.linspace(-0.5 * fov, 0.5 * fov, self.n_beams)
        angles.setflags(write=False)
        object.__setattr__(self, "_beam_angles", angles)

    @property
    def beam_angles(self) -> NDArray[np.float64]:
        """``(M,)`` beam directions relative to the heading (rad), increasing, read-only."""
        return self._beam_angles  # type: ignore[attr-defined]

    def expected_ranges(
        self, poses: ArrayLike, grid_arrays: GridArrays, out: NDArray | None = None
    ) -> NDArray[np.float64]:
        """Noise-free ranges ``(K, M)`` (m) ray-cast from poses ``(K, 3)``."""
        poses = _as_poses(poses)
        values, res, ox, oy, c, s = _unpack_grid(grid_arrays)
        shape = (poses.shape[0], self.n_beams)
        if out is None:
            out = np.empty(shape)
        elif out.shape != shape or out.dtype != np.float64:
            raise ValueError(f"out must be a float64 array of shape {shape}, got {out.shape}")
        cast_rays(
            values, res, ox, oy, c, s, poses, self.beam_angles, self.max_range,
            self.unknown_reflects, out,
        )
        return out

    def measure(
        self, pose: ArrayLike, grid_arrays: GridArrays, rng: np.random.Generator,
        discs: NDArray | None = None,
    ) -> NDArray[np.float64]:
        """Simulate one scan ``(M,)`` (m) from the true ``pose`` ``(3,)``.

        Each beam is ray-cast (and stopped by any of ``discs`` ``(P, 3)``, obstacles the map
        does not hold: centre x, y and radius in m), then one mixture component is drawn with
        probabilities
        ``(z_hit, z_short, z_max, z_rand)``:

        * hit: the ray-cast range plus N(0, sigma_hit^2), clipped to ``[0, max_range]``; a beam
          with no return within range stays a max reading, as a real lidar's does;
        * short: truncated exponential on ``[0, z*)`` with rate ``lambda_short`` (eq. 6.7);
        * max: ``max_range``;
        * random: uniform on ``[0, max_range)``.

        Every call draws exactly ``3 M`` uniforms and ``M`` normals from ``rng``, whatever the
        outcome, so the generator's stream does not depend on the map or the pose.
        """
        pose = np.asarray(pose, dtype=np.float64)
        if pose.shape != (3,):
            raise ValueError(f"pose must have shape (3,), got {pose.shape}")
        expected = self.expected_ranges(pose[None, :], grid_arrays)[0]
        if discs is not None and len(discs):
            occlude_ranges(pose[0], pose[1], pose[2], self.beam_angles,
                           np.ascontiguousarray(discs, dtype=np.float64), expected)
        m = self.n_beams
        u = rng.random((3, m))
        normal = rng.standard_normal(m)
        max_range = self.max_range
        hit = np.where(
            expected >= max_range, max_range,
            np.clip(expected + self.sigma_hit * normal, 0.0, max_range),
        )
        # inverse CDF of the exponential truncated to [0, z*]
        short = -np.log1p(u[1] * np.expm1(-self.lambda_short * expected)) / self.lambda_short
        short = np.clip(short, 0.0, expected)
        rand = u[2] * max_range
        edges = np.cumsum([self.z_hit, self.z_short, self.z_max])
        choice = u[0]
        return np.where(
            choice < edges[0], hit,
            np.where(choice < edges[1], short, np.where(choice < edges[2], max_range, rand)),
        )

    def log_likelihood(
        self,
        z: ArrayLike,
        poses: ArrayLike,
        grid_arrays: GridArrays,
        distance_field: ArrayLike | None = None,
        out: NDArray | None = None,
    ) -> NDArray[np.float64]:
        """Log-likelihood ``log p(z | pose, map)`` (nats) of one scan for each pose.

        Args:
            z: ``(M,)`` measured ranges (m), >= 0; ``inf`` counts as a max reading.
            poses: ``(K, 3)`` particle poses (m, rad).
            grid_arrays: ``(values, resolution, ox, oy, cos_yaw, sin_yaw)``.
            distance_field: ``(ny, nx)`` distance (m) to the nearest obstacle; needed by the
                likelihood field, ignored by the beam model (which ray-casts itself).
            out: optional ``(K,)`` float64 output.

        Returns:
            ``(K,)`` finite log-likelihoods.
        """
        z = np.asarray(z, dtype=np.float64)
        if z.shape != (self.n_beams,):
            raise ValueError(f"z must have shape ({self.n_beams},), got {z.shape}")
        if np.any(np.isnan(z)) or np.any(z < 0):
            raise ValueError("z must hold ranges >= 0 m (inf for no return), got NaN or < 0")
        poses = _as_poses(poses)
        k = poses.shape[0]
        if out is None:
            out = np.empty(k)
        elif out.shape != (k,) or out.dtype != np.float64:
            raise ValueError(f"out must be a float64 array of shape ({k},), got {out.shape}")
        if self.model == "beam":
            expected = self.expected_ranges(poses, grid_arrays)
            beam_model_log_likelihood(
                z, expected, self.max_range, self.z_hit, self.z_short, self.z_max, self.z_rand,
                self.sigma_hit, self.lambda_short, out,
            )
            return out
        values, res, ox, oy, c, s = _unpack_grid(grid_arrays)
        if distance_field is None:
            raise ValueError("distance_field is required by the likelihood_field model")
        field = np.ascontiguousarray(distance_field, dtype=np.float64)
        if field.shape != values.shape:
            raise ValueError(
                f"distance_field must have the grid's shape {values.shape}, got {field.shape}"
            )
        likelihood_field_log_likelihood(
            z, self.beam_angles, poses, field, res, ox, oy, c, s, self.max_range, self.z_hit,
            self.z_rand, self.sigma_hit, out,
        )
        return out

    def log_table(self, distance_field: ArrayLike) -> NDArray[np.float64]:
        """The likelihood field's per-cell log-probabilities for this sensor, ``(ny, nx)``:
        compute once per map and pass to :meth:`field_log_likelihood`."""
        field = np.ascontiguousarray(distance_field, dtype=np.float64)
        return likelihood_field_log_table(
            field, self.max_range, self.z_hit, self.z_rand, self.sigma_hit
        )

    def field_log_likelihood(
        self, z: NDArray, poses: NDArray, grid_arrays: GridArrays, log_table: NDArray,
        out: NDArray | None = None, beam_skip: tuple[float, float, float] | None = None,
        distance_field: NDArray | None = None,
    ) -> NDArray[np.float64]:
        """The likelihood-field log-likelihood ``(K,)`` of scan ``z`` ``(M,)`` for poses
        ``(K, 3)`` from a precomputed :meth:`log_table` (the filter's fast path; the same
        numbers as :meth:`log_likelihood`). Inputs are trusted: the env validated them.

        With ``beam_skip = (distance m, threshold, error threshold)`` (AMCL's beam_skip_*
        parameters; its defaults are (0.5, 0.3, 0.9)) and the grid's ``distance_field``
        ``(ny, nx)`` (m), beams that disagree with the map for most particles are left out:
        see :func:`likelihood_field_skip_log_likelihood`."""
        _, res, ox, oy, c, s = grid_arrays
        if out is None:
            out = np.empty(poses.shape[0])
        log_off = math.log(max(self.z_rand / self.max_range, PROB_FLOOR))
        if beam_skip is not None:
            skip_distance, skip_threshold, skip_error_threshold = beam_skip
            likelihood_field_skip_log_likelihood(
                z, self.beam_angles, poses, log_table, distance_field, log_off, res, ox, oy, c,
                s, self.max_range, skip_distance, skip_threshold, skip_error_threshold, out,
            )
            return out
        pick(likelihood_field_table_log_likelihood, likelihood_field_table_parallel)(
            z, self.beam_angles, poses, log_table, log_off, res, ox, oy, c, s, self.max_range,
            out,
        )
        return out
