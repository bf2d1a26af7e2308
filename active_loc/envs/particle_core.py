"""The simulator of one localization episode with a Monte Carlo (particle) belief.

The same step order as :mod:`active_loc.envs.landmark_core`, for ``belief="mcl"``:

    controls -> (kidnapping) -> true motion (noise, blocked by walls) -> scan from the true pose
             -> MCL predict + weight + resample (the filter never sees the true pose)
             -> metrics (histogram entropy, errors) and the observation row

on a landmark map (landmark sensors, known or identical-looking landmarks) or an occupancy
grid (lidar). A step costs hundreds of microseconds in the particle kernels, so this holder is
plain Python around them, one episode (B = 1). It writes its results into the same ``state``
row layout as the landmark core, so the env reads both the same way.

Observation (float32, in [-1, 1]): the belief header of :mod:`active_loc.envs.observations`,
then an ``8 x 8`` histogram of the particle mass over the map (a picture of a multi-modal
belief), then the scan: landmark slots on landmark maps, ranges / max_range for the lidar.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from pathlib import Path

import numba
import numpy as np
from numpy.typing import NDArray

from active_loc.beliefs.lidar_dual import LidarDualProposal, update_with_scan
from active_loc.beliefs.mcl import FreeSpace, MCLBelief
from active_loc.beliefs.particle_stats import ENTROPY_BINS
from active_loc.envs.actions import ControlLimits
from active_loc.envs.config import LocalizationConfig, check_start_pose, memory_parts
from active_loc.envs.crowd import Crowd
from active_loc.envs.field_checks import check_memory
from active_loc.envs.landmark_core import (
    N_PARAMS,
    P_SCALE,
    STATE_SIZE,
    EnvModels,
    StateViews,
    build_models,
    build_motion,
    fixed_landmark_map,
)
from active_loc.envs.metrics import belief_metrics
from active_loc.envs.observations import (
    BELIEF_HEADER,
    SLOT_SIZE,
    write_belief_header,
    write_landmark_slots,
)
from active_loc.envs.rewards import REWARD_CODES, outcome_term, uncertainty_reward
from active_loc.geometry import wrap_angle
from active_loc.maps import LandmarkMap, OccupancyGrid, random_landmark_map
from active_loc.maps.generators import GENERATORS
from active_loc.maps.pool import pool_map_rng, shared_pool
from active_loc.motion import move_on_grid, move_within_bounds
from active_loc.sensors.lidar import LidarSensor
from active_loc.sensors.range_table import RangeTable

HISTOGRAM_CELLS = 8


def particle_observation_size(config: LocalizationConfig) -> int:
    """Length of the observation of a particle belief."""
    scan = config.n_beams if config.uses_grid else SLOT_SIZE * config.max_landmarks
    return BELIEF_HEADER + HISTOGRAM_CELLS * HISTOGRAM_CELLS + scan


def build_lidar(cfg: LocalizationConfig, simulated: bool = False) -> LidarSensor:
    """The lidar of a grid config: the filter's model, or with ``simulated`` the real sensor
    (the same but for the hit noise, ``lidar_noise_std`` instead of ``lidar_sigma_hit``)."""
    z_hit, z_short, z_max, z_rand = cfg.lidar_mixture
    sigma = cfg.lidar_noise_std if simulated else cfg.lidar_sigma_hit
    return LidarSensor(
        n_beams=cfg.n_beams, fov=cfg.fov, max_range=cfg.max_range, sigma_hit=sigma,
        z_hit=z_hit, z_short=z_short, z_max=z_max, z_rand=z_rand,
        lambda_short=cfg.lidar_lambda_short, model=cfg.lidar_model,  # type: ignore[arg-type]
        unknown_reflects=cfg.unknown_reflects,
    )


def draw_map(cfg: LocalizationConfig, rng: np.random.Generator) -> LandmarkMap | OccupancyGrid:
    """A new generated map of the config (its generator, size and landmark count)."""
    if cfg.uses_grid:
        return GENERATORS[cfg.map](rng, size_m=cfg.map_size)
    return random_landmark_map(rng, cfg.map_size, cfg.n_landmarks)


def _pool_entry(
    core: type[ParticleCore], cfg: LocalizationConfig, index: int
) -> tuple[LandmarkMap | OccupancyGrid, dict]:
    """Map ``index`` of a pool and its derived arrays."""
    lmap = draw_map(cfg, pool_map_rng(index))
    return lmap, core.derive_map_data(cfg, lmap)


class ParticleCore(StateViews):
    """One episode with an MCL belief, on a landmark map or an occupancy grid.

    Offers what :class:`active_loc.envs.localization_env.ActiveLocalizationEnv` uses of a core:
    ``state`` ``(1, STATE_SIZE)``, ``obs`` ``(1, D)``, ``actions`` ``(1, 2)``,
    ``reset_member(0, rng)``, ``step(rngs)``, ``belief``, ``maps``, ``models``.
    """

    batch_size = 1
    #: the ``belief`` config value this core runs
    belief_name = "mcl"

    def __init__(self, config: LocalizationConfig) -> None:
        if config.belief != self.belief_name:
            raise ValueError(
                f"{type(self).__name__} runs belief={self.belief_name!r}, got {config.belief!r}"
            )
        self.config = config
        self.grid_mode = config.uses_grid
        if self.grid_mode:
            self.lidar: LidarSensor | None = build_lidar(config)
            self.true_lidar: LidarSensor | None = build_lidar(config, simulated=True)
            limits = ControlLimits(
                config.action_type, config.dt, config.v_min, config.v_max, config.omega_max
            )
            params = np.zeros(N_PARAMS)
            params[P_SCALE] = config.max_range
            self.models = EnvModels(
                build_motion(config), self.lidar, params, limits.primitives(), limits
            )
        else:
            self.lidar = self.true_lidar = None
            self.models = build_models(config)
        self.fixed_map = self._fixed_map()
        if self.fixed_map is not None and config.start == "fixed":
            check_start_pose(self.fixed_map, config.start_pose[:2])
        self._fixed_data: dict | None = None  # derive_map_data of the fixed map
        self.maps: list[LandmarkMap | OccupancyGrid | None] = [None]
        self.state = np.zeros((1, STATE_SIZE))
        self.obs = np.zeros((1, particle_observation_size(config)), dtype=np.float32)
        self.actions = np.zeros((1, 2))
        n = config.max_landmarks
        self.z = np.zeros((1, n, 2))
        self.visible = np.zeros((1, n), dtype=np.bool_)
        self.ranges = np.zeros((1, config.n_beams))
        self.landmarks = np.zeros((1, n, 2))
        self.belief: MCLBelief | None = None
        self._free: FreeSpace | None = None
        self._grid_arrays: tuple | None = None
        self._distance: NDArray[np.float64] | None = None
        self._log_table: NDArray[np.float64] | None = None  # likelihood field, per cell
        self._range_table: RangeTable | None = None  # beam model, precomputed casts
        self._dual: LidarDualProposal | None = None  # mixture MCL's scan lattice
        self.crowd: Crowd | None = None  # people the map does not hold
        self.t = 0
        self.kidnap_step = -1
        self.kidnapped = False  # the kidnapping of this episode has happened
        self._walls = False  # the map's border blocks motion (landmark maps)
        self._bin_variance = np.diag(np.square(ENTROPY_BINS) / 12.0)

    # -- reset ---------------------------------------------------------------------------------

    def reset_member(self, b: int, rng: np.random.Generator) -> None:
        """New episode: map, true start, initial belief, kidnapping step; no scan yet."""
        cfg = self.config
        lmap, data = self._episode_map(rng)
        if lmap is not self.maps[0]:
            self._bind_map(lmap, data)
        self.maps[0] = lmap
        self.state[0] = 0.0
        row = self.rows[0]
        row["bounds"] = lmap.bounds
        # grids block motion by their cells; a landmark map by its border when it has walls
        self._walls = isinstance(lmap, OccupancyGrid) or lmap.walls
        row["walls"] = self._walls
        if isinstance(lmap, LandmarkMap):
            row["n_landmarks"] = lmap.n_landmarks
        if cfg.start == "fixed":
            if self.fixed_map is None:  # a generated map: each one may block the start
                check_start_pose(lmap, cfg.start_pose[:2])
            row["pose"] = cfg.start_pose
        else:
            row["pose"] = self._random_free_pose(rng)
        self.crowd = None
        people = cfg.dynamic_obstacles
        if people is not None and people[0] > 0:
            assert isinstance(lmap, OccupancyGrid)
            self.crowd = Crowd.spawn(lmap, int(people[0]), float(people[1]), float(people[2]),
                                     row["pose"][:2], rng)
        self._init_belief(rng)
        self.t = 0
        self.kidnapped = False
        self.kidnap_step = -1
        if cfg.kidnap:
            lo, hi = cfg.kidnap_window
            first, last = max(1, round(lo * cfg.horizon)), max(1, round(hi * cfg.horizon))
            self.kidnap_step = int(rng.integers(first, last + 1))
        self.z[:] = 0.0
        self.visible[:] = False
        self.ranges[:] = 0.0
        self._finish(collided=False, kidnapped_now=False, first=True)

    def _init_belief(self, rng: np.random.Generator) -> None:
        """The episode's initial belief: uniform, or Gaussian around the true start plus
        ``initial_error_std`` noise."""
        cfg = self.config
        assert self._free is not None
        self.belief = MCLBelief(
            self._free, self.models.motion, cfg.n_particles, resampling=cfg.resampling,
            resample_threshold=cfg.resample_threshold, augmented=cfg.augmented,
            alpha_slow=cfg.recovery_alpha_slow, alpha_fast=cfg.recovery_alpha_fast, kld=cfg.kld,
            min_particles=min(cfg.min_particles, cfg.n_particles),
            likelihood_exponent=cfg.likelihood_exponent, proposal=cfg.proposal,
            mixture_share=cfg.mixture_share,
        )
        if cfg.initial_belief == "uniform":
            self.belief.initialize_uniform(rng)
        else:
            mean, cov = self._initial_gaussian(rng)
            self.belief.initialize_gaussian(mean, cov, rng)

    def _initial_gaussian(
        self, rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Mean ``(3,)`` (the true start plus ``initial_error_std`` noise) and covariance
        ``(3, 3)`` of a Gaussian initial belief."""
        cfg = self.config
        mean = self.pose[0] + rng.standard_normal(3) * cfg.initial_error_std
        mean[2] = wrap_angle(mean[2])
        return mean, np.diag(np.square(cfg.initial_belief_std))

    def _fixed_map(self) -> LandmarkMap | OccupancyGrid | None:
        cfg = self.config
        if not self.grid_mode:
            if isinstance(cfg.map, str) and cfg.map == "random":
                return None
            return fixed_landmark_map(cfg)
        if isinstance(cfg.map, OccupancyGrid):
            return cfg.map
        if cfg.map in GENERATORS:
            return None
        path = Path(cfg.map)
        if not path.is_file():
            raise ValueError(f"map={cfg.map!r}: no such map file")
        grid = OccupancyGrid.load(path, unknown_reflects=cfg.unknown_reflects)
        check_memory(memory_parts(cfg, grid.values.size, grid.resolution))
        return grid

    def _episode_map(self, rng: np.random.Generator) -> tuple[LandmarkMap | OccupancyGrid, dict]:
        """The map of a new episode and what the core derives from it: the fixed map, one of
        the pool's (``map_pool``), or a new one drawn with ``rng``."""
        cfg = self.config
        if self.fixed_map is not None:
            if self._fixed_data is None:
                self._fixed_data = self.derive_map_data(cfg, self.fixed_map)
            return self.fixed_map, self._fixed_data
        if cfg.map_pool is not None:
            build = functools.partial(_pool_entry, type(self), cfg)
            return shared_pool((type(self).__name__, repr(cfg)), cfg.map_pool, build).draw(rng)
        lmap = draw_map(cfg, rng)
        return lmap, self.derive_map_data(cfg, lmap)

    @classmethod
    def derive_map_data(cls, cfg: LocalizationConfig, lmap: LandmarkMap | OccupancyGrid) -> dict:
        """What the core derives from a map, by attribute name: the filter's free space and,
        on grids, the ray-casting arrays, the distance field and the lidar model's table
        (likelihood field) or precomputed casts (beam model with ``lidar_range_bins``), and
        for mixture MCL the scan lattice of its dual proposal. Read-only once built, so that
        the episodes and sub-envs drawing a pool's map share it."""
        if isinstance(lmap, OccupancyGrid):
            lidar = build_lidar(cfg)
            grid_arrays = lmap.kernel_arrays()
            distance = lmap.distance_field()
            log_table = range_table = None
            if lidar.model == "likelihood_field":
                log_table = lidar.log_table(distance)
            elif cfg.lidar_range_bins:
                range_table = RangeTable.build(lidar, grid_arrays, n_angles=cfg.lidar_range_bins)
            dual = None
            if cfg.proposal == "mixture":
                field = log_table if log_table is not None else lidar.log_table(distance)
                dual = LidarDualProposal.build(lmap, lidar, field)
            return {
                "_free": FreeSpace.from_grid(lmap.values, lmap.resolution, lmap.origin),
                "_grid_arrays": grid_arrays, "_distance": distance, "_log_table": log_table,
                "_range_table": range_table, "_dual": dual,
            }
        if lmap.n_landmarks > cfg.max_landmarks:
            raise ValueError(
                f"the map has {lmap.n_landmarks} landmarks but max_landmarks="
                f"{cfg.max_landmarks}; raise max_landmarks"
            )
        return {"_free": FreeSpace.from_box(*lmap.bounds), "_dual": None}

    def _bind_map(self, lmap: LandmarkMap | OccupancyGrid, data: dict) -> None:
        """Use the per-map arrays ``data`` (:meth:`derive_map_data`) of ``lmap``."""
        for name, value in data.items():
            setattr(self, name, value)
        if isinstance(lmap, LandmarkMap):
            self.landmarks[:] = 0.0
            self.landmarks[0, : lmap.n_landmarks] = lmap.positions

    @property
    def scan_dual(self) -> LidarDualProposal | None:
        """Mixture MCL's scan lattice for the current map (grid maps), else None."""
        return self._dual

    @property
    def range_table(self) -> RangeTable | None:
        """The beam model's precomputed casts for the current map (``lidar_range_bins > 0``
        with the beam model), else None."""
        return self._range_table

    def _random_free_pose(self, rng: np.random.Generator) -> NDArray[np.float64]:
        """A uniform free pose; on landmark maps 1 m (at most a quarter) away from the border."""
        lmap = self.maps[0]
        if isinstance(lmap, OccupancyGrid):
            xy = lmap.sample_free(rng, 1)[0]
            return np.array([xy[0], xy[1], rng.uniform(-np.pi, np.pi)])
        assert lmap is not None
        x_min, y_min, x_max, y_max = lmap.bounds
        margin = min(1.0, 0.25 * (x_max - x_min), 0.25 * (y_max - y_min))
        u = rng.random(3)
        return np.array([
            x_min + margin + u[0] * (x_max - x_min - 2 * margin),
            y_min + margin + u[1] * (y_max - y_min - 2 * margin),
            -np.pi + 2 * np.pi * u[2],
        ])

    # -- step ----------------------------------------------------------------------------------

    def step(self, rngs: Sequence[np.random.Generator]) -> int:
        """Advance the episode with the action in :attr:`actions`; -1, or 0 if not finite."""
        action = self.actions[0]
        if not np.all(np.isfinite(action)):
            return 0
        rng = rngs[0]
        limits = self.models.limits
        if limits.action_type == "continuous":
            v, omega = limits.decode(action)
        else:
            v, omega = float(action[0]), float(action[1])
        self.t += 1
        kidnapped_now = self.t == self.kidnap_step
        if kidnapped_now:
            self.pose[0] = self._random_free_pose(rng)
            self.kidnapped = True
        collided = self._move_truth(v, omega, rng)
        if self.crowd is not None:
            assert isinstance(self.maps[0], OccupancyGrid)
            self.crowd.step(self.maps[0], self.config.dt, self.pose[0, :2], rng)
        # a blocked robot did not move: the filter predicts with V = 0
        self._filter_step(0.0 if collided else v, omega, rng)
        self._finish(collided, kidnapped_now, first=False)
        return -1

    def _filter_step(self, v: float, omega: float, rng: np.random.Generator) -> None:
        """Predict with the control, take the scan from the true pose and correct."""
        belief = self.belief
        assert belief is not None
        belief.predict(np.array([v, omega]), rng)
        pose = self.pose[0]
        lmap = self.maps[0]
        if isinstance(lmap, OccupancyGrid):
            ranges = self._scan(rng)
            update_with_scan(belief, ranges,
                             functools.partial(self._scan_log_likelihood, ranges), self._dual,
                             rng)
        else:
            assert lmap is not None
            sensor = self.models.sensor
            z, visible = sensor.measure(pose, lmap.positions, rng)
            n = lmap.n_landmarks
            self.z[0, :n] = z
            self.visible[0, :n] = visible
            belief.update_landmarks(
                z, visible, lmap.positions, sensor, rng,
                known_correspondence=self.config.known_correspondences,
            )

    def _scan(self, rng: np.random.Generator) -> NDArray[np.float64]:
        """The lidar scan ``(M,)`` (m) from the true pose (people occlude), kept in
        :attr:`ranges`."""
        assert self.true_lidar is not None
        pose = self.pose[0]
        discs = self.crowd.discs if self.crowd is not None else None
        ranges = self.true_lidar.measure(pose, self._grid_arrays, rng, discs)
        self.ranges[0] = ranges
        return ranges

    def _scan_log_likelihood(
        self, ranges: NDArray[np.float64], poses: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """The filter's lidar log-likelihood ``(K,)`` of a scan at poses ``(K, 3)``: the
        likelihood field from its per-cell table, the beam model from the range table, or the
        beam model ray-casting every pose."""
        assert self.lidar is not None
        if self._log_table is not None:
            return self.lidar.field_log_likelihood(
                ranges, poses, self._grid_arrays, self._log_table,
                beam_skip=self.config.lidar_beam_skip, distance_field=self._distance,
            )
        if self._range_table is not None:
            return self._range_table.log_likelihood(ranges, poses)
        return self.lidar.log_likelihood(ranges, poses, self._grid_arrays)

    def _move_truth(self, v: float, omega: float, rng: np.random.Generator) -> bool:
        """Move the true robot with noise; returns whether walls blocked the translation."""
        pose = self.pose[0]
        noise = self.models.motion.noise_root @ rng.standard_normal(3)
        lmap = self.maps[0]
        if not isinstance(lmap, OccupancyGrid):
            box = self.rows[0]["bounds"]
            return bool(move_within_bounds(pose, v, omega, self.config.dt, noise, box,
                                           self._walls))
        crowd = self.crowd
        return move_on_grid(pose, v, omega, self.config.dt, noise, lmap,
                            crowd.blocks if crowd is not None else None)

    # -- metrics and observation ---------------------------------------------------------------

    def _finish(self, collided: bool, kidnapped_now: bool, first: bool) -> None:
        cfg = self.config
        row = self.rows[0]
        mean, cov, entropy, logdet = self._belief_summary()
        row["mean"] = mean
        row["cov"] = cov
        trace = float(np.trace(cov))
        row["uncertainty_reward"] = 0.0 if first else uncertainty_reward(
            REWARD_CODES[cfg.reward], row["entropy"], entropy, row["logdet"], logdet,
            row["trace"], trace,
        )
        row["entropy"] = entropy
        row["logdet"] = logdet
        row["trace"] = trace
        pose = row["pose"]
        pos_err = float(np.hypot(pose[0] - mean[0], pose[1] - mean[1]))
        head_err = float(abs(wrap_angle(pose[2] - mean[2])))
        # with a kidnapping ahead, or just behind, localizing now is not yet the end of the task
        unresolved = cfg.kidnap and (
            not self.kidnapped or self.t < self.kidnap_step + cfg.kidnap_grace
        )
        pos_std, head_std, localized, success, terminal = belief_metrics(
            cov, pos_err, head_err, unresolved, cfg.localized_position_std,
            cfg.localized_heading_std, cfg.success_position_tol, cfg.success_heading_tol,
        )
        row["pos_err"] = pos_err
        row["head_err"] = head_err
        row["pos_std"] = pos_std
        row["head_std"] = head_std
        row["collided"] = collided
        row["localized"] = localized
        row["success"] = success
        row["terminal"] = terminal
        row["outcome"] = 0.0 if first else outcome_term(terminal, success, cfg.outcome_reward)
        row["kidnapped"] = kidnapped_now
        row["n_visible"] = float(self.visible[0].sum()) if not self.grid_mode else 0.0
        self._write_observation(mean, cov, entropy)

    def _belief_summary(self) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float]:
        """The belief's mean ``(3,)``, covariance ``(3, 3)``, entropy (nats) and log det."""
        belief = self.belief
        assert belief is not None
        summary = belief.summary()
        # a particle set stands for a density at the resolution of the entropy bins, so its log
        # det adds a bin's own variance (d^2 / 12): finite even when every particle coincides
        sign, logdet = np.linalg.slogdet(summary.cov + self._bin_variance)
        return (summary.mean, summary.cov, summary.entropy,
                float(logdet) if sign > 0 else -np.inf)

    def _write_observation(self, mean: NDArray, cov: NDArray, entropy: float) -> None:
        out = self.obs[0]
        bounds = self.rows[0]["bounds"]
        write_belief_header(mean, cov, entropy, bounds, out)
        # where the belief's mass is, on a coarse grid over the map
        cells = HISTOGRAM_CELLS
        hist = self._mass_histogram(bounds)
        start = BELIEF_HEADER
        out[start : start + cells * cells] = np.clip(hist, 0.0, 1.0)
        start += cells * cells
        if self.grid_mode:
            assert self.lidar is not None
            out[start:] = np.clip(self.ranges[0] / self.lidar.max_range, 0.0, 1.0)
        else:
            lmap = self.maps[0]
            assert isinstance(lmap, LandmarkMap)
            write_landmark_slots(
                mean, self.z[0], self.visible[0], self.landmarks[0], lmap.n_landmarks,
                self.models.sensor.kind, self.models.scale, out[start:],
            )

    def _mass_histogram(self, bounds: NDArray) -> NDArray[np.float64]:
        """``(64,)`` the belief's mass in each cell of an ``8 x 8`` grid over the map box
        ``bounds`` ``(4,)``, row-major from the bottom-left (index ``iy * 8 + ix``)."""
        belief = self.belief
        assert belief is not None
        return mass_histogram(belief.particles[:, :2], belief.summary().weights, bounds)


@numba.njit(cache=True, nogil=True)
def mass_histogram(
    points: NDArray[np.float64], weights: NDArray[np.float64], bounds: NDArray
) -> NDArray[np.float64]:
    """``(64,)`` the total weight of points ``(K, 2)`` (m) in each cell of an ``8 x 8`` grid
    over the box ``bounds`` ``(4,)``, row-major from the bottom-left; points outside fall
    into the border cells. (A kernel that releases the GIL: the vector env's worker threads
    build the observations of two sub-envs at once.)"""
    cells = HISTOGRAM_CELLS
    out = np.zeros(cells * cells)
    width = bounds[2] - bounds[0]
    height = bounds[3] - bounds[1]
    for k in range(points.shape[0]):
        ix = min(max(int((points[k, 0] - bounds[0]) / width * cells), 0), cells - 1)
        iy = min(max(int((points[k, 1] - bounds[1]) / height * cells), 0), cells - 1)
        out[iy * cells + ix] += weights[k]
    return out
