"""Monte Carlo localization (the chapter's Algorithm 4), with KLD sampling and augmented MCL.

MCL (Dellaert et al. 1999) represents the belief by K weighted particles ``(x, y, theta)``:

1. **Motion** (map-aware transition, eq. 13.2): every particle is moved with the unicycle model
   plus additive noise ``eps = L n``, ``n ~ N(0, I)`` and ``L L^T = Q``; a particle that lands
   in an occupied, unknown or off-map cell (or outside the box of a landmark map) has
   ``p(x | m) = 0``, so its log-weight becomes ``-inf``.
2. **Measurement**: per-particle log-likelihoods ``log p(z | x_k, m)`` (from the lidar module,
   or :func:`landmark_log_likelihood` here) are added to the log-weights, which are normalized
   with logsumexp. Their weighted mean is the evidence ``p(z_t | z_1:t-1)``.
3. **Resampling** when the effective sample size drops below a fraction of K: the low-variance
   (systematic) sampler of Thrun et al. (2005, table 4.4) or stratified resampling.

Two extensions, both off by default:

* **Augmented MCL** (Thrun et al. 2005, table 8.3; AMCL's ``recovery_alpha_slow/fast``): short-
  and long-term averages ``w_fast``, ``w_slow`` of the evidence; at resampling a fraction
  ``max(0, 1 - w_fast / w_slow)`` of the particles is replaced by uniform free poses, so the
  filter can recover from a kidnapping. The averages are kept in log space (evidence values of
  ``exp(-1000)`` are common), start at the first evidence and restart after every resampling
  that injected, as in AMCL (whose comment says why: "to avoid spiraling off into complete
  randomness"; without the restart the rate sustains itself at the fraction of particles it
  replaces, and a sharp likelihood never lets the set regrow).
* **KLD sampling** (Fox 2003): at resampling, particles are drawn one by one until their count
  reaches the bound of :func:`~active_loc.beliefs.particle_stats.kld_limit` for the number of
  occupied pose bins, as AMCL's ``pf_update_resample``; as in AMCL the draws are then
  multinomial (the low-variance sampler needs the count in advance). Arrays keep the maximum
  size; the first ``n_active`` rows are the particle set.

Randomness: every draw comes from the ``numpy.random.Generator`` passed in, and a step's draws
scale with the ACTIVE particles K, not the maximum: ``predict`` draws ``3 K`` normals (numpy's
ziggurat, into an array the belief reuses), ``update`` one 64-bit key, from which a resampling
computes exactly the uniforms it uses (:mod:`active_loc.random_streams`; KLD sampling knows its
count only as it goes). The same Generator state gives the same step, so runs are reproducible
and planners get common random numbers. An initialization draws ``4 K_max`` uniforms (uniform)
or ``3 K_max`` normals (Gaussian): there every particle is active.

The map enters as a :class:`FreeSpace`: an occupancy grid in plain arrays (``values (ny, nx)``
int8, FREE = 0, OCCUPIED = 100, UNKNOWN = -1, row 0 at the bottom, origin the world pose of the
bottom-left corner of cell (0, 0)) or an axis-aligned box for landmark maps.

Entropy (nats) is the histogram entropy on the pose grid plus ``log(cell volume)``
(:func:`~active_loc.beliefs.particle_stats.histogram_entropy`), as for the grid filter.
"""

from __future__ import annotations

import copy as _copy
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from active_loc.beliefs.dual_proposal import dual_log_density, dual_pairs, sample_dual_poses
from active_loc.beliefs.particle_density import kde_log_density, silverman_bandwidth
from active_loc.beliefs.particle_stats import (
    ENTROPY_BINS,
    MAX_DENSE_BINS,
    bin_hash,
    kld_limit,
    logsumexp,
    normalize_log_weights,
    pose_bin,
    summarize_particles,
    summary_weights,
    table_size,
)
from active_loc.geometry import wrap_angle, wrap_angle_scalar
from active_loc.motion import UnicycleModel
from active_loc.parallel import parallel_twin, pick, use_parallel
from active_loc.random_streams import draw_key, fill_uniforms, stream_uniform
from active_loc.sensors.landmarks import (
    RANGE_BEARING,
    RELATIVE_POSITION,
    LandmarkSensor,
    measurement,
)

#: occupancy values of the grid convention
FREE = 0
OCCUPIED = 100
UNKNOWN = -1

RESAMPLING_SCHEMES = ("systematic", "stratified")
#: ``"motion"``: plain MCL; ``"mixture"``: a share of every landmark update's particles from
#: the measurement (:meth:`MCLBelief.update_landmarks`)
PROPOSALS = ("motion", "mixture")
#: the smallest kernel bandwidth (m, m, rad) of the predicted belief's density in mixture MCL
MIN_KDE_BANDWIDTH = (0.05, 0.05, 0.02)

#: a dual proposal: ``(D, rng) -> (poses (D, 3), log q (D,))`` (:meth:`MCLBelief.update_mixture`)
DualDraw = Callable[[int, np.random.Generator], tuple[NDArray[np.float64], NDArray[np.float64]]]

# lanes of a resampling's stream (active_loc.random_streams): which particle to copy, the
# stochastic rounding of the injected count, whether KLD's draw injects, and 4 for a pose
LANE_SELECT = 0
LANE_ROUND = 1
LANE_DECIDE = 2
LANE_POSE = 3

#: AMCL's KLD bin size (dx m, dy m, dtheta rad): 0.5 m, 0.5 m, 10 degrees
KLD_BINS = (0.5, 0.5, math.radians(10.0))

# jitter inside a free cell stays this far from its edges, so that rounding in the world <-> grid
# transform can never move a sampled pose into the neighbouring (maybe occupied) cell
_EDGE = 1e-9


