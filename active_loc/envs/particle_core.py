"""The simulator of B localization episodes with a Monte Carlo (particle) belief each.

The same step order as :mod:`active_loc.envs.landmark_core`, for ``belief="mcl"``:

    controls -> (kidnapping) -> true motion (noise, blocked by walls) -> scan from the true pose
             -> MCL predict + weight + resample (the filter never sees the true pose)
             -> metrics (histogram entropy, errors) and the observation row

on a landmark map (landmark sensors, known or identical-looking landmarks) or an occupancy
grid (lidar). A step costs hundreds of microseconds in the particle kernels, so this holder is
plain Python around them: the members' filters run one after another (a single env is B = 1).
It writes its results into the same ``state`` row layout as the landmark core, so the envs
read both the same way.

Observation (float32, in [-1, 1]): the belief header of :mod:`active_loc.envs.observations`,
then an ``8 x 8`` histogram of the particle mass over the map (a picture of a multi-modal
belief), then the scan: landmark slots on landmark maps, ranges / max_range for the lidar.
With ``observation="image"`` the core also keeps :attr:`image`, the belief as an image over
the map (:mod:`active_loc.envs.belief_image`).
"""

from __future__ import annotations

import functools
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numba
import numpy as np
from numpy.typing import NDArray

from active_loc.beliefs.lidar_dual import LidarDualProposal, update_with_scan
from active_loc.beliefs.mcl import FreeSpace, MCLBelief
from active_loc.beliefs.particle_stats import ENTROPY_BINS
from active_loc.envs.actions import ControlLimits
from active_loc.envs.belief_image import image_shape, map_channel, particle_image
from active_loc.envs.config import LocalizationConfig, check_start_pose, memory_parts
from active_loc.envs.crowd import Crowd
from active_loc.envs.field_checks import check_memory
from active_loc.envs.landmark_core import (
    N_PARAMS,
    N_STATS,
    P_SCALE,
    S_COLLIDED,
    S_KIDNAPPED,
    S_N_VISIBLE,
    S_OUTCOME,
    S_UNCERTAINTY_REWARD,
    STATE_SIZE,
    X_BOX,
    X_COV,
    X_MEAN,
    X_STATS,
    EnvModels,
    StateViews,
    build_models,
    build_motion,
    fixed_landmark_map,
    record_metrics,
    write_task_params,
)
from active_loc.envs.observations import (
    BELIEF_HEADER,
    SLOT_SIZE,
    write_belief_header,
    write_landmark_slots,
)
from active_loc.geometry import wrap_angle
from active_loc.maps import LandmarkMap, OccupancyGrid, random_landmark_map
from active_loc.maps.generators import GENERATORS
from active_loc.maps.pool import pool_map_rng, shared_pool
from active_loc.motion import move_on_grid, move_within_bounds
from active_loc.parallel import WorkerThreads
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


def _pool_entry(core: type[ParticleCore], cfg: LocalizationConfig,
                index: int) -> tuple[LandmarkMap | OccupancyGrid, MapData]:
    """Map ``index`` of a pool and its derived arrays."""
    lmap = draw_map(cfg, pool_map_rng(index))
    return lmap, core.derive_map_data(cfg, lmap)


@dataclass(frozen=True, eq=False)
class MapData:
    """What a particle core derives from one map, built once per map and read-only after,
    so that the episodes and sub-envs that draw a pool's map share it.

    Attributes:
        free: the filter's free space (uniform draws, the free-space test).
        grid_arrays: the ray-casting arrays of an occupancy grid (None on landmark maps).
        distance: the grid's distance field (m).
        log_table: the likelihood field's per-cell log-probabilities (likelihood field model).
        range_table: the beam model's precomputed casts (``lidar_range_bins > 0``).
        dual: mixture MCL's scan lattice (``proposal="mixture"`` on grids).
        image_map: ``(R, R)`` the map channel of ``observation="image"``
            (:func:`~active_loc.envs.belief_image.map_channel`; None without an image).
    """

    free: FreeSpace
    grid_arrays: tuple | None = None
    distance: NDArray[np.float64] | None = None
    log_table: NDArray[np.float64] | None = None
    range_table: RangeTable | None = None
    dual: LidarDualProposal | None = None
    image_map: NDArray[np.float32] | None = None


