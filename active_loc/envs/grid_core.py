"""The simulator of B localization episodes with a grid Markov belief each (the chapter's
Algorithm 1) on occupancy grids seen through a lidar, the beliefs stepped together.

Each episode is :class:`~active_loc.envs.particle_core.ParticleCore`'s (the same map draws,
true start, unicycle with noise blocked by walls, people, lidar scan, metrics and ``state``
row); only the filter differs:

    controls -> true motion (noise, blocked by walls) -> scan from the true pose
             -> grid predict (fractional per-heading kernels; V = 0 after a collision)
             -> lidar likelihood field at every free cell pose, tempered -> grid update
             -> metrics (histogram entropy + log cell volume, errors) and the observation row

The beliefs are one :class:`~active_loc.beliefs.grid.GridBelief` of B members: each kernel
(prediction, correction, entropy, moments) takes every member in one call, and only the
scan's likelihood field is scored member by member (each against its own map). They live on
cells of
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
The image of ``observation="image"`` pools each cell's mass into the image cell that holds its
centre and each heading bin into the image channel that holds its heading.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from active_loc.beliefs.grid import GridBelief, coarse_free_mask
from active_loc.envs.belief_image import grid_image_index, pooled_grid_image
from active_loc.envs.config import LocalizationConfig
from active_loc.envs.particle_core import (
    HISTOGRAM_CELLS,
    BeliefSummary,
    Episode,
    MapData,
    ParticleCore,
    build_lidar,
)
from active_loc.maps import LandmarkMap, OccupancyGrid
from active_loc.parallel import thread_count
from active_loc.sensors.lidar_lattice import (
    lattice_field_log_likelihood,
    off_map_log_probability,
    padded_table,
)


@dataclass(frozen=True, eq=False)
class GridMapData(MapData):
    """:class:`~active_loc.envs.particle_core.MapData` and what the grid filter derives
    from the same map.

    Attributes:
        template: a one-member belief uniform over the map's free cells (its clearance
            computed), copied at every reset.
        free_index: ``(F,)`` the flat indices of the free cells.
        poses: ``(F H, 3)`` their cell poses (m, m, rad).
        lattice: the cells' columns ``(X,)`` and rows ``(Y,)`` in the map's grid coordinates,
            and the bins' headings ``(H,)`` in its frame, for the likelihood field.
        lattice_table: the likelihood field's table framed by its off-map value (None with
            the beam model).
        hist_bins: ``(X Y,)`` the ``8 x 8`` observation bin of each cell.
        map_resolution: the map's cell side (m).
        image_cells, image_channels: ``(X Y,)`` the image cell of each belief cell and
            ``(H,)`` the image channel of each heading bin (``observation="image"``; see
            :func:`~active_loc.envs.belief_image.grid_image_index`).
    """

    template: GridBelief | None = None
    free_index: NDArray[np.int64] | None = None
    poses: NDArray[np.float64] | None = None
    lattice: tuple[NDArray[np.float64], ...] = ()
    lattice_table: NDArray[np.float64] | None = None
    hist_bins: NDArray[np.int64] | None = None
    map_resolution: float = 1.0
    image_cells: NDArray[np.int64] | None = None
    image_channels: NDArray[np.int64] | None = None


class GridCore(ParticleCore):
    """B episodes with a grid Markov belief each, on occupancy grids with a lidar.

    Offers the simulator interface of :class:`~active_loc.envs.particle_core.ParticleCore`;
    :attr:`belief` is the :class:`~active_loc.beliefs.grid.GridBelief` of all B members
    (member ``b``: ``belief.member(b)``). The members' maps must share one grid (cells and
    origin), as the generated maps of a config and a fixed map do.

    Args:
        config: the task (``belief="grid"``, ``sensor="lidar"``).
        batch_size: B.
    """

    belief_name = "grid"

    def __init__(self, config: LocalizationConfig, batch_size: int = 1) -> None:
        if not config.uses_grid:
            raise ValueError("GridCore runs on grid maps: it needs sensor='lidar'")
        super().__init__(config, batch_size)
        self.grid_belief: GridBelief | None = None  # all members (made at the first reset)
        self._log_lik: NDArray[np.float64] | None = None  # (B, X, Y, H), -inf off free cells
        self._noise_std = np.asarray(config.motion_noise_std, dtype=np.float64)

    # -- map and belief ------------------------------------------------------------------------

    @property
    def belief(self) -> GridBelief | None:  # type: ignore[override]
        """The grid beliefs of all B members (None before the first reset)."""
        return self.grid_belief

    def member_belief(self, b: int) -> GridBelief | None:  # type: ignore[override]
        """A copy of member ``b``'s belief alone (B = 1)."""
        return None if self.grid_belief is None else self.grid_belief.member(b)

    def _data(self, b: int) -> GridMapData:
        data = self.episode(b).data
        assert isinstance(data, GridMapData)
        return data

    @classmethod
    def derive_map_data(cls, cfg: LocalizationConfig, lmap: LandmarkMap | OccupancyGrid
                        ) -> GridMapData:
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
        if data.log_table is not None:
            lattice_table = padded_table(data.log_table,
                                         off_map_log_probability(build_lidar(cfg)))
        centres = poses[:, :, 0, :2].reshape(-1, 2)
        x_min, y_min, x_max, y_max = lmap.bounds
        cells = HISTOGRAM_CELLS
        ix = np.clip(((centres[:, 0] - x_min) / (x_max - x_min) * cells).astype(np.int64), 0,
                     cells - 1)
        iy = np.clip(((centres[:, 1] - y_min) / (y_max - y_min) * cells).astype(np.int64), 0,
                     cells - 1)
        image_cells = image_channels = None
        if cfg.observation == "image":
            image_cells, image_channels = grid_image_index(
                poses[:, :, 0, 0], poses[:, :, 0, 1], poses[0, 0, :, 2], lmap.bounds,
                cfg.image_size, cfg.image_headings)
        return GridMapData(
            **vars(data),
            template=template,
            free_index=free_index,
            poses=np.ascontiguousarray(poses.reshape(nx * ny, nh, 3)[free_index].reshape(-1, 3)),
            lattice=((np.arange(nx) + 0.5) * ratio, (np.arange(ny) + 0.5) * ratio,
                     2.0 * np.pi * np.arange(nh) / nh),
            lattice_table=lattice_table,
            hist_bins=iy * cells + ix,
            map_resolution=lmap.resolution,
            image_cells=image_cells,
            image_channels=image_channels,
        )

    def _bind_map(self, b: int, episode: Episode) -> None:
        """Member ``b``'s likelihood buffer is cleared for its new map (the beam model writes
        only the free cells); the batch's belief is made with the first map's grid."""
        super()._bind_map(b, episode)
        template = self._data(b).template
        assert template is not None
        if self.grid_belief is None:
            free = np.repeat(template.free, self.batch_size, axis=0)
            self.grid_belief = GridBelief(free, template.n_headings, template.cell_size,
                                          template.origin)
            self._log_lik = np.full(self.grid_belief.shape, -np.inf)
        assert self._log_lik is not None
        self._log_lik[b] = -np.inf

    def _init_belief(self, b: int, rng: np.random.Generator) -> None:
        """Member ``b`` uniform over its free cell poses, or a Gaussian around the true start
        plus ``initial_error_std`` noise evaluated at them."""
        template = self._data(b).template
        assert template is not None and self.grid_belief is not None
        member = template.copy()
        if self.config.initial_belief != "uniform":
            mean, cov = self._initial_gaussian(b, rng)
            member.initialize_gaussian(mean, cov)
        self.grid_belief.set_member(b, member)

    # -- step ----------------------------------------------------------------------------------

    def _step_members(
        self, members: list[int], controls: NDArray[np.float64],
        rngs: Sequence[np.random.Generator], threads: int | None,
    ) -> None:
        """One step of ``members`` with their ``controls`` ``(B, 2)``: each member's world,
        then every belief in one call of each grid kernel on ``threads`` numba threads (1:
        their serial twins; None: this thread's setting), then each member's metrics. The
        members not stepped are about to be reset: their beliefs are predicted and corrected
        with stale values, never their Generators touched."""
        collided = np.zeros(self.batch_size, dtype=np.bool_)
        kidnapped_now = np.zeros(self.batch_size, dtype=np.bool_)
        for b in members:
            kidnapped_now[b], collided[b] = self._advance_truth(
                b, float(controls[b, 0]), float(controls[b, 1]), rngs[b])
        # a blocked robot did not move: the filter predicts with V = 0
        controls[collided, 0] = 0.0
        with thread_count(threads):
            self._filter_step(members, controls, rngs)
            assert self.grid_belief is not None
            summaries = self._summaries(self.grid_belief, members, members)
        for b, summary in zip(members, summaries, strict=True):
            self._finish(b, *summary, collided=bool(collided[b]),
                         kidnapped_now=bool(kidnapped_now[b]), first=False)

    def reset_members(
        self, rows: Sequence[int], rngs: Sequence[np.random.Generator],
        threads: int | None = None,
    ) -> None:
        """:meth:`reset_member` of each member in ``rows``, in turn whatever ``threads`` says:
        the members share the batch's belief arrays."""
        super().reset_members(rows, rngs, threads=None)

    # -- Algorithm 1 ---------------------------------------------------------------------------

    def _filter_step(
        self, members: list[int], controls: NDArray[np.float64],
        rngs: Sequence[np.random.Generator],
    ) -> None:
        """Predict every member with its control, take the stepped members' scans from their
        true poses, correct every free cell pose with its tempered lidar likelihood."""
        belief = self.grid_belief
        log_lik = self._log_lik  # (B, X, Y, H), -inf on occupied cells
        assert belief is not None and log_lik is not None
        belief.predict_unicycle(controls[:, 0], controls[:, 1], self.config.dt, self._noise_std)
        exponent = self.config.likelihood_exponent
        for b in members:
            ranges = self._scan(b, rngs[b])
            data = self._data(b)
            if data.lattice_table is not None and self.config.lidar_beam_skip is None:
                assert self.lidar is not None
                cols, rows, headings = data.lattice
                lattice_field_log_likelihood(
                    self.lidar, ranges, headings, cols, rows, belief.free[b],
                    data.map_resolution, data.lattice_table, out=log_lik[b], scale=exponent,
                )
            else:  # beam model, or beam skipping: the particle filter's scoring, pose by pose
                assert data.poses is not None
                flat = log_lik[b].reshape(-1, belief.n_headings)
                flat[data.free_index] = self._scan_log_likelihood(
                    b, ranges, data.poses).reshape(-1, belief.n_headings)
                if exponent != 1.0:
                    log_lik[b] *= exponent  # -inf stays -inf
        # the members not stepped are reset next: their likelihoods are stale, but finite
        belief.update_log(log_lik)

    # -- metrics and observation ---------------------------------------------------------------

    def _write_image(self, b: int) -> None:
        """Member ``b``'s belief channels of its image: its cells' mass pooled."""
        data = self._data(b)
        assert self.grid_belief is not None and self.image is not None
        assert data.image_cells is not None and data.image_channels is not None
        pooled_grid_image(self.grid_belief.prob[b], data.image_cells, data.image_channels,
                          self.image[b])

    def _reset_summary(self, b: int) -> BeliefSummary:
        """The summary of member ``b``'s new belief, from a one-member copy (the kernels then
        read one member, not the batch)."""
        member = self.member_belief(b)
        assert member is not None
        return self._summaries(member, [0], [b])[0]

    def _summaries(self, belief: GridBelief, rows: list[int], members: list[int]
                   ) -> list[BeliefSummary]:
        """Summaries of ``belief``'s ``rows``, which hold the core's ``members`` (aligned;
        the same indices unless the belief is a copy): mean, covariance (cells' own spread
        included), entropy, its log det, the ``8 x 8`` histogram of the x-y marginal."""
        mean, cov = belief.moments()
        entropy = belief.entropy()
        marginal = belief.marginal_xy()
        cells = HISTOGRAM_CELLS
        out = []
        for row, b in zip(rows, members, strict=True):
            sign, logdet = np.linalg.slogdet(cov[row])
            bins = self._data(b).hist_bins
            assert bins is not None
            hist = np.bincount(bins, weights=marginal[row].ravel(), minlength=cells * cells)
            out.append(BeliefSummary(mean[row], cov[row], float(entropy[row]),
                                     float(logdet) if sign > 0 else -np.inf, hist))
        return out
