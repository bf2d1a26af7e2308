"""The dual proposal of mixture MCL on grid maps: poses drawn from a lidar scan.

The landmark maps' dual (:mod:`~active_loc.beliefs.dual_proposal`) inverts a detection; a scan
of ranges has no such inverse, so here the proposal is a lattice of the map's free poses scored
against the scan. The lattice has cells of about :data:`DUAL_CELL_M` (a whole number of map
cells, aligned with them) and :data:`DUAL_HEADINGS` heading bins; the likelihood field scores
every lattice pose (:mod:`~active_loc.sensors.lidar_lattice`) on every
:data:`DUAL_BEAM_STRIDE`-th beam, with the filter's exponent scaled up to stand for all the
beams. A dual pose is drawn as

1. a lattice pose with probability ``(1 - eps) softmax(score) + eps / n_poses``: the uniform
   share ``eps`` (:data:`DEFENSIVE_SHARE`) keeps ``q`` positive on every free pose, wherever
   the coarse score is wrong;
2. a point uniform in its cell and heading bin.

So ``q`` is piecewise constant, ``P(cell, bin) / (cell area x bin width)``, and exact. Mixture
MCL weights a dual pose by the filter's own likelihood at it, so the lattice's coarseness costs
efficiency (how many dual poses land where the posterior is), never correctness. The lattice
covers the map cells exactly, so a free map cell is never outside it.

When the dual poses are weighted by the predicted belief alone (no recovery share), a pose
where that belief's kernel density is 0 gets no weight, so the draw keeps to the lattice cells
and heading bins that reach the density's support
(:class:`~active_loc.beliefs.particle_density.KernelSupport`): ``q`` stays positive wherever
``p(z | x) bel_bar(x)`` is, and only those poses are scored.
Measured on GridMCL-v0 with the passive agent, the support holds a median 18% of the free
cells (a mean of 41%).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from active_loc.beliefs.grid import coarse_free_mask
from active_loc.beliefs.mcl import MCLBelief
from active_loc.beliefs.particle_density import KernelSupport
from active_loc.geometry import wrap_angle
from active_loc.maps.occupancy import OccupancyGrid
from active_loc.parallel import parallel_twin, pick
from active_loc.sensors.lidar import LidarSensor
from active_loc.sensors.lidar_lattice import (
    lattice_field_log_likelihood,
    off_map_log_probability,
    padded_table,
)

#: the lattice's cell side (m), rounded to a whole number of map cells
DUAL_CELL_M = 0.25
#: the lattice's heading bins (10 degrees)
DUAL_HEADINGS = 36
#: the lattice scores every this many beams (the exponent is scaled to stand for all)
DUAL_BEAM_STRIDE = 4
#: the uniform share of the proposal over the lattice (defensive importance sampling)
DEFENSIVE_SHARE = 0.1
#: nats below the best lattice pose beyond which a pose's softmax share is taken as 0
SOFTMAX_CUTOFF = 40.0


@dataclass(frozen=True, eq=False)
class LidarDualProposal:
    """The scan lattice of one map: built once per map and shared (read-only) by the episodes
    and sub-envs that draw it.

    Attributes:
        free: ``(X, Y)`` bool, the lattice cells holding free map cells.
        cell_ratio: lattice cell side / map resolution (a whole number).
        resolution: the map's resolution (m).
        origin: the map's origin ``(x, y, yaw)`` (m, m, rad).
        table: the likelihood field's per-cell table framed by the off-map value
            (:func:`~active_loc.sensors.lidar_lattice.padded_table`).
        beams: ``(M',)`` the beams the lattice scores.
        n_beams: the scan's beams M.
        sensor: the filter's lidar, with the likelihood field as its model.
    """

    free: NDArray[np.bool_]
    cell_ratio: int
    resolution: float
    origin: tuple[float, float, float]
    table: NDArray[np.float64]
    beams: NDArray[np.int64]
    n_beams: int
    sensor: LidarSensor

    @classmethod
    def build(
        cls, grid: OccupancyGrid, sensor: LidarSensor, log_table: NDArray[np.float64]
    ) -> LidarDualProposal:
        """The lattice of ``grid`` for ``sensor``, scored with the likelihood field of
        ``log_table`` (:meth:`~active_loc.sensors.lidar.LidarSensor.log_table`), whichever
        model the filter weights with: the proposal only has to cover the posterior, the
        weights use the filter's own likelihood."""
        sensor = dataclasses.replace(sensor, model="likelihood_field")
        ratio = max(1, round(DUAL_CELL_M / grid.resolution))
        free = coarse_free_mask(grid, ratio * grid.resolution)
        free.setflags(write=False)
        n_beams = sensor.beam_angles.shape[0]
        return cls(
            free=free, cell_ratio=ratio,
            resolution=float(grid.resolution),
            origin=tuple(float(v) for v in grid.origin),  # type: ignore[arg-type]
            table=padded_table(log_table, off_map_log_probability(sensor)),
            beams=np.arange(0, n_beams, DUAL_BEAM_STRIDE), n_beams=n_beams, sensor=sensor,
        )

    @property
    def cell_side(self) -> float:
        """The lattice cell's side (m)."""
        return self.cell_ratio * self.resolution

    def bins_near(self, support: KernelSupport) -> NDArray[np.int64]:
        """The heading bins (indices, ascending) that hold a heading of ``support``."""
        bin_width = 2.0 * np.pi / DUAL_HEADINGS
        half = math.ceil(support.heading_reach / bin_width)
        if 2 * half + 1 >= DUAL_HEADINGS:
            return np.arange(DUAL_HEADINGS)
        # the points' headings in the map's frame, in [0, 2 pi): bin b starts at b x bin_width
        phi = np.mod(support.points[:, 2] - self.origin[2], 2.0 * np.pi)
        return np.flatnonzero(near_bins_kernel(phi / bin_width, half, DUAL_HEADINGS))

    def cells_near(self, support: KernelSupport) -> NDArray[np.bool_]:
        """``(X, Y)`` bool: the free lattice cells that hold a point of ``support``."""
        ox, oy, yaw = self.origin
        c, s = math.cos(yaw), math.sin(yaw)
        reach_x, reach_y = support.reach
        # the world-axis box's half-widths along the map's axes, in lattice cells
        half_x = (abs(c) * reach_x + abs(s) * reach_y) / self.cell_side
        half_y = (abs(s) * reach_x + abs(c) * reach_y) / self.cell_side
        dx = support.points[:, 0] - ox
        dy = support.points[:, 1] - oy
        return near_cells_kernel((c * dx + s * dy) / self.cell_side,
                                 (c * dy - s * dx) / self.cell_side,
                                 math.ceil(half_x), math.ceil(half_y), self.free)

    def scores(
        self, ranges: NDArray[np.float64], support: KernelSupport | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """The likelihood field's log-likelihood ``(X, Y, B)`` (nats, the scored beams only) of
        the scan ``ranges`` ``(M,)`` (m) at the lattice poses of the heading bins ``(B,)``
        (returned too): every bin, or with ``support`` those near it (:meth:`bins_near`);
        ``-inf`` off the free cells, and with ``support`` off the cells near it
        (:meth:`cells_near`)."""
        nx, ny = self.free.shape
        bins = np.arange(DUAL_HEADINGS) if support is None else self.bins_near(support)
        out = np.empty((nx, ny, bins.shape[0]))  # per call: sub-envs share the lattice
        lattice_field_log_likelihood(
            self.sensor, np.asarray(ranges, dtype=np.float64),
            2.0 * np.pi * bins / DUAL_HEADINGS,
            (np.arange(nx) + 0.5) * self.cell_ratio, (np.arange(ny) + 0.5) * self.cell_ratio,
            self.free if support is None else self.cells_near(support), self.resolution,
            self.table, out=out, beams=self.beams,
        )
        return out, bins

    def draw(
        self, n: int, ranges: NDArray[np.float64], exponent: float, rng: np.random.Generator,
        support: KernelSupport | None = None,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``n`` dual poses ``(n, 3)`` (m, m, rad) for the scan ``ranges`` ``(M,)`` and their
        log-density ``(n,)`` under the proposal; ``exponent`` is the filter's likelihood
        exponent; with ``support``, over the lattice cells near it only (module docstring).
        Draws ``4 n`` uniforms from ``rng``."""
        scores, bins = self.scores(ranges, support)
        cdf = scores.reshape(-1)  # overwritten by the proposal's CDF
        scale = exponent * self.n_beams / self.beams.shape[0]
        pick(proposal_cdf, proposal_cdf_parallel)(cdf, scale, DEFENSIVE_SHARE)
        u = rng.random((n, 4))
        total = cdf[-1]
        pose = np.minimum(np.searchsorted(cdf, u[:, 0] * total, side="right"), cdf.shape[0] - 1)
        prob = (cdf[pose] - np.where(pose > 0, cdf[pose - 1], 0.0)) / total
        cell = pose // bins.shape[0]
        ny = self.free.shape[1]
        gx = (cell // ny + u[:, 1]) * self.cell_ratio  # map grid coordinates (cells)
        gy = (cell % ny + u[:, 2]) * self.cell_ratio
        ox, oy, yaw = self.origin
        c, s = math.cos(yaw), math.sin(yaw)
        poses = np.empty((n, 3))
        poses[:, 0] = ox + self.resolution * (c * gx - s * gy)
        poses[:, 1] = oy + self.resolution * (s * gx + c * gy)
        bin_width = 2.0 * np.pi / DUAL_HEADINGS
        poses[:, 2] = wrap_angle(yaw + (bins[pose % bins.shape[0]] + u[:, 3]) * bin_width)
        log_q = np.log(prob) - math.log(self.cell_side**2 * bin_width)
        return poses, log_q


@numba.njit(cache=True, nogil=True)
def proposal_cdf(scores: NDArray, scale: float, uniform_share: float) -> None:
    """Overwrite the lattice's scores ``(N,)`` (``-inf`` off the free poses) with the
    unnormalized CDF of ``(1 - eps) softmax(scale x score) + eps / F`` over the F free poses,
    ``eps`` = ``uniform_share``; the last entry is the total, 1 up to rounding. A pose
    ``SOFTMAX_CUTOFF`` nats below the best gets ``eps / F`` alone (its softmax share is below
    e^-40 of the best's)."""
    top = -np.inf
    n_free = 0
    for i in range(scores.shape[0]):
        if scores[i] > -np.inf:
            top = max(top, scale * scores[i])
            n_free += 1
    uniform_mass = uniform_share / n_free
    for i in numba.prange(scores.shape[0]):  # the exps, in parallel in the twin
        v = scale * scores[i] - top
        scores[i] = math.exp(v) if v > -SOFTMAX_CUTOFF else (0.0 if v > -np.inf else -1.0)
    total = 0.0
    for i in range(scores.shape[0]):  # in order, so that both twins add alike
        if scores[i] > 0.0:
            total += scores[i]
    softmax_mass = (1.0 - uniform_mass * n_free) / total
    running = 0.0
    for i in range(scores.shape[0]):
        if scores[i] >= 0.0:  # a free pose
            running += softmax_mass * scores[i] + uniform_mass
        scores[i] = running


proposal_cdf_parallel = parallel_twin(proposal_cdf)


@numba.njit(cache=True, nogil=True)
def near_bins_kernel(u: NDArray, half: int, n_bins: int) -> NDArray[np.bool_]:
    """``(n_bins,)`` bool: the bins of a circle within ``half`` bins of one holding a point;
    the points' coordinates ``u`` ``(K,)`` are in bins (``[0, n_bins]``)."""
    seeded = np.zeros(n_bins, dtype=np.bool_)
    for k in range(u.shape[0]):
        seeded[math.floor(u[k]) % n_bins] = True
    out = np.zeros(n_bins, dtype=np.bool_)
    for b in range(n_bins):
        if seeded[b]:
            for d in range(-half, half + 1):
                out[(b + d) % n_bins] = True
    return out


@numba.njit(cache=True, nogil=True)
def near_cells_kernel(
    u: NDArray, v: NDArray, half_u: int, half_v: int, free: NDArray
) -> NDArray[np.bool_]:
    """``(X, Y)`` bool: the ``free`` cells within ``half_u`` cells along the first axis and
    ``half_v`` along the second of a cell holding a point; the points' coordinates ``u``,
    ``v`` ``(K,)`` are in lattice cells. A box of half-widths ``(a, b)`` cells around a point
    lies within ``(ceil a, ceil b)`` cells of the point's own cell, since
    ``floor(x + a) <= floor(x) + ceil(a)``; a point off the lattice counts at its edge cell,
    which only widens the result."""
    nx, ny = free.shape
    seeded = np.zeros((nx + 1, ny + 1), dtype=np.int64)  # prefix sums of the points' cells
    for k in range(u.shape[0]):
        i = min(max(math.floor(u[k]), 0), nx - 1)
        j = min(max(math.floor(v[k]), 0), ny - 1)
        seeded[i + 1, j + 1] = 1
    for i in range(1, nx + 1):
        for j in range(1, ny + 1):
            seeded[i, j] += seeded[i - 1, j] + seeded[i, j - 1] - seeded[i - 1, j - 1]
    out = np.zeros((nx, ny), dtype=np.bool_)
    for i in range(nx):
        i0, i1 = max(i - half_u, 0), min(i + half_u + 1, nx)
        for j in range(ny):
            if free[i, j]:
                j0, j1 = max(j - half_v, 0), min(j + half_v + 1, ny)
                out[i, j] = (seeded[i1, j1] - seeded[i0, j1] - seeded[i1, j0]
                             + seeded[i0, j0]) > 0
    return out


def update_with_scan(
    belief: MCLBelief,
    ranges: NDArray[np.float64],
    score: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    dual: LidarDualProposal | None,
    rng: np.random.Generator,
) -> None:
    """Correct an MCL belief with a lidar scan ``ranges`` ``(M,)`` (m), as the env's filter
    does: ``score(poses (K, 3)) -> (K,)`` is the filter's log-likelihood; mixture MCL draws its
    dual poses from ``dual`` (the current map's lattice)."""
    log_lik = score(belief.particles)
    if belief.proposal != "mixture":
        belief.update(log_lik, rng)
        return
    if dual is None:
        raise ValueError("mixture MCL on a grid map needs the map's LidarDualProposal")
    exponent = belief.likelihood_exponent

    def draw(n: int, gen: np.random.Generator,
             support: KernelSupport | None) -> tuple[NDArray, NDArray]:
        return dual.draw(n, ranges, exponent, gen, support)

    belief.update_mixture(log_lik, draw, score, rng)
