"""The simulator of one localization episode with a grid Markov belief (the chapter's
Algorithm 1) on an occupancy grid seen through a lidar.

The episode is :class:`~active_loc.envs.particle_core.ParticleCore`'s (the same map draws,
true start, unicycle with noise blocked by walls, people, lidar scan, metrics and ``state``
row); only the filter differs:

    controls -> true motion (noise, blocked by walls) -> scan from the true pose
             -> grid predict (fractional per-heading kernels; V = 0 after a collision)
             -> lidar likelihood field at every free cell pose, tempered -> grid update
             -> metrics (histogram entropy + log cell volume, errors) and the observation row

The belief (:class:`~active_loc.beliefs.grid.GridBelief`, B = 1) lives on cells of
``grid_cell_size`` m laid over the map from its origin, ``grid_headings`` heading bins each;
a cell is free when it holds a FREE map cell (so the true pose is never ruled out by the
discretization), and only free cell poses are scored. The likelihood of a scan is the
filter's lidar model at each cell pose (centre and bin heading), raised to
``likelihood_exponent`` (as in MCL: beams are not independent, and a cell pose is up to half
a cell and half a bin away from the robot it stands for).

Observation: the same layout as the particle core's: the belief header, an ``8 x 8``
histogram of the belief's x-y marginal pooled over the map, then the lidar ranges /
max_range. Mean and covariance are those of the histogram's piecewise-constant density
(:meth:`GridBelief.moments <active_loc.beliefs.grid.GridBelief.moments>`: circular heading
mean, the cells' own spread included), the density whose entropy is reported, so the
localized test (largest position std, heading std) is about the same density as the reward.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from active_loc.beliefs.grid import GridBelief, coarse_free_mask
from active_loc.envs.config import LocalizationConfig
from active_loc.envs.particle_core import HISTOGRAM_CELLS, ParticleCore, build_lidar
from active_loc.maps import LandmarkMap, OccupancyGrid
from active_loc.sensors.lidar_lattice import (
    lattice_field_log_likelihood,
    off_map_log_probability,
    padded_table,
)


class GridCore(ParticleCore):
    """One episode with a grid Markov belief on an occupancy grid with a lidar.

    Offers what :class:`active_loc.envs.localization_env.ActiveLocalizationEnv` uses of a core
    (as :class:`~active_loc.envs.particle_core.ParticleCore`): ``state`` ``(1, STATE_SIZE)``,
    ``obs`` ``(1, D)``, ``actions`` ``(1, 2)``, ``reset_member(0, rng)``, ``step(rngs)``,
    ``belief`` (a :class:`~active_loc.beliefs.grid.GridBelief`), ``maps``, ``models``.
    """

    belief_name = "grid"

    def __init__(self, config: LocalizationConfig) -> None:
        if not config.uses_grid:
            raise ValueError("GridCore runs on grid maps: it needs sensor='lidar'")
        super().__init__(config)
        self.belief: GridBelief | None = None  # type: ignore[assignment]
        self._template: GridBelief | None = None  # uniform over the current map's free cells
        self._free_index: NDArray[np.int64] | None = None  # (F,) flat free cells
        self._poses: NDArray[np.float64] | None = None  # (F H, 3) their cell poses
        # the likelihood field on the lattice: the cells' columns (X,) and rows (Y,) in the
        # map's grid coordinates, the bins' headings in its frame (H,), the framed table
        self._lattice: tuple[NDArray[np.float64], ...] = ()
        self._lattice_table: NDArray[np.float64] | None = None
        self._log_lik: NDArray[np.float64] | None = None  # (X, Y, H), -inf off the free cells
        self._map_resolution = 1.0
        self._hist_bins: NDArray[np.int64] | None = None  # (X Y,) 8 x 8 bin of each cell
        noise = np.asarray(config.motion_noise_std, dtype=np.float64)
        self._noise_std = noise

    # -- map and belief ------------------------------------------------------------------------

    @classmethod
    def derive_map_data(cls, cfg: LocalizationConfig, lmap: LandmarkMap | OccupancyGrid) -> dict:
        """The simulator's per-map arrays, then the belief's cells, their poses and the
        lattice the likelihood field is scored on."""
        data = super().derive_map_data(cfg, lmap)
        assert isinstance(lmap, OccupancyGrid)
        free = coarse_free_mask(lmap, cfg.grid_cell_size)
        template = GridBelief(free, cfg.grid_headings, cfg.grid_cell_size, lmap.origin)
        nx, ny, nh = free.shape[0], free.shape[1], cfg.grid_headings
        poses = template.cell_poses()  # (X, Y, H, 3)
        template.clearance  # noqa: B018  (computed once per map, shared by the episodes' copies)
        free_index = np.flatnonzero(free.ravel())
        ratio = cfg.grid_cell_size / lmap.resolution
        lattice_table = None
        if data["_log_table"] is not None:
            lattice_table = padded_table(data["_log_table"],
                                         off_map_log_probability(build_lidar(cfg)))
        centres = poses[:, :, 0, :2].reshape(-1, 2)
        x_min, y_min, x_max, y_max = lmap.bounds
        cells = HISTOGRAM_CELLS
        ix = np.clip(((centres[:, 0] - x_min) / (x_max - x_min) * cells).astype(np.int64), 0,
                     cells - 1)
        iy = np.clip(((centres[:, 1] - y_min) / (y_max - y_min) * cells).astype(np.int64), 0,
                     cells - 1)
        data.update(
            _template=template,
            _free_index=free_index,
            _poses=np.ascontiguousarray(poses.reshape(nx * ny, nh, 3)[free_index].reshape(-1, 3)),
            _map_resolution=lmap.resolution,
            _lattice=((np.arange(nx) + 0.5) * ratio, (np.arange(ny) + 0.5) * ratio,
                      2.0 * np.pi * np.arange(nh) / nh),
            _lattice_table=lattice_table,
            _hist_bins=iy * cells + ix,
        )
        return data

    def _bind_map(self, lmap: LandmarkMap | OccupancyGrid, data: dict) -> None:
        """The shared per-map arrays, and this core's own likelihood buffer."""
        super()._bind_map(lmap, data)
        assert self._template is not None
        self._log_lik = np.full(self._template.shape[1:], -np.inf)

    def _init_belief(self, rng: np.random.Generator) -> None:
        """Uniform over the free cell poses, or a Gaussian around the true start plus
        ``initial_error_std`` noise evaluated at them."""
        assert self._template is not None
        self.belief = self._template.copy()
        if self.config.initial_belief != "uniform":
            mean, cov = self._initial_gaussian(rng)
            self.belief.initialize_gaussian(mean, cov)

    # -- Algorithm 1 ---------------------------------------------------------------------------

    def _filter_step(self, v: float, omega: float, rng: np.random.Generator) -> None:
        """Predict with the control, take the scan from the true pose, correct every free cell
        pose with its tempered lidar likelihood."""
        belief = self.belief
        assert belief is not None and self._log_lik is not None and self._poses is not None
        belief.predict_unicycle(v, omega, self.config.dt, self._noise_std)
        ranges = self._scan(rng)
        log_lik = self._log_lik  # (X, Y, H), -inf on occupied cells
        if self._lattice_table is not None and self.config.lidar_beam_skip is None:
            assert self.lidar is not None
            cols, rows, headings = self._lattice
            lattice_field_log_likelihood(
                self.lidar, ranges, headings, cols, rows, belief.free[0], self._map_resolution,
                self._lattice_table, out=log_lik,
            )
        else:  # beam model, or beam skipping: the particle filter's scoring, pose by pose
            flat = log_lik.reshape(-1, belief.n_headings)
            flat[self._free_index] = self._scan_log_likelihood(ranges, self._poses).reshape(
                -1, belief.n_headings
            )
        exponent = self.config.likelihood_exponent
        if exponent != 1.0:
            log_lik *= exponent  # -inf stays -inf
        belief.update_log(log_lik)

    # -- metrics and observation ---------------------------------------------------------------

    def _belief_summary(self) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float]:
        """Mean, covariance (cells' own spread included), entropy and its log det."""
        belief = self.belief
        assert belief is not None
        mean, cov = belief.moments()
        sign, logdet = np.linalg.slogdet(cov[0])
        entropy = float(belief.entropy()[0])
        return mean[0], cov[0], entropy, float(logdet) if sign > 0 else -np.inf

    def _mass_histogram(self, bounds: NDArray) -> NDArray[np.float64]:
        """``(64,)`` the belief's x-y marginal pooled to the ``8 x 8`` grid over the map."""
        belief = self.belief
        assert belief is not None and self._hist_bins is not None
        cells = HISTOGRAM_CELLS
        return np.bincount(self._hist_bins, weights=belief.marginal_xy()[0].ravel(),
                           minlength=cells * cells)
