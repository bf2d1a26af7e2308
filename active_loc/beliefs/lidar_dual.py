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

    def scores(self, ranges: NDArray[np.float64]) -> NDArray[np.float64]:
        """The likelihood field's log-likelihood ``(X, Y, H)`` (nats, the scored beams only) of
        the scan ``ranges`` ``(M,)`` (m) at the lattice poses; ``-inf`` off the free cells."""
        nx, ny = self.free.shape
        out = np.empty((nx, ny, DUAL_HEADINGS))  # per call: sub-envs share the lattice
        lattice_field_log_likelihood(
            self.sensor, np.asarray(ranges, dtype=np.float64),
            2.0 * np.pi * np.arange(DUAL_HEADINGS) / DUAL_HEADINGS,
            (np.arange(nx) + 0.5) * self.cell_ratio, (np.arange(ny) + 0.5) * self.cell_ratio,
            self.free, self.resolution, self.table, out=out, beams=self.beams,
        )
        return out

    def draw(
        self, n: int, ranges: NDArray[np.float64], exponent: float, rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``n`` dual poses ``(n, 3)`` (m, m, rad) for the scan ``ranges`` ``(M,)`` and their
        log-density ``(n,)`` under the proposal; ``exponent`` is the filter's likelihood
        exponent. Draws ``4 n`` uniforms from ``rng``."""
        cdf = self.scores(ranges).reshape(-1)  # overwritten by the proposal's CDF
        scale = exponent * self.n_beams / self.beams.shape[0]
        pick(proposal_cdf, proposal_cdf_parallel)(cdf, scale, DEFENSIVE_SHARE)
        u = rng.random((n, 4))
        total = cdf[-1]
        pose = np.minimum(np.searchsorted(cdf, u[:, 0] * total, side="right"), cdf.shape[0] - 1)
        prob = (cdf[pose] - np.where(pose > 0, cdf[pose - 1], 0.0)) / total
        cell = pose // DUAL_HEADINGS
        ny = self.free.shape[1]
        gx = (cell // ny + u[:, 1]) * self.cell_ratio  # map grid coordinates (cells)
        gy = (cell % ny + u[:, 2]) * self.cell_ratio
        ox, oy, yaw = self.origin
        c, s = math.cos(yaw), math.sin(yaw)
        poses = np.empty((n, 3))
        poses[:, 0] = ox + self.resolution * (c * gx - s * gy)
        poses[:, 1] = oy + self.resolution * (s * gx + c * gy)
        bin_width = 2.0 * np.pi / DUAL_HEADINGS
        poses[:, 2] = wrap_angle(yaw + (pose % DUAL_HEADINGS + u[:, 3]) * bin_width)
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

    def draw(n: int, gen: np.random.Generator) -> tuple[NDArray, NDArray]:
        return dual.draw(n, ranges, exponent, gen)

    belief.update_mixture(log_lik, draw, score, rng)