@dataclass(eq=False)
class Episode:
    """One member's episode, beside its ``state`` row: its map and what is derived from it,
    whether the map blocks motion, the people, the step count and the kidnapping."""

    map: LandmarkMap | OccupancyGrid
    data: MapData
    walls: bool  # grids block motion by their cells; a landmark map by its border if walled
    crowd: Crowd | None = None
    t: int = 0
    kidnap_step: int = -1  # the step the robot is kidnapped at (-1: never)
    kidnapped: bool = False  # the kidnapping has happened


class ParticleCore(StateViews):
    """B episodes with an MCL belief each, on landmark maps or occupancy grids.

    Offers the simulator interface of :class:`~active_loc.envs.landmark_core.LandmarkCore`:
    ``state`` ``(B, STATE_SIZE)``, ``obs`` ``(B, D)``, ``actions`` ``(B, 2)``,
    ``reset_member(b, rng)``, ``step(rngs, active)``, ``maps``, ``models``; per member its
    :attr:`episodes` entry and belief (:meth:`member_belief`). The members' filters run one
    after another (each on both cores when it is large); :class:`~active_loc.envs.grid_core.
    GridCore` steps its members' grid beliefs together.

    Args:
        config: the task.
        batch_size: B.
    """

    #: the ``belief`` config value this core runs
    belief_name = "mcl"

    def __init__(self, config: LocalizationConfig, batch_size: int = 1) -> None:
        if config.belief != self.belief_name:
            raise ValueError(
                f"{type(self).__name__} runs belief={self.belief_name!r}, got {config.belief!r}"
            )
        self.config = config
        self.batch_size = int(batch_size)
        self.grid_mode = config.uses_grid
        if self.grid_mode:
            self.lidar: LidarSensor | None = build_lidar(config)
            self.true_lidar: LidarSensor | None = build_lidar(config, simulated=True)
            limits = ControlLimits(
                config.action_type, config.dt, config.v_min, config.v_max, config.omega_max
            )
            params = np.zeros(N_PARAMS)
            params[P_SCALE] = config.max_range
            write_task_params(config, params)
            self.models = EnvModels(
                build_motion(config), self.lidar, params, limits.primitives(), limits
            )
        else:
            self.lidar = self.true_lidar = None
            self.models = build_models(config)
        self.fixed_map = self._fixed_map()
        if self.fixed_map is not None and config.start == "fixed":
            check_start_pose(self.fixed_map, config.start_pose[:2])
        self._fixed_data: MapData | None = None  # derive_map_data of the fixed map
        b, n = self.batch_size, config.max_landmarks
        self.episodes: list[Episode | None] = [None] * b
        self.state = np.zeros((b, STATE_SIZE))
        self.obs = np.zeros((b, particle_observation_size(config)), dtype=np.float32)
        if config.observation == "image":
            shape = image_shape(config.image_size, config.image_headings)
            self.image = np.zeros((b, *shape), dtype=np.float32)
        self.actions = np.zeros((b, 2))
        self.z = np.zeros((b, n, 2))
        self.visible = np.zeros((b, n), dtype=np.bool_)
        self.ranges = np.zeros((b, config.n_beams))
        self.landmarks = np.zeros((b, n, 2))
        self.beliefs: list[MCLBelief | None] = [None] * b
        self._workers: WorkerThreads | None = None  # started by the first threaded call
        self._seconds = np.zeros(b)  # how long each member's last threaded call took
        if self.fixed_map is not None:  # built now, so that threaded resets share it
            self._fixed_data = self.derive_map_data(config, self.fixed_map)
        self._bin_variance = np.diag(np.square(ENTROPY_BINS) / 12.0)

    # -- members -------------------------------------------------------------------------------

    @property
    def maps(self) -> list[LandmarkMap | OccupancyGrid | None]:
        """``(B,)`` each member's map (None before its first reset)."""
        return [None if e is None else e.map for e in self.episodes]

    def episode(self, b: int) -> Episode:
        """Member ``b``'s episode (after its first reset)."""
        episode = self.episodes[b]
        if episode is None:
            raise RuntimeError(f"member {b} has not been reset")
        return episode

    @property
    def belief(self) -> MCLBelief | None:
        """The first member's belief: the single env's."""
        return self.beliefs[0]

    def member_belief(self, b: int) -> MCLBelief | None:
        """Member ``b``'s belief (the object the filter updates)."""
        return self.beliefs[b]

    @property
    def scan_dual(self) -> LidarDualProposal | None:
        """Mixture MCL's scan lattice of the first member's map (grid maps), else None."""
        return None if self.episodes[0] is None else self.episode(0).data.dual

    @property
    def range_table(self) -> RangeTable | None:
        """The beam model's precomputed casts for the first member's map
        (``lidar_range_bins > 0`` with the beam model), else None."""
        return None if self.episodes[0] is None else self.episode(0).data.range_table

    # -- reset ---------------------------------------------------------------------------------

    def reset_member(self, b: int, rng: np.random.Generator) -> None:
        """New episode of member ``b``: map, true start, initial belief, kidnapping step; no
        scan yet."""
        cfg = self.config
        lmap, data = self._episode_map(rng)
        previous = self.episodes[b]
        # grids block motion by their cells; a landmark map by its border when it has walls
        walls = isinstance(lmap, OccupancyGrid) or lmap.walls
        episode = Episode(lmap, data, walls)
        self.episodes[b] = episode
        if previous is None or previous.map is not lmap:
            self._bind_map(b, episode)
        self.state[b] = 0.0
        row = self.rows[b]
        row["bounds"] = lmap.bounds
        row["walls"] = walls
        if isinstance(lmap, LandmarkMap):
            row["n_landmarks"] = lmap.n_landmarks
        if cfg.start == "fixed":
            if self.fixed_map is None:  # a generated map: each one may block the start
                check_start_pose(lmap, cfg.start_pose[:2])
            row["pose"] = cfg.start_pose
        else:
            row["pose"] = self._random_free_pose(b, rng)
        people = cfg.dynamic_obstacles
        if people is not None and people[0] > 0:
            assert isinstance(lmap, OccupancyGrid)
            episode.crowd = Crowd.spawn(lmap, int(people[0]), float(people[1]),
                                        float(people[2]), row["pose"][:2], rng)
        self._init_belief(b, rng)
        if cfg.kidnap:
            lo, hi = cfg.kidnap_window
            first, last = max(1, round(lo * cfg.horizon)), max(1, round(hi * cfg.horizon))
            episode.kidnap_step = int(rng.integers(first, last + 1))
        self.z[b] = 0.0
        self.visible[b] = False
        self.ranges[b] = 0.0
        self._finish(b, *self._reset_summary(b), collided=False, kidnapped_now=False,
                     first=True)

    def _init_belief(self, b: int, rng: np.random.Generator) -> None:
        """Member ``b``'s initial belief: uniform, or Gaussian around the true start plus
        ``initial_error_std`` noise."""
        cfg = self.config
        belief = MCLBelief(
            self.episode(b).data.free, self.models.motion, cfg.n_particles,
            resampling=cfg.resampling, resample_threshold=cfg.resample_threshold,
            augmented=cfg.augmented, alpha_slow=cfg.recovery_alpha_slow,
            alpha_fast=cfg.recovery_alpha_fast, recovery_threshold=cfg.recovery_threshold,
            kld=cfg.kld,
            min_particles=min(cfg.min_particles, cfg.n_particles),
            likelihood_exponent=cfg.likelihood_exponent, proposal=cfg.proposal,
            mixture_share=cfg.mixture_share,
        )
        if cfg.initial_belief == "uniform":
            belief.initialize_uniform(rng)
        else:
            mean, cov = self._initial_gaussian(b, rng)
            belief.initialize_gaussian(mean, cov, rng)
        self.beliefs[b] = belief

    def _initial_gaussian(
        self, b: int, rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Mean ``(3,)`` (member ``b``'s true start plus ``initial_error_std`` noise) and
        covariance ``(3, 3)`` of a Gaussian initial belief."""
        cfg = self.config
        mean = self.pose[b] + rng.standard_normal(3) * cfg.initial_error_std
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

    def _episode_map(self, rng: np.random.Generator) -> tuple[LandmarkMap | OccupancyGrid,
                                                               MapData]:
        """The map of a new episode and what the core derives from it: the fixed map, one of
        the pool's (``map_pool``), or a new one drawn with ``rng``."""
        cfg = self.config
        if self.fixed_map is not None:
            assert self._fixed_data is not None
            return self.fixed_map, self._fixed_data
        if cfg.map_pool is not None:
            build = functools.partial(_pool_entry, type(self), cfg)
            return shared_pool((type(self).__name__, repr(cfg)), cfg.map_pool, build).draw(rng)
        lmap = draw_map(cfg, rng)
        return lmap, self.derive_map_data(cfg, lmap)

    @classmethod
    def derive_map_data(cls, cfg: LocalizationConfig, lmap: LandmarkMap | OccupancyGrid
                        ) -> MapData:
        """What the core derives from a map (:class:`MapData`): the filter's free space and,
        on grids, the ray-casting arrays, the distance field and the lidar model's table
        (likelihood field) or precomputed casts (beam model with ``lidar_range_bins``), and
        for mixture MCL the scan lattice of its dual proposal; the map channel of an image
        observation."""
        image_map = None
        if cfg.observation == "image":
            image_map = map_channel(lmap, lmap.bounds, cfg.image_size)
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
            return MapData(FreeSpace.from_grid(lmap.values, lmap.resolution, lmap.origin),
                           grid_arrays, distance, log_table, range_table, dual, image_map)
        if lmap.n_landmarks > cfg.max_landmarks:
            raise ValueError(
                f"the map has {lmap.n_landmarks} landmarks but max_landmarks="
                f"{cfg.max_landmarks}; raise max_landmarks"
            )
        return MapData(FreeSpace.from_box(*lmap.bounds), image_map=image_map)

    def _bind_map(self, b: int, episode: Episode) -> None:
        """Member ``b`` has a new map: its per-member copies of the map's arrays."""
        lmap = episode.map
        if self.image is not None:
            self.image[b, -1] = episode.data.image_map
        if isinstance(lmap, LandmarkMap):
            self.landmarks[b] = 0.0
            self.landmarks[b, : lmap.n_landmarks] = lmap.positions

    def _random_free_pose(self, b: int, rng: np.random.Generator) -> NDArray[np.float64]:
        """A uniform free pose in member ``b``'s map; on landmark maps 1 m (at most a
        quarter) away from the border."""
        lmap = self.episode(b).map
        if isinstance(lmap, OccupancyGrid):
            xy = lmap.sample_free(rng, 1)[0]
            return np.array([xy[0], xy[1], rng.uniform(-np.pi, np.pi)])
        x_min, y_min, x_max, y_max = lmap.bounds
        margin = min(1.0, 0.25 * (x_max - x_min), 0.25 * (y_max - y_min))
        u = rng.random(3)
        return np.array([
            x_min + margin + u[0] * (x_max - x_min - 2 * margin),
            y_min + margin + u[1] * (y_max - y_min - 2 * margin),
            -np.pi + 2 * np.pi * u[2],
        ])

    # -- step ----------------------------------------------------------------------------------

    def step(
        self,
        rngs: Sequence[np.random.Generator],
        active: NDArray[np.bool_] | None = None,
        threads: int | None = None,
    ) -> int:
        """Advance the members with the actions in :attr:`actions` ``(B, 2)``.

        Args:
            rngs: the Generator of each member.
            active: ``(B,)`` which members to advance; None: all. (The others are about to
                be reset: their Generators are not touched.)
            threads: the threads that step the members (see :meth:`_step_members`); None
                or 1: this thread alone. The result does not depend on it.

        Returns:
            -1, or the index of a member whose action is not finite (nothing advanced then).
        """
        members = self._members(active)
        bad = self._first_bad_action(members)
        if bad >= 0:
            return bad
        self._step_members(members, self._controls(members), rngs, threads)
        return -1

    def _step_members(
        self, members: list[int], controls: NDArray[np.float64],
        rngs: Sequence[np.random.Generator], threads: int | None,
    ) -> None:
        """One step of each of ``members`` with its commanded ``controls[b]`` ``(V, omega)``:
        ``threads`` members at once, each on a worker thread and the kernels' serial
        twins; None or 1: one after another in this thread."""
        tasks = [(b, controls[b], rngs[b]) for b in members]
        self._run(self._step_member, tasks, threads)

    def reset_members(
        self, rows: Sequence[int], rngs: Sequence[np.random.Generator],
        threads: int | None = None,
    ) -> None:
        """:meth:`reset_member` of each member in ``rows`` with its Generator in ``rngs``
        (aligned with ``rows``), ``threads`` at once as in :meth:`step`."""
        self._run(self.reset_member, list(zip(rows, rngs, strict=True)), threads)

    def _run(self, fn: Any, tasks: list[tuple], threads: int | None) -> None:
        """``fn(b, ...)`` for each task ``(b, ...)``: in turn, or on ``threads`` worker
        threads taking first the members whose last call took longest, so that a few
        100000-particle steps do not all land on one thread."""
        if threads is None or threads <= 1 or len(tasks) < 2:
            for task in tasks:
                fn(*task)
            return
        if self._workers is None or self._workers.workers != threads:
            self.close()
            self._workers = WorkerThreads(threads)
        seconds = self._seconds

        def timed(task: tuple) -> None:
            start = time.perf_counter()
            fn(*task)
            seconds[task[0]] = time.perf_counter() - start

        tasks.sort(key=lambda task: -seconds[task[0]])
        self._workers.run_tasks(timed, tasks)

    def close(self) -> None:
        """Stop the worker threads (a later threaded call starts new ones)."""
        if self._workers is not None:
            self._workers.close()
            self._workers = None

    def _members(self, active: NDArray[np.bool_] | None) -> list[int]:
        """The indices of the members to step (``active``, or all)."""
        if active is None:
            return list(range(self.batch_size))
        return np.flatnonzero(active).tolist()

    def _first_bad_action(self, members: list[int]) -> int:
        """The first of ``members`` whose action is not finite, or -1."""
        finite = np.isfinite(self.actions[members]).all(axis=1)
        return -1 if finite.all() else members[int(np.argmin(finite))]

    def _controls(self, members: list[int]) -> NDArray[np.float64]:
        """``(B, 2)`` the commanded ``(V, omega)`` (m/s, rad/s) of ``members`` (0 elsewhere):
        the continuous actions decoded, or the discrete ones' primitives as they are."""
        out = np.zeros((self.batch_size, 2))
        limits = self.models.limits
        for b in members:
            action = self.actions[b]
            if limits.action_type == "continuous":
                out[b] = limits.decode(action)
            else:
                out[b] = action
        return out

    def _step_member(self, b: int, control: NDArray[np.float64],
                     rng: np.random.Generator) -> None:
        """One step of member ``b`` with its commanded ``(V, omega)``."""
        v, omega = float(control[0]), float(control[1])
        kidnapped_now, collided = self._advance_truth(b, v, omega, rng)
        # a blocked robot did not move: the filter predicts with V = 0
        self._filter_member(b, np.array([0.0 if collided else v, omega]), rng)
        self._finish(b, *self._member_summary(b), collided=collided,
                     kidnapped_now=kidnapped_now, first=False)

    def _advance_truth(
        self, b: int, v: float, omega: float, rng: np.random.Generator
    ) -> tuple[bool, bool]:
        """Member ``b``'s world for one step: the kidnapping (if now), the true robot's noisy
        motion and the people's; ``(kidnapped now, walls blocked the translation)``."""
        episode = self.episode(b)
        episode.t += 1
        kidnapped_now = episode.t == episode.kidnap_step
        if kidnapped_now:
            self.pose[b] = self._random_free_pose(b, rng)
            episode.kidnapped = True
        collided = self._move_truth(b, v, omega, rng)
        if episode.crowd is not None:
            assert isinstance(episode.map, OccupancyGrid)
            episode.crowd.step(episode.map, self.config.dt, self.pose[b, :2], rng)
        return kidnapped_now, collided

    def _filter_member(self, b: int, control: NDArray[np.float64],
                       rng: np.random.Generator) -> None:
        """Member ``b``'s MCL step: predict with its executed ``control`` ``(V, omega)``,
        take the scan from the true pose and correct."""
        belief = self.beliefs[b]
        assert belief is not None
        belief.predict(control, rng)
        episode = self.episode(b)
        lmap = episode.map
        if isinstance(lmap, OccupancyGrid):
            ranges = self._scan(b, rng)
            update_with_scan(belief, ranges,
                             functools.partial(self._scan_log_likelihood, b, ranges),
                             episode.data.dual, rng)
        else:
            sensor = self.models.sensor
            z, visible = sensor.measure(self.pose[b], lmap.positions, rng)
            n = lmap.n_landmarks
            self.z[b, :n] = z
            self.visible[b, :n] = visible
            belief.update_landmarks(
                z, visible, lmap.positions, sensor, rng,
                known_correspondence=self.config.known_correspondences,
            )

    def _scan(self, b: int, rng: np.random.Generator) -> NDArray[np.float64]:
        """Member ``b``'s lidar scan ``(M,)`` (m) from its true pose (people occlude), kept in
        :attr:`ranges`."""
        assert self.true_lidar is not None
        episode = self.episode(b)
        discs = episode.crowd.discs if episode.crowd is not None else None
        ranges = self.true_lidar.measure(self.pose[b], episode.data.grid_arrays, rng, discs)
        self.ranges[b] = ranges
        return ranges

    def _scan_log_likelihood(
        self, b: int, ranges: NDArray[np.float64], poses: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """The filter's lidar log-likelihood ``(K,)`` of a scan at poses ``(K, 3)`` in member
        ``b``'s map: the likelihood field from its per-cell table, the beam model from the
        range table, or the beam model ray-casting every pose."""
        assert self.lidar is not None
        data = self.episode(b).data
        if data.log_table is not None:
            return self.lidar.field_log_likelihood(
                ranges, poses, data.grid_arrays, data.log_table,
                beam_skip=self.config.lidar_beam_skip, distance_field=data.distance,
            )
        if data.range_table is not None:
            return data.range_table.log_likelihood(ranges, poses)
        return self.lidar.log_likelihood(ranges, poses, data.grid_arrays)

    def _move_truth(self, b: int, v: float, omega: float, rng: np.random.Generator) -> bool:
        """Move member ``b``'s true robot with noise; returns whether walls blocked the
        translation."""
        pose = self.pose[b]
        noise = self.models.motion.noise_root @ rng.standard_normal(3)
        episode = self.episode(b)
        lmap = episode.map
        if not isinstance(lmap, OccupancyGrid):
            box = self.rows[b]["bounds"]
            return bool(move_within_bounds(pose, v, omega, self.config.dt, noise, box,
                                           episode.walls))
        crowd = episode.crowd
        return move_on_grid(pose, v, omega, self.config.dt, noise, lmap,
                            crowd.blocks if crowd is not None else None)

    # -- metrics and observation ---------------------------------------------------------------

    def _reset_summary(self, b: int) -> BeliefSummary:
        """Member ``b``'s belief summary after its reset."""
        return self._member_summary(b)

    def _member_summary(self, b: int) -> BeliefSummary:
        """Member ``b``'s particle set summarized: mean ``(3,)``, covariance ``(3, 3)``,
        entropy (nats), log det and the ``(64,)`` mass histogram over its map."""
        belief = self.beliefs[b]
        assert belief is not None
        summary = belief.summary()
        # a particle set stands for a density at the resolution of the entropy bins, so its log
        # det adds a bin's own variance (d^2 / 12): finite even when every particle coincides
        sign, logdet = np.linalg.slogdet(summary.cov + self._bin_variance)
        hist = mass_histogram(belief.particles[:, :2], summary.weights, self.rows[b]["bounds"])
        return BeliefSummary(summary.mean, summary.cov, summary.entropy,
                             float(logdet) if sign > 0 else -np.inf, hist)

    def _finish(
        self, b: int, mean: NDArray, cov: NDArray, entropy: float, logdet: float,
        hist: NDArray, collided: bool, kidnapped_now: bool, first: bool,
    ) -> None:
        """Member ``b``'s metrics row and observation from its belief summary."""
        cfg = self.config
        episode = self.episode(b)
        # with a kidnapping ahead, or just behind, localizing now is not yet the end of the task
        unresolved = cfg.kidnap and (
            not episode.kidnapped or episode.t < episode.kidnap_step + cfg.kidnap_grace
        )
        n_visible = 0.0 if self.grid_mode else float(self.visible[b].sum())
        out = self.obs[b]
        finish_member(self.models.params, self.state[b], out, mean, cov, entropy, logdet, hist,
                      unresolved, first, collided, kidnapped_now, n_visible)
        start = BELIEF_HEADER + HISTOGRAM_CELLS * HISTOGRAM_CELLS
        if self.grid_mode:
            assert self.lidar is not None
            out[start:] = np.clip(self.ranges[b] / self.lidar.max_range, 0.0, 1.0)
        else:
            lmap = episode.map
            assert isinstance(lmap, LandmarkMap)
            write_landmark_slots(
                mean, self.z[b], self.visible[b], self.landmarks[b], lmap.n_landmarks,
                self.models.sensor.kind, self.models.scale, out[start:],
            )
        if self.image is not None:
            self._write_image(b)

    def _write_image(self, b: int) -> None:
        """Member ``b``'s belief channels of its image: the particles' weights binned."""
        belief = self.beliefs[b]
        assert belief is not None and self.image is not None
        particle_image(belief.particles, belief.summary().weights, self.rows[b]["bounds"],
                       self.image[b])


class BeliefSummary(NamedTuple):
    """What a step's metrics and observation read of a member's belief."""

    mean: NDArray[np.float64]  # (3,) m, m, rad
    cov: NDArray[np.float64]  # (3, 3)
    entropy: float  # nats
    logdet: float  # log det of the covariance (the bins' own spread included)
    hist: NDArray[np.float64]  # (64,) mass in each cell of the 8 x 8 grid over the map


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


@numba.njit(cache=True, nogil=True)
def finish_member(
    params: NDArray, state: NDArray, obs: NDArray, mean: NDArray, cov: NDArray,
    entropy: float, logdet: float, hist: NDArray, kidnap_unresolved: bool, first: bool,
    collided: bool, kidnapped_now: bool, n_visible: float,
) -> None:
    """A member's state row ``state`` and the start of its observation row ``obs`` from its
    belief summary: mean ``(3,)``, covariance ``(3, 3)``, entropy (nats), log det and mass
    histogram ``(64,)``. The metrics are :func:`~active_loc.envs.landmark_core.
    record_metrics`'s; a reset (``first``) has no reward or outcome yet."""
    for i in range(3):
        state[X_MEAN + i] = mean[i]
        for j in range(3):
            state[X_COV + 3 * i + j] = cov[i, j]
    record_metrics(params, state, entropy, logdet, kidnap_unresolved)
    stats = state[X_STATS : X_STATS + N_STATS]
    if first:
        stats[S_UNCERTAINTY_REWARD] = 0.0
        stats[S_OUTCOME] = 0.0
    stats[S_COLLIDED] = 1.0 if collided else 0.0
    stats[S_KIDNAPPED] = 1.0 if kidnapped_now else 0.0
    stats[S_N_VISIBLE] = n_visible
    write_belief_header(mean, cov, entropy, state[X_BOX : X_BOX + 4], obs)
    # where the belief's mass is, on a coarse grid over the map
    for i in range(hist.shape[0]):
        obs[BELIEF_HEADER + i] = min(max(hist[i], 0.0), 1.0)