# --- free space ----------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class FreeSpace:
    """Where the robot may be: the free cells of an occupancy grid, or an axis-aligned box.

    Build it with :meth:`from_grid` or :meth:`from_box`. The kernels take the plain arrays
    ``values``, ``geom``, ``is_grid`` and ``free_cells``.

    Attributes:
        values: ``(ny, nx)`` int8 occupancy (FREE = 0, OCCUPIED = 100, UNKNOWN = -1), row 0 at
            the bottom; a ``(1, 1)`` dummy for a box.
        resolution: cell size (m).
        origin: ``(ox, oy, yaw)``, world pose of the bottom-left corner of cell (0, 0) (m, rad).
        box: ``(x_min, y_min, x_max, y_max)`` (m): the valid region of a box map (inclusive);
            for a grid, the axis-aligned bounds of the grid's extent (information only).
        is_grid: whether validity is the grid test (else the box test).
        free_cells: ``(F, 2)`` int64 ``(ix, iy)`` of the free cells (derived; ``(1, 2)`` zeros
            for a box), to sample uniform free poses.
        geom: ``(9,)`` float64 ``ox, oy, cos yaw, sin yaw, resolution, x_min, y_min, x_max,
            y_max`` for the kernels (derived).
        area: free area (m^2) (derived).
    """

    values: NDArray[np.int8]
    resolution: float = 1.0
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    box: tuple[float, float, float, float] = (0.0, 0.0, 1.0, 1.0)
    is_grid: bool = True
    free_cells: NDArray[np.int64] = field(init=False, repr=False)
    geom: NDArray[np.float64] = field(init=False, repr=False)
    area: float = field(init=False)

    def __post_init__(self) -> None:
        values = np.ascontiguousarray(self.values)
        if values.ndim != 2 or values.size == 0:
            raise ValueError(f"FreeSpace.values must be a non-empty (ny, nx) array, got shape "
                             f"{values.shape}")
        numeric = np.issubdtype(values.dtype, np.integer) or np.issubdtype(
            values.dtype, np.floating
        )
        if not numeric or not np.all(np.isfinite(values)) or np.any(values != np.round(values)) or (
            values.min() < -128 or values.max() > 127
        ):
            raise ValueError("FreeSpace.values must be integers in the int8 range "
                             "(FREE 0, OCCUPIED 100, UNKNOWN -1)")
        values = values.astype(np.int8)
        res = float(self.resolution)
        if not (math.isfinite(res) and res > 0):
            raise ValueError(f"FreeSpace.resolution must be a finite number > 0 m, got {res}")
        origin = tuple(float(v) for v in np.asarray(self.origin, dtype=np.float64).reshape(-1))
        if len(origin) != 3 or not all(math.isfinite(v) for v in origin):
            raise ValueError(f"FreeSpace.origin must be 3 finite numbers (ox, oy, yaw), "
                             f"got {self.origin}")
        c, s = math.cos(origin[2]), math.sin(origin[2])
        if self.is_grid:
            cells = np.argwhere(values == FREE)[:, ::-1]  # (iy, ix) -> (ix, iy)
            if cells.shape[0] == 0:
                raise ValueError("FreeSpace.values has no FREE (0) cell: nowhere to put the robot")
            ny, nx = values.shape
            corners = np.array([[0, 0], [nx, 0], [0, ny], [nx, ny]], dtype=np.float64) * res
            wx = origin[0] + c * corners[:, 0] - s * corners[:, 1]
            wy = origin[1] + s * corners[:, 0] + c * corners[:, 1]
            box = (float(wx.min()), float(wy.min()), float(wx.max()), float(wy.max()))
            area = cells.shape[0] * res * res
        else:
            box = tuple(float(v) for v in np.asarray(self.box, dtype=np.float64).reshape(-1))
            if len(box) != 4 or not all(math.isfinite(v) for v in box) or not (
                box[0] < box[2] and box[1] < box[3]
            ):
                raise ValueError(f"FreeSpace.box must be finite (x_min, y_min, x_max, y_max) with "
                                 f"x_min < x_max and y_min < y_max, got {self.box}")
            cells = np.zeros((1, 2), dtype=np.int64)
            area = (box[2] - box[0]) * (box[3] - box[1])
        cells = np.ascontiguousarray(cells, dtype=np.int64)
        geom = np.array([origin[0], origin[1], c, s, res, *box], dtype=np.float64)
        for arr in (values, cells, geom):
            arr.setflags(write=False)
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "resolution", res)
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "box", box)
        object.__setattr__(self, "is_grid", bool(self.is_grid))
        object.__setattr__(self, "free_cells", cells)
        object.__setattr__(self, "geom", geom)
        object.__setattr__(self, "area", float(area))

    @classmethod
    def from_grid(
        cls, values: ArrayLike, resolution: float, origin: ArrayLike = (0.0, 0.0, 0.0)
    ) -> FreeSpace:
        """Free space of an occupancy grid ``values (ny, nx)`` with cell size ``resolution``
        (m) and ``origin`` ``(ox, oy, yaw)``; only FREE (0) cells are valid."""
        return cls(np.asarray(values), resolution, tuple(np.asarray(origin, float)), is_grid=True)

    @classmethod
    def from_box(cls, x_min: float, y_min: float, x_max: float, y_max: float) -> FreeSpace:
        """Free space of a landmark map: the box ``[x_min, x_max] x [y_min, y_max]`` (m)."""
        return cls(
            np.zeros((1, 1), dtype=np.int8), 1.0, (0.0, 0.0, 0.0),
            (x_min, y_min, x_max, y_max), is_grid=False,
        )

    def is_free(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Validity of world points ``(..., 2)`` (or poses ``(..., 3)``): booleans ``(...)``."""
        pts = np.asarray(points, dtype=np.float64)
        flat = np.ascontiguousarray(pts.reshape(-1, pts.shape[-1])[:, :2])
        out = np.empty(flat.shape[0], dtype=np.bool_)
        points_free(flat, self.values, self.geom, self.is_grid, out)
        return out.reshape(pts.shape[:-1])

    def sample(self, n: int, rng: np.random.Generator) -> NDArray[np.float64]:
        """``n`` poses ``(n, 3)`` uniform over the free space and over headings."""
        out = np.empty((n, 3))
        sample_free_poses(rng.random((n, 4)), self.values, self.geom, self.is_grid,
                          self.free_cells, out)
        return out


@numba.njit(cache=True, nogil=True, inline="always")
def grid_cell(
    x: float, y: float, ox: float, oy: float, c: float, s: float, res: float, nx: int, ny: int
) -> int:
    """Flat index ``iy * nx + ix`` of the grid cell holding ``(x, y)`` (m), or -1 off the map.

    Grid coordinates are ``gx = (c (x - ox) + s (y - oy)) / res`` and
    ``gy = (-s (x - ox) + c (y - oy)) / res``; the cell is ``(floor(gx), floor(gy))``. Scalars
    only, so that per-particle loops pay no array reference counting.
    """
    if not (np.isfinite(x) and np.isfinite(y)):
        return -1
    dx = x - ox
    dy = y - oy
    fx = np.floor((c * dx + s * dy) / res)
    fy = np.floor((-s * dx + c * dy) / res)
    if fx < 0.0 or fy < 0.0 or fx >= nx or fy >= ny:
        return -1
    return int(fy) * nx + int(fx)


@numba.njit(cache=True, nogil=True)
def points_free(
    points: NDArray, values: NDArray, geom: NDArray, is_grid: bool, out: NDArray
) -> None:
    """Validity of points ``(M, >= 2)`` (m) into booleans ``out`` ``(M,)``: the point lies in a
    FREE cell of the grid ``values`` (off-map, occupied and unknown cells are invalid), or in
    the box ``geom[5:9]`` (inclusive) when ``is_grid`` is False. ``geom`` is
    :attr:`FreeSpace.geom`."""
    ny, nx = values.shape
    flat = values.ravel()
    ox, oy, c, s, res = geom[0], geom[1], geom[2], geom[3], geom[4]
    x_min, y_min, x_max, y_max = geom[5], geom[6], geom[7], geom[8]
    for i in range(points.shape[0]):
        x = points[i, 0]
        y = points[i, 1]
        if is_grid:
            j = grid_cell(x, y, ox, oy, c, s, res, nx, ny)
            out[i] = j >= 0 and flat[j] == FREE
        else:
            out[i] = x_min <= x <= x_max and y_min <= y <= y_max


@numba.njit(cache=True, nogil=True, inline="always")
def free_pose_into(
    out: NDArray, m: int, u0: float, u1: float, u2: float, u3: float, geom: NDArray,
    is_grid: bool, free_cells: NDArray,
) -> None:
    """Row ``m`` of ``out`` ``(M, 3)`` = a pose uniform over the free space and the headings,
    from four uniforms in [0, 1): ``u0`` picks the free cell (grid) or x (box), ``u1``, ``u2``
    jitter inside the cell (grid) or ``u1`` is y (box), ``u3`` the heading."""
    if is_grid:
        n_free = free_cells.shape[0]
        f = int(u0 * n_free)
        if f >= n_free:
            f = n_free - 1
        gx = free_cells[f, 0] + _EDGE + u1 * (1.0 - 2.0 * _EDGE)
        gy = free_cells[f, 1] + _EDGE + u2 * (1.0 - 2.0 * _EDGE)
        out[m, 0] = geom[0] + geom[4] * (geom[2] * gx - geom[3] * gy)
        out[m, 1] = geom[1] + geom[4] * (geom[3] * gx + geom[2] * gy)
    else:
        out[m, 0] = geom[5] + u0 * (geom[7] - geom[5])
        out[m, 1] = geom[6] + u1 * (geom[8] - geom[6])
    th = -np.pi + 2.0 * np.pi * u3
    out[m, 2] = th if th < np.pi else -np.pi


@numba.njit(cache=True, nogil=True)
def sample_free_poses(
    u: NDArray, values: NDArray, geom: NDArray, is_grid: bool, free_cells: NDArray, out: NDArray
) -> None:
    """Poses ``(M, 3)`` uniform over the free space and the headings, from uniforms ``u``
    ``(M, >= 4)`` (the columns of :func:`free_pose_into`; extra columns are ignored).
    ``free_cells`` ``(F, 2)`` holds ``(ix, iy)`` of the free cells (grid only)."""
    for m in range(out.shape[0]):
        free_pose_into(out, m, u[m, 0], u[m, 1], u[m, 2], u[m, 3], geom, is_grid, free_cells)


@numba.njit(cache=True, nogil=True)
def stream_free_poses(
    key: np.uint64, geom: NDArray, is_grid: bool, free_cells: NDArray, out: NDArray
) -> None:
    """Poses ``(M, 3)`` uniform over the free space, number m from index m of the pose lanes
    of the stream ``key`` (:mod:`active_loc.random_streams`)."""
    for m in range(out.shape[0]):
        free_pose_into(out, m, stream_uniform(key, m, LANE_POSE),
                       stream_uniform(key, m, LANE_POSE + 1),
                       stream_uniform(key, m, LANE_POSE + 2),
                       stream_uniform(key, m, LANE_POSE + 3), geom, is_grid, free_cells)


# --- motion --------------------------------------------------------------------------------------


@numba.njit(cache=True, nogil=True, inline="always")
def move_particle(
    x: float, y: float, th: float, v: float, omega: float, dt: float, n0: float, n1: float,
    n2: float, L: NDArray,
) -> tuple[float, float, float]:
    """A pose moved by the unicycle transition with the noise ``L n``, ``n = (n0, n1, n2)``
    standard normals (scalars in and out: no array per particle in the loops)."""
    return (
        x + v * np.cos(th) * dt + L[0, 0] * n0 + L[0, 1] * n1 + L[0, 2] * n2,
        y + v * np.sin(th) * dt + L[1, 0] * n0 + L[1, 1] * n1 + L[1, 2] * n2,
        wrap_angle_scalar(th + omega * dt + L[2, 0] * n0 + L[2, 1] * n1 + L[2, 2] * n2),
    )


@numba.njit(cache=True, nogil=True, inline="always")
def pose_free(x: float, y: float, values: NDArray, geom: NDArray, is_grid: bool) -> bool:
    """Whether the point ``(x, y)`` (m) is in the free space (:func:`points_free`)."""
    if is_grid:
        ny, nx = values.shape
        j = grid_cell(x, y, geom[0], geom[1], geom[2], geom[3], geom[4], nx, ny)
        return j >= 0 and values[j // nx, j % nx] == FREE
    return geom[5] <= x <= geom[7] and geom[6] <= y <= geom[8]


@numba.njit(cache=True, nogil=True)
def move_particles(
    src: NDArray, v: float, omega: float, dt: float, normals: NDArray, noise_root: NDArray,
    values: NDArray, geom: NDArray, is_grid: bool, dst: NDArray, inside: NDArray,
) -> None:
    """The motion update of one particle set out of place: ``dst`` ``(K, 3)`` = ``src`` moved
    with the control (V m/s, omega rad/s) and the noise of ``normals`` ``(K, 3)``, and
    ``inside`` ``(K,)`` whether each moved particle is in the free space (the map prior)."""
    for k in numba.prange(src.shape[0]):
        x, y, th = move_particle(src[k, 0], src[k, 1], src[k, 2], v, omega, dt, normals[k, 0],
                                 normals[k, 1], normals[k, 2], noise_root)
        dst[k, 0] = x
        dst[k, 1] = y
        dst[k, 2] = th
        inside[k] = pose_free(x, y, values, geom, is_grid)


move_particles_parallel = parallel_twin(move_particles)


@numba.njit(cache=True, nogil=True)
def sample_motion(
    particles: NDArray,
    counts: NDArray,
    controls: NDArray,
    dt: float,
    normals: NDArray,
    noise_root: NDArray,
) -> None:
    """Sample the unicycle transition in place (Algorithm 4, first loop, without the map).

    ``x += V cos(theta) dt + e_x``, ``y += V sin(theta) dt + e_y``,
    ``theta = wrap(theta + omega dt + e_theta)`` with ``e = L n``.

    Args:
        particles: ``(B, K, 3)``; the first ``counts[b]`` rows of member b move.
        counts: ``(B,)`` int64 active particle counts.
        controls: ``(B, 2)`` (V m/s, omega rad/s).
        dt: time step (s).
        normals: ``(B, K, 3)`` standard normals drawn with the Generator.
        noise_root: ``(3, 3)`` L with ``L L^T = Q``.
    """
    for b in range(particles.shape[0]):
        for k in numba.prange(counts[b]):
            x, y, th = move_particle(particles[b, k, 0], particles[b, k, 1], particles[b, k, 2],
                                     controls[b, 0], controls[b, 1], dt, normals[b, k, 0],
                                     normals[b, k, 1], normals[b, k, 2], noise_root)
            particles[b, k, 0] = x
            particles[b, k, 1] = y
            particles[b, k, 2] = th


sample_motion_parallel = parallel_twin(sample_motion)


@numba.njit(cache=True, nogil=True)
def mask_free_space(
    particles: NDArray,
    log_w: NDArray,
    counts: NDArray,
    values: NDArray,
    geom: NDArray,
    is_grid: bool,
) -> None:
    """The map prior of eq. 13.2: ``log_w = -inf`` for particles ``(B, K, 3)`` outside the free
    space (occupied, unknown or off-map cells, or outside the box; see :func:`points_free`).
    ``log_w`` is ``(B, K)``; only the first ``counts[b]`` entries of member b are touched."""
    ny, nx = values.shape
    flat = values.ravel()
    ox, oy, c, s, res = geom[0], geom[1], geom[2], geom[3], geom[4]
    x_min, y_min, x_max, y_max = geom[5], geom[6], geom[7], geom[8]
    for b in range(particles.shape[0]):
        for k in numba.prange(counts[b]):
            x = particles[b, k, 0]
            y = particles[b, k, 1]
            if is_grid:
                j = grid_cell(x, y, ox, oy, c, s, res, nx, ny)
                ok = j >= 0 and flat[j] == FREE
            else:
                ok = x_min <= x <= x_max and y_min <= y <= y_max
            if not ok:
                log_w[b, k] = -np.inf


mask_free_space_parallel = parallel_twin(mask_free_space)


# --- weights and resampling ----------------------------------------------------------------------


@numba.njit(cache=True, nogil=True)
def add_log_likelihood(log_w: NDArray, log_lik: NDArray) -> float:
    """Measurement update of the weights in place: ``log_w += log_lik``, then normalized.

    Args:
        log_w: ``(K,)`` log-weights (normalized or not).
        log_lik: ``(K,)`` per-particle log-likelihoods ``log p(z | x_k, m)``; ``-inf`` and huge
            negative values are fine, NaN and ``+inf`` are not (the caller checks).

    Returns:
        The log evidence ``log sum_k w_k p(z | x_k)`` with the prior weights normalized (the
        average likelihood that drives augmented MCL); ``-inf`` on a total collapse, in which
        case ``log_w`` is all ``-inf``.
    """
    lse_prior = logsumexp(log_w)
    # shift by the largest log-likelihood (a constant cancels in the normalization), so that
    # values like -1e300 do not swamp the log-weights they are added to
    shift = -np.inf
    for v in log_lik:
        if v > shift:
            shift = v
    if shift == -np.inf or lse_prior == -np.inf:
        for i in range(log_w.shape[0]):
            log_w[i] = -np.inf
        return -np.inf
    for i in range(log_w.shape[0]):
        log_w[i] += log_lik[i] - shift
    lse_post = normalize_log_weights(log_w)
    if lse_post == -np.inf:
        return -np.inf
    return shift + lse_post - lse_prior


@numba.njit(cache=True, nogil=True)
def _cumulative_weights(log_w: NDArray, cdf: NDArray) -> tuple:
    """Running sums of the normalized weights into ``cdf`` ``(K,)``; returns ``(total, last)``
    with ``last`` the index of the last particle of positive weight (the search never goes
    beyond it, whatever the rounding of the sums)."""
    k = log_w.shape[0]
    lse = logsumexp(log_w)
    running = 0.0
    last = k - 1
    found = False
    for i in range(k):
        w = 1.0 / k if lse == -np.inf else np.exp(log_w[i] - lse)
        running += w
        cdf[i] = running
        if w > 0.0:
            last = i
            found = True
    if not found:
        last = k - 1
    return running, last


@numba.njit(cache=True, nogil=True)
def _positions_to_indices(cdf: NDArray, total: float, last: int, positions: NDArray,
                          out: NDArray) -> None:
    """For increasing positions in [0, 1), the particle whose cdf interval holds each one:
    the first ``i`` with ``cdf[i] > pos * total``; zero-weight particles are never chosen."""
    i = 0
    for m in range(positions.shape[0]):
        target = positions[m] * total
        while i < last and cdf[i] <= target:
            i += 1
        out[m] = i


@numba.njit(cache=True, nogil=True)
def systematic_resample(log_w: NDArray, u: float, out: NDArray) -> None:
    """Low-variance sampler (Thrun et al. 2005, table 4.4): indices ``out`` ``(M,)`` of the
    particles at positions ``(u + m) / M``, from one uniform ``u`` in [0, 1). Particle k gets
    ``floor(M w_k)`` or ``ceil(M w_k)`` copies."""
    m_out = out.shape[0]
    if m_out == 0:
        return
    cdf = np.empty(log_w.shape[0])
    total, last = _cumulative_weights(log_w, cdf)
    positions = (u + np.arange(m_out)) / m_out
    _positions_to_indices(cdf, total, last, positions, out)


@numba.njit(cache=True, nogil=True)
def stratified_resample(log_w: NDArray, u: NDArray, out: NDArray) -> None:
    """Stratified resampling: indices ``out`` ``(M,)`` at positions ``(m + u_m) / M``, one
    uniform per stratum from ``u`` (``(>= M,)``, the first M are used)."""
    m_out = out.shape[0]
    if m_out == 0:
        return
    cdf = np.empty(log_w.shape[0])
    total, last = _cumulative_weights(log_w, cdf)
    positions = (np.arange(m_out) + u[:m_out]) / m_out
    _positions_to_indices(cdf, total, last, positions, out)


@numba.njit(cache=True, nogil=True)
def resample_particles(
    particles: NDArray,
    log_w: NDArray,
    key: np.uint64,
    stratified: bool,
    inject_prob: float,
    geom: NDArray,
    is_grid: bool,
    free_cells: NDArray,
    out: NDArray,
) -> int:
    """Fixed-count resampling with optional injection of uniform free poses (augmented MCL).

    ``n_inj = floor(inject_prob K + u)`` (stochastic rounding, unbiased) rows of ``out`` get
    uniform free poses; the other ``K - n_inj`` are drawn from the weighted set, systematically
    (one uniform) or stratified (one per stratum). Every uniform is a number of the stream
    ``key`` (:mod:`active_loc.random_streams`): as many as the step uses.

    Args:
        particles: ``(S, 3)``; log_w: ``(S,)``.
        key: the step's stream key.
        inject_prob: fraction of random particles in [0, 1].
        out: ``(K, 3)`` out: K particles are drawn (K = S but for a mixture MCL step, whose
            source holds the dual poses too).

    Returns:
        The number of injected particles.
    """
    k = out.shape[0]
    n_inj = 0
    if inject_prob > 0.0:
        n_inj = int(np.floor(inject_prob * k + stream_uniform(key, 0, LANE_ROUND)))
        n_inj = min(max(n_inj, 0), k)
        stream_free_poses(key, geom, is_grid, free_cells, out[:n_inj])
    m = k - n_inj
    idx = np.empty(m, dtype=np.int64)
    if stratified:
        u = np.empty(m)
        fill_uniforms(key, LANE_SELECT, u)
        stratified_resample(log_w, u, idx)
    else:
        systematic_resample(log_w, stream_uniform(key, 0, LANE_SELECT), idx)
    for j in range(m):
        out[n_inj + j, 0] = particles[idx[j], 0]
        out[n_inj + j, 1] = particles[idx[j], 1]
        out[n_inj + j, 2] = particles[idx[j], 2]
    return n_inj


@numba.njit(cache=True, nogil=True)
def kld_resample(
    particles: NDArray,
    log_w: NDArray,
    key: np.uint64,
    inject_prob: float,
    geom: NDArray,
    is_grid: bool,
    free_cells: NDArray,
    bins: NDArray,
    min_particles: int,
    max_particles: int,
    err: float,
    z: float,
    out: NDArray,
) -> tuple:
    """KLD-sampling resampling (Fox 2003), as AMCL's ``pf_update_resample``.

    Draws particles one at a time (multinomial; with probability ``inject_prob`` a uniform
    free pose instead), counts the occupied bins of size ``bins`` ``(dx, dy, dtheta)``, and
    stops once the count reaches :func:`kld_limit` of the bins (or ``max_particles``). Draw n
    takes number n of the select, decide and pose lanes of the stream ``key``, so the step
    uses as many uniforms as it draws particles.

    Args:
        particles: ``(K, 3)``; log_w: ``(K,)``; key: the step's stream key;
        out: ``(max_particles, 3)`` out; the first ``count`` rows are the new set.

    Returns:
        ``(count, n_injected)``.
    """
    k = particles.shape[0]
    cdf = np.empty(k)
    total, last = _cumulative_weights(log_w, cdf)
    dx, dy, dth = bins[0], bins[1], bins[2]
    size = table_size(max_particles)
    mask = size - 1
    keys = np.empty((size, 3), dtype=np.int64)
    used = np.zeros(size, dtype=np.bool_)
    n_bins = 0
    count = 0
    n_inj = 0
    limit = kld_limit(0, min_particles, max_particles, err, z)
    while count < max_particles:
        if inject_prob > 0.0 and stream_uniform(key, count, LANE_DECIDE) < inject_prob:
            free_pose_into(out, count, stream_uniform(key, count, LANE_POSE),
                           stream_uniform(key, count, LANE_POSE + 1),
                           stream_uniform(key, count, LANE_POSE + 2),
                           stream_uniform(key, count, LANE_POSE + 3), geom, is_grid,
                           free_cells)
            n_inj += 1
        else:
            i = np.searchsorted(cdf, stream_uniform(key, count, LANE_SELECT) * total,
                                side="right")
            if i > last:
                i = last
            out[count, 0] = particles[i, 0]
            out[count, 1] = particles[i, 1]
            out[count, 2] = particles[i, 2]
        x, y, th = out[count, 0], out[count, 1], out[count, 2]
        # insert the bin (open addressing; see particle_stats.assign_bins)
        b0, b1, b2 = pose_bin(x, y, th, dx, dy, dth)
        j = bin_hash(b0, b1, b2, mask)
        while used[j] and not (keys[j, 0] == b0 and keys[j, 1] == b1 and keys[j, 2] == b2):
            j = (j + 1) & mask
        if not used[j]:
            used[j] = True
            keys[j, 0] = b0
            keys[j, 1] = b1
            keys[j, 2] = b2
            n_bins += 1
            limit = kld_limit(n_bins, min_particles, max_particles, err, z)
        count += 1
        if count >= limit:
            break
    return count, n_inj


# --- landmark likelihood -------------------------------------------------------------------------


@numba.njit(cache=True, nogil=True, inline="always")
def _landmark_log_density(
    kind: int, x: float, y: float, th: float, mx: float, my: float, z0: float, z1: float,
    l00: float, l10: float, l11: float, log_norm: float,
) -> float:
    """``log N(z; h(x, m), R)`` with R = L L^T, the bearing residual wrapped."""
    h0, h1 = measurement(kind, x, y, th, mx, my)
    r0 = z0 - h0
    r1 = z1 - h1
    if kind == RANGE_BEARING:
        r1 = wrap_angle_scalar(r1)
    w0 = r0 / l00
    w1 = (r1 - l10 * w0) / l11
    return log_norm - 0.5 * (w0 * w0 + w1 * w1)


@numba.njit(cache=True, nogil=True)
def landmark_log_likelihood_kernel(
    particles: NDArray,
    z: NDArray,
    visible: NDArray,
    landmarks: NDArray,
    kind: int,
    l00: float,
    l10: float,
    l11: float,
    known_correspondence: bool,
    out: NDArray,
) -> None:
    """Per-particle ``sum_i log N(z_i; h(x_k, m_c(i)), R)`` over the visible measurements.

    Args:
        particles: ``(K, 3)``; z: ``(N, 2)``; visible: ``(N,)`` bool; landmarks: ``(L, 2)``.
        kind: ``RELATIVE_POSITION`` or ``RANGE_BEARING``.
        l00, l10, l11: lower Cholesky factor of R (2 x 2).
        known_correspondence: measurement i belongs to landmark i (``N == L``); otherwise each
            measurement is matched, per particle, to the landmark of maximum likelihood (the
            chapter's ML data association, evaluated at the particle instead of the mean).
        out: ``(K,)`` out.
    """
    log_norm = -np.log(2.0 * np.pi) - np.log(l00) - np.log(l11)
    n_lm = landmarks.shape[0]
    for k in numba.prange(particles.shape[0]):
        x = particles[k, 0]
        y = particles[k, 1]
        th = particles[k, 2]
        total = 0.0
        for i in range(z.shape[0]):
            if not visible[i]:
                continue
            if known_correspondence:
                total += _landmark_log_density(
                    kind, x, y, th, landmarks[i, 0], landmarks[i, 1], z[i, 0], z[i, 1],
                    l00, l10, l11, log_norm,
                )
            else:
                best = -np.inf
                for j in range(n_lm):
                    val = _landmark_log_density(
                        kind, x, y, th, landmarks[j, 0], landmarks[j, 1], z[i, 0], z[i, 1],
                        l00, l10, l11, log_norm,
                    )
                    if val > best:
                        best = val
                total += best
        out[k] = total


landmark_log_likelihood_parallel = parallel_twin(landmark_log_likelihood_kernel)


def landmark_log_likelihood(
    particles: ArrayLike,
    z: ArrayLike,
    visible: ArrayLike,
    landmarks: ArrayLike,
    kind: int,
    noise_cov: ArrayLike,
    known_correspondence: bool = True,
) -> NDArray[np.float64]:
    """Log-likelihoods ``(K,)`` of landmark measurements for particles ``(K, 3)``.

    Args:
        particles: ``(K, 3)`` poses (m, m, rad).
        z: ``(N, 2)`` measurements (relative position m, or range m and bearing rad).
        visible: ``(N,)`` which rows of ``z`` are real measurements.
        landmarks: ``(L, 2)`` landmark positions (m); only real landmarks (no padding) when
            correspondences are unknown.
        kind: ``RELATIVE_POSITION`` or ``RANGE_BEARING``.
        noise_cov: ``(2, 2)`` R, positive definite.
        known_correspondence: see :func:`landmark_log_likelihood_kernel`.

    Raises:
        ValueError: on inconsistent shapes, an unknown kind or a bad R.
    """
    parts = np.ascontiguousarray(particles, dtype=np.float64).reshape(-1, 3)
    z = np.ascontiguousarray(z, dtype=np.float64).reshape(-1, 2)
    visible = np.ascontiguousarray(visible, dtype=np.bool_).reshape(-1)
    landmarks = np.ascontiguousarray(landmarks, dtype=np.float64).reshape(-1, 2)
    if visible.shape[0] != z.shape[0]:
        raise ValueError(f"landmark_log_likelihood: z has {z.shape[0]} rows but visible has "
                         f"{visible.shape[0]}")
    if known_correspondence and z.shape[0] != landmarks.shape[0]:
        raise ValueError(f"landmark_log_likelihood: with known correspondences z needs one row per "
                         f"landmark ({landmarks.shape[0]}), got {z.shape[0]}")
    if not known_correspondence and landmarks.shape[0] == 0 and visible.any():
        raise ValueError("landmark_log_likelihood: measurements but no landmarks to match")
    if kind not in (RELATIVE_POSITION, RANGE_BEARING):
        raise ValueError(f"landmark_log_likelihood: kind must be RELATIVE_POSITION (0) or "
                         f"RANGE_BEARING (1), got {kind}")
    try:
        root = np.linalg.cholesky(np.asarray(noise_cov, dtype=np.float64).reshape(2, 2))
    except np.linalg.LinAlgError:
        raise ValueError("landmark_log_likelihood: noise_cov is not positive definite") from None
    out = np.empty(parts.shape[0])
    pick(landmark_log_likelihood_kernel, landmark_log_likelihood_parallel)(
        parts, z, visible, landmarks, int(kind), float(root[0, 0]), float(root[1, 0]),
        float(root[1, 1]), bool(known_correspondence), out,
    )
    return out


# --- the belief ----------------------------------------------------------------------------------


def _log_add(a: float, b: float) -> float:
    """``log(exp(a) + exp(b))`` for floats, ``-inf`` allowed."""
    if a == -math.inf:
        return b
    if b == -math.inf:
        return a
    m = max(a, b)
    return m + math.log(math.exp(a - m) + math.exp(b - m))


def _check_bins(name: str, bins: ArrayLike) -> NDArray[np.float64]:
    arr = np.asarray(bins, dtype=np.float64).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise ValueError(f"MCLBelief.{name} must be 3 finite sizes > 0 (dx m, dy m, dtheta rad), "
                         f"got {bins}")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class ParticleSummary:
    """What a step reads of a particle set (read-only arrays).

    Attributes:
        weights: ``(K,)`` normalized linear weights of the active particles.
        mean: ``(3,)`` weighted mean pose (m, m, rad; circular in theta).
        cov: ``(3, 3)`` weighted covariance (heading residuals wrapped about the mean).
        entropy: histogram entropy on the belief's entropy bins plus log(cell volume) (nats).
        ess: Kish's effective sample size ``1 / sum w^2``.
    """

    weights: NDArray[np.float64]
    mean: NDArray[np.float64]
    cov: NDArray[np.float64]
    entropy: float
    ess: float


class MCLBelief:
    """Monte Carlo localization belief: a batch of one particle set, arrays batch-first.

    State: ``(1, K_max, 3)`` particles, ``(1, K_max)`` normalized log-weights and the active
    count (``K_max`` unless KLD sampling shrinks it); rows beyond the count have weight
    ``-inf``. :attr:`particles` and :attr:`log_weights` are read-only views of the active rows.

    Args:
        free_space: where the robot may be (:class:`FreeSpace`).
        motion: unicycle model (dt and Q).
        n_particles: K, the particle count; with KLD sampling the maximum (AMCL 5000).
        resampling: ``"systematic"`` (low-variance) or ``"stratified"``.
        resample_threshold: resample when ESS < ``resample_threshold * K`` (in [0, 1];
            1 after every update unless the weights are exactly uniform, 0 never).
        augmented: inject uniform particles at rate ``max(0, 1 - w_fast / w_slow)`` (mixture
            MCL: dual poses that explain the scan, at that rate).
        alpha_slow, alpha_fast: averaging rates of w_slow and w_fast,
            ``0 < alpha_slow < alpha_fast <= 1`` (AMCL's recovery_alpha_slow/fast would be
            0.001 and 0.1 when on).
        recovery_threshold: rho in (0, 1]: the injection rate is
            ``max(0, 1 - w_fast / (rho w_slow))``, so nothing is injected until the short-term
            average falls below rho times the long-term one (1: augmented MCL's rate, which
            answers every dip of the evidence).
        kld: KLD sampling at resampling time.
        min_particles: KLD lower bound (ROS AMCL's default 100; Nav2's is 500),
            ``1 <= min_particles <= n_particles``.
        kld_err: KLD error bound epsilon in (0, 1) (AMCL 0.01).
        kld_z: upper standard normal quantile (AMCL's kld_z 0.99, used as is).
        kld_bins: KLD bin size (dx m, dy m, dtheta rad) (AMCL 0.5 m, 0.5 m, 10 deg).
        entropy_bins: entropy pose-grid cells (dx m, dy m, dtheta rad).
        likelihood_exponent: the power in (0, 1] each measurement likelihood is raised to
            before weighting. Lidar beams are not independent (map errors, correlated noise),
            so the product over beams overstates the evidence and collapses the particle set
            onto a few hypotheses; tempering it (AMCL subsamples beams for the same reason)
            keeps global localization from converging falsely. 1 is the plain filter.
        proposal: ``"motion"`` (plain MCL) or ``"mixture"``: every measurement update also
            draws ``mixture_share`` x K poses from the measurement (:meth:`update_mixture`:
            from a landmark scan's detections, :mod:`~active_loc.beliefs.dual_proposal`, or a
            lidar scan's lattice, :mod:`~active_loc.beliefs.lidar_dual`), and augmented MCL
            injects such poses instead of uniform ones.
        mixture_share: phi in (0, 1).

    Attributes:
        reinitialized: True when a total collapse re-initialized the belief since the start of
            the last :meth:`predict` (every weight zero after an update, or an initial
            Gaussian entirely outside the free space).
        blocked: True when the last :meth:`predict` would have moved every particle out of the
            free space, and so moved none.
        n_reinitializations: how many re-initializations in all.
        resampled: whether the last :meth:`update` resampled.
        last_injected: uniform particles injected by the last update (0 if it did not
            resample; always 0 in mixture MCL, which gives that share to dual poses).
        last_injection_rate: the injection (recovery) rate that update used (0 if it did not
            resample).
        last_log_evidence: log of the weighted average likelihood at the last update.
    """

    def __init__(
        self,
        free_space: FreeSpace,
        motion: UnicycleModel,
        n_particles: int = 1000,
        *,
        resampling: str = "systematic",
        resample_threshold: float = 0.5,
        augmented: bool = False,
        alpha_slow: float = 0.001,
        alpha_fast: float = 0.1,
        recovery_threshold: float = 1.0,
        kld: bool = False,
        min_particles: int = 100,
        kld_err: float = 0.01,
        kld_z: float = 0.99,
        kld_bins: ArrayLike = KLD_BINS,
        entropy_bins: ArrayLike = ENTROPY_BINS,
        likelihood_exponent: float = 1.0,
        proposal: str = "motion",
        mixture_share: float = 0.2,
    ) -> None:
        if proposal not in PROPOSALS:
            raise ValueError(f"MCLBelief.proposal must be one of {PROPOSALS}, got {proposal!r}")
        if not (isinstance(mixture_share, (int, float)) and not isinstance(mixture_share, bool)
                and 0.0 < mixture_share < 1.0):
            raise ValueError(f"MCLBelief.mixture_share must be a number in (0, 1), got "
                             f"{mixture_share!r}")
        if not (math.isfinite(likelihood_exponent) and 0.0 < likelihood_exponent <= 1.0):
            raise ValueError(f"MCLBelief.likelihood_exponent must be in (0, 1], got "
                             f"{likelihood_exponent}")
        if not isinstance(free_space, FreeSpace):
            raise ValueError(f"MCLBelief.free_space must be a FreeSpace, got "
                             f"{type(free_space).__name__}")
        if isinstance(n_particles, bool) or int(n_particles) != n_particles or n_particles < 1:
            raise ValueError(f"MCLBelief.n_particles must be an integer >= 1, got {n_particles}")
        if resampling not in RESAMPLING_SCHEMES:
            raise ValueError(f"MCLBelief.resampling must be one of {RESAMPLING_SCHEMES}, "
                             f"got {resampling!r}")
        if not (0.0 <= resample_threshold <= 1.0):
            raise ValueError(f"MCLBelief.resample_threshold must be in [0, 1], got "
                             f"{resample_threshold}")
        if not (0.0 < alpha_slow < alpha_fast <= 1.0):
            raise ValueError(f"MCLBelief.alpha_slow and alpha_fast must satisfy 0 < alpha_slow < "
                             f"alpha_fast <= 1, got {alpha_slow}, {alpha_fast}")
        if not (isinstance(recovery_threshold, (int, float))
                and not isinstance(recovery_threshold, bool) and 0.0 < recovery_threshold <= 1.0):
            raise ValueError(f"MCLBelief.recovery_threshold must be a number in (0, 1], got "
                             f"{recovery_threshold!r}")
        n_particles = int(n_particles)
        if kld:
            if isinstance(min_particles, bool) or int(min_particles) != min_particles or not (
                1 <= min_particles <= n_particles
            ):
                raise ValueError(f"MCLBelief.min_particles must be an integer in [1, n_particles="
                                 f"{n_particles}], got {min_particles}")
            if not (0.0 < kld_err < 1.0):
                raise ValueError(f"MCLBelief.kld_err must be in (0, 1), got {kld_err}")
            if not math.isfinite(kld_z):
                raise ValueError(f"MCLBelief.kld_z must be finite, got {kld_z}")
        self.free_space = free_space
        self.motion = motion
        self.n_particles = n_particles
        self.resampling = resampling
        self.resample_threshold = float(resample_threshold)
        self.augmented = bool(augmented)
        self.alpha_slow = float(alpha_slow)
        self.alpha_fast = float(alpha_fast)
        self.recovery_threshold = float(recovery_threshold)
        self.kld = bool(kld)
        self.min_particles = int(min_particles) if kld else n_particles
        self.kld_err = float(kld_err)
        self.kld_z = float(kld_z)
        self.kld_bins = _check_bins("kld_bins", kld_bins)
        self.entropy_bins = _check_bins("entropy_bins", entropy_bins)
        self.likelihood_exponent = float(likelihood_exponent)
        self.proposal = proposal
        self.mixture_share = float(mixture_share)

        self._particles = np.zeros((1, n_particles, 3))
        self._log_weights = np.full((1, n_particles), -math.log(n_particles))
        self._counts = np.full(1, n_particles, dtype=np.int64)
        self._log_w_slow: float | None = None
        self._log_w_fast: float | None = None
        self._summary: ParticleSummary | None = None
        self._initialized = False
        #: reusable arrays for a step's draws (see :meth:`_buffer`)
        self._buffers: dict[str, Any] = {}
        self.reinitialized = False
        self.n_reinitializations = 0
        self.blocked = False
        self.resampled = False
        self.last_injected = 0
        self.last_injection_rate = 0.0
        self.last_log_evidence = math.nan

    # --- views -------------------------------------------------------------------------------

    @property
    def batch_size(self) -> int:
        """B, always 1."""
        return 1

    @property
    def n_active(self) -> int:
        """Active particle count K (changes only with KLD sampling)."""
        return int(self._counts[0])

    @property
    def particles(self) -> NDArray[np.float64]:
        """``(K, 3)`` read-only view of the active particles (valid until the next call that
        changes the belief)."""
        view = self._particles[0, : self._counts[0]]
        view.flags.writeable = False
        return view

    @property
    def log_weights(self) -> NDArray[np.float64]:
        """``(K,)`` read-only view of the normalized log-weights of the active particles."""
        view = self._log_weights[0, : self._counts[0]]
        view.flags.writeable = False
        return view

    @property
    def weights(self) -> NDArray[np.float64]:
        """``(K,)`` normalized linear weights (a new array)."""
        return self.summary().weights.copy()

    @property
    def injection_rate(self) -> float:
        """``max(0, 1 - w_fast / (rho w_slow))`` of augmented MCL (rho the
        ``recovery_threshold``); 0 when augmentation is off."""
        if not self.augmented or self._log_w_slow is None or self._log_w_fast is None:
            return 0.0
        diff = self._log_w_fast - self._log_w_slow - math.log(self.recovery_threshold)
        return 0.0 if diff >= 0.0 else -math.expm1(diff)

    # --- initialization ----------------------------------------------------------------------

    def _set_uniform(self, rng: np.random.Generator) -> None:
        k = self.n_particles
        fs = self.free_space
        sample_free_poses(rng.random((k, 4)), fs.values, fs.geom, fs.is_grid, fs.free_cells,
                          self._particles[0])
        self._log_weights[0] = -math.log(k)
        self._counts[0] = k
        self._summary = None
        self._log_w_slow = self._log_w_fast = None
        self._initialized = True

    def _reinitialize(self, rng: np.random.Generator) -> None:
        """Recovery from a total collapse: uniform over the free space, recorded."""
        self._set_uniform(rng)
        self.reinitialized = True
        self.n_reinitializations += 1

    def initialize_uniform(self, rng: np.random.Generator) -> None:
        """K_max particles uniform over the free space and all headings (global
        localization); draws ``4 K_max`` uniforms."""
        self._set_uniform(rng)

    def initialize_gaussian(
        self, mean: ArrayLike, cov: ArrayLike, rng: np.random.Generator
    ) -> None:
        """K_max particles from N(mean ``(3,)``, cov ``(3, 3)``) (pose tracking), headings
        wrapped; samples outside the free space get weight 0, and if none is inside, the
        belief is re-initialized uniformly (``reinitialized`` is set). Draws ``3 K_max``
        normals."""
        mean = np.asarray(mean, dtype=np.float64).reshape(-1)
        cov = np.asarray(cov, dtype=np.float64)
        if mean.shape != (3,) or not np.all(np.isfinite(mean)):
            raise ValueError(f"MCLBelief.initialize_gaussian: mean must be 3 finite numbers, "
                             f"got {mean}")
        if cov.shape != (3, 3) or not np.all(np.isfinite(cov)) or not np.allclose(cov, cov.T):
            raise ValueError("MCLBelief.initialize_gaussian: cov must be a finite symmetric "
                             "(3, 3) matrix")
        w, v = np.linalg.eigh(cov)
        if w.min() < -1e-12 * max(1.0, w.max()):
            raise ValueError("MCLBelief.initialize_gaussian: cov must be positive semi-definite")
        root = v * np.sqrt(np.clip(w, 0.0, None))
        k = self.n_particles
        parts = mean + rng.standard_normal((k, 3)) @ root.T
        parts[:, 2] = wrap_angle(parts[:, 2])
        self._particles[0] = parts
        self._log_weights[0] = -math.log(k)
        self._counts[0] = k
        self._summary = None
        self._log_w_slow = self._log_w_fast = None
        self._initialized = True
        self.reinitialized = False
        self._apply_map(rng)

    def set_particles(self, particles: ArrayLike, log_weights: ArrayLike | None = None) -> None:
        """Set the particle set directly: ``(K, 3)`` poses and optional ``(K,)`` log-weights
        (default uniform; normalized here). K must equal ``n_particles``, or lie in
        ``[1, n_particles]`` with KLD sampling. Particles outside the free space get weight 0.

        Raises:
            ValueError: on bad shapes, non-finite poses, NaN/+inf weights, or no particle of
                positive weight in the free space.
        """
        parts = np.array(particles, dtype=np.float64).reshape(-1, 3)
        k = parts.shape[0]
        if not (k == self.n_particles or (self.kld and 1 <= k <= self.n_particles)):
            raise ValueError(f"MCLBelief.set_particles: expected {self.n_particles} particles"
                             f"{' (or fewer with KLD)' if self.kld else ''}, got {k}")
        if not np.all(np.isfinite(parts)):
            raise ValueError("MCLBelief.set_particles: particles must be finite")
        if log_weights is None:
            lw = np.full(k, -math.log(k))
        else:
            lw = np.array(log_weights, dtype=np.float64).reshape(-1)
            if lw.shape != (k,) or np.any(np.isnan(lw)) or np.any(lw == np.inf):
                raise ValueError(f"MCLBelief.set_particles: log_weights must be ({k},) without "
                                 f"NaN or +inf")
        parts[:, 2] = wrap_angle(parts[:, 2])
        counts = np.array([k], dtype=np.int64)
        lw2 = lw.reshape(1, k).copy()
        fs = self.free_space
        mask_free_space(parts.reshape(1, k, 3), lw2, counts, fs.values, fs.geom, fs.is_grid)
        if normalize_log_weights(lw2[0]) == -math.inf:
            raise ValueError("MCLBelief.set_particles: no particle of positive weight in the "
                             "free space")
        self._particles[0, :k] = parts
        self._particles[0, k:] = 0.0
        self._log_weights[0, :k] = lw2[0]
        self._log_weights[0, k:] = -math.inf
        self._counts[0] = k
        self._summary = None
        self._log_w_slow = self._log_w_fast = None
        self._initialized = True

    # --- filter steps ------------------------------------------------------------------------

    def _check_initialized(self) -> None:
        if not self._initialized:
            raise RuntimeError("MCLBelief: call initialize_uniform, initialize_gaussian or "
                               "set_particles first")

    def _apply_map(self, rng: np.random.Generator) -> None:
        """Map prior (eq. 13.2) on the active particles, normalization, collapse recovery."""
        fs = self.free_space
        mask_free_space(self._particles, self._log_weights, self._counts, fs.values, fs.geom,
                        fs.is_grid)
        self._summary = None
        if normalize_log_weights(self._log_weights[0, : self._counts[0]]) == -math.inf:
            self._reinitialize(rng)

    def predict(self, control: ArrayLike, rng: np.random.Generator) -> None:
        """Motion update with control ``(2,)`` = (V m/s, omega rad/s) and the map prior.

        Draws ``3 K`` normals for the K active particles. Particles that land outside the free
        space get weight 0; if all would, every particle keeps its pre-move pose and weight
        (``blocked`` is set).
        """
        self._check_initialized()
        u = np.asarray(control, dtype=np.float64).reshape(-1)
        if u.shape != (2,) or not np.all(np.isfinite(u)):
            raise ValueError(f"MCLBelief.predict: control must be 2 finite numbers (V m/s, "
                             f"omega rad/s), got {control}")
        self.reinitialized = False
        self._summary = None
        n = self.n_active
        normals = rng.standard_normal(out=self._buffer("normals", (self.n_particles, 3))[:n])
        moved = self._buffer("moved", (1, self.n_particles, 3))
        inside = self._flags("inside")[:n]
        fs = self.free_space
        pick(move_particles, move_particles_parallel)(
            self._particles[0, :n], float(u[0]), float(u[1]), self.motion.dt, normals,
            self.motion.noise_root, fs.values, fs.geom, fs.is_grid, moved[0, :n], inside,
        )
        n_inside = int(np.count_nonzero(inside))
        # Every hypothesis says this move runs into a wall: read it as blocked under all of
        # them, as the robot itself would be, and let the scans judge (every particle keeps
        # its pose and weight). Re-initializing here would throw a whole tracked belief away on
        # one step (and would act as a second, unconfigured kidnapping recovery beside
        # augmented MCL).
        self.blocked = n_inside == 0 or not np.any(self._log_weights[0, :n][inside] > -math.inf)
        if self.blocked:
            return
        # the moved set becomes the belief (the arrays swap: no copy of K poses)
        self._buffers["moved"], self._particles = self._particles, moved
        if n_inside < n:
            log_w = self._log_weights[0, :n]
            log_w[~inside] = -math.inf
            normalize_log_weights(log_w)

    def update(self, log_likelihood: ArrayLike, rng: np.random.Generator) -> None:
        """Measurement update with per-particle log-likelihoods ``(K,)`` (K = :attr:`n_active`,
        in the order of :attr:`particles`), then resampling when ESS < threshold * K.

        ``-inf`` and huge negative values are fine. If no particle keeps a positive weight the
        belief is re-initialized uniformly (``reinitialized`` is set). Draws one key from
        ``rng`` whether or not it resamples; a resampling computes its uniforms from it
        (:mod:`active_loc.random_streams`), as many as it uses.

        Raises:
            ValueError: on a wrong shape, NaN or ``+inf``.
        """
        ll = self._tempered(log_likelihood)
        n = self.n_active
        key = draw_key(rng)
        log_ev = add_log_likelihood(self._log_weights[0, :n], ll)
        self.last_log_evidence = log_ev
        if log_ev == -math.inf:
            self._reinitialize(rng)
            return
        self._track_evidence(log_ev)
        if self.summary().ess < self.resample_threshold * n:
            self._resample(key)

    def _tempered(self, log_likelihood: ArrayLike) -> NDArray[np.float64]:
        """The checked per-particle log-likelihoods ``(K,)`` times the exponent; starts an
        update (no resampling or injection recorded yet, the summary stale)."""
        self._check_initialized()
        n = self.n_active
        ll = np.ascontiguousarray(log_likelihood, dtype=np.float64).reshape(-1)
        if ll.shape != (n,):
            raise ValueError(f"MCLBelief.update: log_likelihood must have one entry per active "
                             f"particle ({n}), got shape {np.shape(log_likelihood)}")
        if np.any(np.isnan(ll)) or np.any(ll == np.inf):
            raise ValueError("MCLBelief.update: log_likelihood contains NaN or +inf")
        if self.likelihood_exponent != 1.0:
            ll = ll * self.likelihood_exponent  # a tempered likelihood p(z | x)^exponent
        self.resampled = False
        self.last_injected = 0
        self.last_injection_rate = 0.0
        self._summary = None
        return ll

    def _track_evidence(self, log_ev: float) -> None:
        """w_slow += alpha_slow (w_avg - w_slow), and w_fast likewise, in log space."""
        if self._log_w_slow is None or self._log_w_fast is None:
            self._log_w_slow = self._log_w_fast = log_ev
        else:
            self._log_w_slow = _log_add(math.log1p(-self.alpha_slow) + self._log_w_slow,
                                        math.log(self.alpha_slow) + log_ev)
            fast = math.log1p(-self.alpha_fast) if self.alpha_fast < 1.0 else -math.inf
            self._log_w_fast = _log_add(fast + self._log_w_fast,
                                        math.log(self.alpha_fast) + log_ev)

    def update_mixture(
        self,
        log_likelihood: ArrayLike,
        draw_dual: DualDraw,
        score: Callable[[NDArray[np.float64]], NDArray[np.float64]],
        rng: np.random.Generator,
    ) -> None:
        """Mixture MCL's measurement update (Thrun, Fox, Burgard and Dellaert 2001).

        Three weighted samples of the posterior are mixed and resampled (with KLD as set):

        - the K predicted particles weighted by ``w p(z | x)^a`` (the motion proposal), share
          ``(1 - r)(1 - phi)``;
        - ``D = phi K`` dual poses ``x ~ q`` weighted by ``p(z | x)^a bel_bar(x) / q(x)``,
          ``bel_bar`` the predicted set's kernel density
          (:mod:`~active_loc.beliefs.particle_density`), share ``(1 - r) phi``;
        - the same dual poses weighted by ``p(z | x)^a / q(x)``: the posterior under a uniform
          prior, share ``r``, the recovery rate :attr:`injection_rate` (0 unless augmented).
          Where augmented MCL injects uniform poses, mixture MCL injects these: poses that
          explain the scan (Lenser and Veloso's sensor resetting, weighted exactly). Nor
          does it restart w_slow and w_fast after an injection as AMCL does: its injected poses
          are not noise to be rid of, and a restart just before a kidnapping would hide it
          (on GridMCLKidnapped-v0 the restart cost 3 to 5 of 100 recoveries).

        A sample with no weight leaves its share to the others; with none at all the belief is
        re-initialized. w_slow / w_fast track the motion proposal's average likelihood, as in
        :meth:`update`, but do not drive the recovery.

        Args:
            log_likelihood: ``(K,)`` the particles' log-likelihoods ``log p(z | x)``
                (untempered).
            draw_dual: ``(D, rng) -> (poses (D, 3), log q (D,))``: the dual proposal of this
                scan (``log q = -inf`` for a pose it could not make).
            score: ``poses (S, 3) -> (S,)``: the same log-likelihood at other poses.
            rng: the env's Generator: one key, then the dual proposal's draws.
        """
        ll = self._tempered(log_likelihood)
        n = self.n_active
        key = draw_key(rng)
        particles = self._particles[0, :n]
        prior = self._weights()  # the predicted belief's weights
        bandwidth = silverman_bandwidth(particles, prior, MIN_KDE_BANDWIDTH)
        log_w = self._log_weights[0, :n]
        log_ev = add_log_likelihood(log_w, ll)  # log_w is now the motion sample's weights
        self._summary = None
        self.last_log_evidence = log_ev
        n_dual = max(1, round(self.mixture_share * n))
        poses, log_q = draw_dual(n_dual, rng)
        valid = np.isfinite(log_q) & self.free_space.is_free(poses)
        log_u = np.full(n_dual, -math.inf)  # dual weights under a uniform prior
        log_b = np.full(n_dual, -math.inf)  # and under the predicted belief
        if valid.any():
            dual = np.ascontiguousarray(poses[valid])
            log_u[valid] = self.likelihood_exponent * score(dual) - log_q[valid]
            log_b[valid] = log_u[valid] + kde_log_density(particles, prior, bandwidth, dual)
        recovery = self.injection_rate  # 0 unless augmented
        samples = [  # (normalized log-weights, log total, share)
            (log_w, log_ev, (1.0 - recovery) * (1.0 - self.mixture_share)),
            (log_b, logsumexp(log_b), (1.0 - recovery) * self.mixture_share),
            (log_u, logsumexp(log_u), recovery),
        ]
        live = sum(share for _, total, share in samples if total > -math.inf)
        if live == 0.0:
            self._reinitialize(rng)
            return
        if log_ev > -math.inf:
            self._track_evidence(log_ev)
        mixed_lw = np.full(n + n_dual, -math.inf)
        for i, (lw, total, share) in enumerate(samples):
            if total == -math.inf or share == 0.0:
                continue
            rows = mixed_lw[:n] if i == 0 else mixed_lw[n:]
            term = lw - (0.0 if i == 0 else total) + math.log(share / live)
            np.logaddexp(rows, term, out=rows)
        # K_max rows and the dual poses of K_max particles (n <= K_max, so n_dual is no more)
        most_dual = max(1, round(self.mixture_share * self.n_particles))
        mixed = self._buffer("mixed", (self.n_particles + most_dual, 3))
        mixed[:n] = particles
        mixed[n : n + n_dual] = poses
        self._resample(key, mixed[: n + n_dual], mixed_lw, recovery=recovery)

    def update_landmarks(
        self,
        z: ArrayLike,
        visible: ArrayLike,
        landmarks: ArrayLike,
        sensor: LandmarkSensor,
        rng: np.random.Generator,
        known_correspondence: bool = True,
    ) -> None:
        """:meth:`update` with :func:`landmark_log_likelihood` of ``sensor`` (its kind and R);
        z ``(N, 2)``, visible ``(N,)``, landmarks ``(L, 2)``. When no measurement is visible
        the belief is left as it is (an empty scan carries no information, and a likelihood of
        1 would bias w_slow / w_fast); nothing is drawn then."""
        vis = np.asarray(visible, dtype=np.bool_).reshape(-1)
        if not vis.any():
            self._check_initialized()
            self.resampled = False
            self.last_injected = 0
            self.last_injection_rate = 0.0
            return
        ll = landmark_log_likelihood(self.particles, z, vis, landmarks, sensor.kind,
                                     sensor.noise_cov, known_correspondence)
        if self.proposal != "mixture":
            self.update(ll, rng)
            return
        z = np.asarray(z, dtype=np.float64).reshape(-1, 2)
        landmarks = np.asarray(landmarks, dtype=np.float64).reshape(-1, 2)
        pairs = dual_pairs(vis, landmarks.shape[0], known_correspondence)

        def draw(n: int, gen: np.random.Generator) -> tuple[NDArray, NDArray]:
            poses, made = sample_dual_poses(n, z, landmarks, pairs, sensor.kind,
                                            sensor.noise_cov, gen)
            log_q = np.full(n, -math.inf)
            if made.any():
                log_q[made] = dual_log_density(poses[made], z, landmarks, pairs, sensor.kind,
                                               sensor.noise_cov)
            return poses, log_q

        def score(poses: NDArray[np.float64]) -> NDArray[np.float64]:
            return landmark_log_likelihood(poses, z, vis, landmarks, sensor.kind,
                                           sensor.noise_cov, known_correspondence)

        self.update_mixture(ll, draw, score, rng)

    def _entropy_grid(self) -> tuple[NDArray, NDArray, NDArray] | None:
        """The dense grid of entropy bins over the free space's box (scratch for
        :func:`~active_loc.beliefs.particle_stats.dense_binned_entropy`), or None when it would
        have more than ``MAX_DENSE_BINS`` cells."""
        grid = self._buffers.get("entropy_grid")
        if grid is None:
            dx, dy, dth = self.entropy_bins
            x_min, y_min, x_max, y_max = self.free_space.box
            ix0, iy0 = math.floor(x_min / dx), math.floor(y_min / dy)
            nx, ny = math.floor(x_max / dx) - ix0 + 1, math.floor(y_max / dy) - iy0 + 1
            nh = math.floor(2.0 * math.pi / dth) + 1
            if nx * ny * nh > MAX_DENSE_BINS:
                return None
            origin = np.array([ix0, iy0, nx, ny, nh], dtype=np.int64)
            grid = self._buffers["entropy_grid"] = (
                origin, np.zeros(nx * ny * nh), np.empty(self.n_particles, dtype=np.int64)
            )
        return grid  # type: ignore[return-value]

    def _flags(self, name: str) -> NDArray[np.bool_]:
        """This belief's reusable bool array ``name`` ``(K_max,)``."""
        flags = self._buffers.get(name)
        if flags is None:
            flags = self._buffers[name] = np.empty(self.n_particles, dtype=np.bool_)
        return flags

    def _buffer(self, name: str, shape: tuple[int, ...]) -> NDArray[np.float64]:
        """This belief's reusable float64 array ``name`` (K_max rows): a step's draws go into
        its first rows every time instead of memory allocated and freed per call."""
        buffer = self._buffers.get(name)
        if buffer is None:
            buffer = self._buffers[name] = np.empty(shape)
        return buffer

    def resample(self, rng: np.random.Generator) -> None:
        """Resample now, whatever the ESS (with injection and KLD when on); draws one key, as
        :meth:`update` does."""
        self._check_initialized()
        self._resample(draw_key(rng))

    def _resample(
        self, key: np.uint64, src: NDArray | None = None, lw: NDArray | None = None,
        recovery: float | None = None,
    ) -> None:
        """Resample with the uniforms of the stream ``key``, from the particle set or from
        another weighted sample ``src`` ``(S, 3)``, ``lw`` ``(S,)``: mixture MCL's, whose
        weights hold the ``recovery`` share already (so nothing uniform is injected)."""
        n = self.n_active
        if src is None or lw is None:
            src = self._particles[0, :n]
            lw = self._log_weights[0, :n]
        fs = self.free_space
        p_inj = self.injection_rate if recovery is None else 0.0
        out = self._buffer("resampled", (self.n_particles, 3))
        if self.kld:
            new_n, n_inj = kld_resample(
                src, lw, key, p_inj, fs.geom, fs.is_grid, fs.free_cells, self.kld_bins,
                self.min_particles, self.n_particles, self.kld_err, self.kld_z, out,
            )
        else:
            new_n = n
            n_inj = resample_particles(
                src, lw, key, self.resampling == "stratified", p_inj, fs.geom, fs.is_grid,
                fs.free_cells, out[:n],
            )
        self._particles[0, :new_n] = out[:new_n]
        self._particles[0, new_n:] = 0.0
        self._log_weights[0, :new_n] = -math.log(new_n)
        self._log_weights[0, new_n:] = -math.inf
        self._counts[0] = new_n
        self._summary = None
        self.resampled = True
        self.last_injected = int(n_inj)
        self.last_injection_rate = p_inj if recovery is None else recovery
        if p_inj > 0.0:
            # AMCL's restart of both averages (see the module docstring)
            self._log_w_slow = self._log_w_fast = None

    # --- statistics --------------------------------------------------------------------------

    def summary(self) -> ParticleSummary:
        """The weights, mean, covariance, entropy and ESS of the particle set, computed once
        per state of the belief (:func:`~active_loc.beliefs.particle_stats.summarize_particles`)
        and shared by every statistic below until the next change."""
        if self._summary is None:
            n = int(self._counts[0])
            weights, mean, cov = np.empty(n), np.empty(3), np.empty((3, 3))
            dx_dy_dth = self.entropy_bins
            entropy, ess = summarize_particles(
                self._particles[0, :n], self._log_weights[0, :n], dx_dy_dth, use_parallel(),
                weights, mean, cov, self._entropy_grid(),
            )
            for arr in (weights, mean, cov):
                arr.setflags(write=False)
            self._summary = ParticleSummary(weights, mean, cov, entropy, ess)
        return self._summary

    def _weights(self) -> NDArray[np.float64]:
        """The summary's normalized weights ``(K,)``, without the rest of a summary not made
        yet (read-only)."""
        if self._summary is not None:
            return self._summary.weights
        n = int(self._counts[0])
        weights = np.empty(n)
        summary_weights(self._particles[0, :n], self._log_weights[0, :n], use_parallel(),
                        weights)
        weights.setflags(write=False)
        return weights

    def mean(self) -> NDArray[np.float64]:
        """Weighted mean pose ``(3,)`` (m, m, rad), heading by the circular mean."""
        return self.summary().mean.copy()

    def covariance(self) -> NDArray[np.float64]:
        """Weighted covariance ``(3, 3)``, heading residuals wrapped about the circular mean."""
        return self.summary().cov.copy()

    def mean_and_covariance(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """:meth:`mean` and :meth:`covariance` together."""
        summary = self.summary()
        return summary.mean.copy(), summary.cov.copy()

    def entropy(self) -> float:
        """Histogram entropy on the ``entropy_bins`` pose grid plus log(cell volume) (nats)."""
        return self.summary().entropy

    def effective_sample_size(self) -> float:
        """ESS ``1 / sum w^2`` of the active particles."""
        return self.summary().ess

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_buffers"] = {}  # scratch: not worth pickling
        return state

    def copy(self) -> MCLBelief:
        """A deep copy (the free space and motion model are immutable and shared)."""
        out = _copy.copy(self)
        out._buffers = {}  # its own, so that a copy and its original never share scratch
        out._particles = self._particles.copy()
        out._log_weights = self._log_weights.copy()
        out._counts = self._counts.copy()
        return out
