"""Configuration of the localization environments: one frozen dataclass for every env id.

Every field has a documented default and unit; ``gymnasium.make(id, **kwargs)`` passes kwargs
straight into it (over the scenario's preset), and a bad value raises ``ValueError`` naming the
field and the allowed range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from active_loc.beliefs.mcl import PROPOSALS
from active_loc.envs.field_checks import (
    check_bool_fields,
    check_choice,
    check_integer,
    check_memory,
    check_number,
    check_positive,
    check_std,
    check_stds,
    integers,
    is_finite_number,
    numbers,
)
from active_loc.maps import LandmarkMap, OccupancyGrid
from active_loc.maps.pool import MAX_MAP_POOL
from active_loc.sensors.detections import MAX_CLUTTER_RATE

BELIEFS = ("ekf", "mcl", "grid")
EKF_BACKENDS = ("numba", "filterpy")
SENSORS = ("range_bearing", "relative_position", "lidar")
LANDMARK_MAPS = ("random", "textbook")
GRID_MAPS = ("rooms", "symmetric_rooms", "marked_rooms", "pillars", "maze")
INITIAL_BELIEFS = ("gaussian", "uniform")
LIDAR_MODELS = ("likelihood_field", "beam")
RESAMPLING = ("systematic", "stratified")
ACTION_TYPES = ("continuous", "discrete")
OBSERVATIONS = ("belief", "image")
REWARDS = ("info_gain", "neg_entropy", "logdet", "trace")
STARTS = ("random", "fixed", "unseen")
_CHOICES = {
    "belief": BELIEFS, "ekf_backend": EKF_BACKENDS, "sensor": SENSORS,
    "action_type": ACTION_TYPES, "observation": OBSERVATIONS, "reward": REWARDS,
    "start": STARTS, "initial_belief": INITIAL_BELIEFS, "lidar_model": LIDAR_MODELS,
    "resampling": RESAMPLING, "proposal": PROPOSALS,
}

# bounds of the sizes (each also counts towards field_checks.MEMORY_BOUND_BYTES)
MAX_MAP_SIDE_M = 10_000.0  # map_size, each side (m)
MAX_LANDMARKS = 100_000  # max_landmarks
MAX_BEAMS = 10_000  # n_beams
MAX_GRID_HEADINGS = 3600  # grid_headings
MAX_PEOPLE = 1000  # dynamic_obstacles count
MIN_IMAGE_SIZE, MAX_IMAGE_SIZE = 4, 256  # image_size (cells per side)
MAX_IMAGE_HEADINGS = 36  # image_headings
MIN_GRID_CELL_M, MAX_GRID_CELL_M = 0.01, 100.0  # grid_cell_size (m)
GENERATOR_RESOLUTION_M = 0.1  # the map generators' cell side
# bytes per unit of the memory estimate: a particle (pose, weight, draws, resampling and
# mixture buffers), a map cell (values, distance field, likelihood table, free-space index),
# a grid belief pose (probability, scratch, cell pose)
PARTICLE_BYTES = 256
MAP_CELL_BYTES = 48
GRID_POSE_BYTES = 64


@dataclass(frozen=True)
class LocalizationConfig:
    """Everything that defines a localization task."""

    # --- map -----------------------------------------------------------------------------
    # landmark maps: "random" (a new seeded random landmark map every episode), "textbook"
    # (the four landmarks of the chapter's exercise), a LandmarkMap or an (N, 2) array;
    # grid maps (with sensor="lidar"): a generator name of GRID_MAPS (a new seeded map every
    # episode), an OccupancyGrid, or a path to a ROS map_server YAML file
    map: Any = "random"
    map_size: tuple[float, float] = (20.0, 20.0)  # random maps: width, height (m)
    n_landmarks: tuple[int, int] = (8, 15)  # random maps: inclusive range of the count
    max_landmarks: int = 15  # observation slots; maps may not have more landmarks than this
    # generated maps: None draws a new map every episode; N draws one of N seeded maps (the
    # same N for every env of this config), each built once with its derived tables and shared
    # by the sub-envs of a vector env (active_loc.maps.pool)
    map_pool: int | None = None

    # --- robot ---------------------------------------------------------------------------
    dt: float = 0.2  # time step (s)
    # square root of the diagonal of Q, the motion noise per step (m, m, rad)
    motion_noise_std: tuple[float, float, float] = (0.02, 0.02, 0.01)
    v_min: float = 0.0  # forward speed range (m/s)
    v_max: float = 1.0
    omega_max: float = 1.5  # turn rate range [-omega_max, omega_max] (rad/s)
    # "random": uniform in the map (1 m from the border), any heading; "unseen" (landmark maps,
    # EKF): the same, drawn again until no landmark is in view, so that the episode starts
    # unlocalized and the agent must look; "fixed": start_pose
    start: str = "random"
    start_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)  # used when start == "fixed"

    # --- sensor --------------------------------------------------------------------------
    sensor: str = "range_bearing"  # or "relative_position" (landmark in the robot frame)
    range_std: float = 0.1  # range_bearing: range noise std (m)
    bearing_std: float = 0.035  # range_bearing: bearing noise std (rad), about 2 degrees
    position_std: float = 0.5  # relative_position: noise std per axis (m); R = std^2 I
    fov: float = math.pi / 2  # field of view (rad), centred on the heading; 2*pi = all round
    max_range: float = 6.0  # maximum range (m); inf for unlimited
    known_correspondences: bool = True  # False: identical-looking landmarks (no ids)
    # identical-looking landmarks with belief="ekf" (active_loc.sensors.detections): the
    # probability that a landmark in view is not detected, in [0, 1); the mean number of false
    # detections per scan (Poisson, uniform over the field-of-view area), in [0, 50]; and the
    # probability of the chi-square validation gate of the data association, in (0, 1]
    # (None or 1: every measurement is matched to its most likely landmark)
    miss_probability: float = 0.0
    clutter_rate: float = 0.0
    association_gate: float | None = 0.99
    n_beams: int = 60  # lidar: beams evenly spread over the field of view
    lidar_model: str = "likelihood_field"  # the filter's lidar model, or "beam"
    lidar_noise_std: float = 0.03  # lidar: std of a hit reading of the simulated sensor (m)
    # lidar: std of a hit in the filter's model (m); wider than the sensor's noise, as AMCL's
    # default, to absorb map discretization and the beams' correlated errors
    lidar_sigma_hit: float = 0.2
    # lidar mixture weights (hit, short, max, random), summing to 1, for the simulated sensor
    # and the filter's model (the likelihood field uses hit and random only)
    lidar_mixture: tuple[float, float, float, float] = (0.9, 0.04, 0.03, 0.03)
    lidar_lambda_short: float = 0.1  # rate of the short-reading exponential (1/m)
    # beam model: directions of a range table precomputed once per map (RangeTable; ~30x
    # faster steps for 2-4 s per new 200 x 200 map); 0 ray-casts every beam at every step
    lidar_range_bins: int = 0
    unknown_reflects: bool = True  # whether unknown grid cells stop lidar beams
    # likelihood field: AMCL's beam skipping, its outlier rejection for unmapped obstacles:
    # (distance m, threshold, error threshold), AMCL's values (0.5, 0.3, 0.9); None is off
    lidar_beam_skip: tuple[float, float, float] | None = None
    # grid maps: people the map does not hold, (count, speed m/s, radius m) of discs walking
    # between random free points, occluding the lidar and blocking the robot; None for none
    dynamic_obstacles: tuple[int, float, float] | None = None

    # --- belief --------------------------------------------------------------------------
    belief: str = "ekf"
    # "filterpy" runs the reference implementation (single envs, known correspondences; with
    # identical-looking landmarks the EKF always runs the numba kernels of Algorithm 3)
    ekf_backend: str = "numba"
    initial_error_std: tuple[float, float, float] = (0.5, 0.5, 0.3)  # true - mean at reset
    initial_belief_std: tuple[float, float, float] = (0.5, 0.5, 0.3)  # sqrt diag Sigma_0
    # "gaussian": N(mean, Sigma_0) as above (pose tracking); "uniform": the whole free space,
    # any heading (global localization; MCL and grid only)
    initial_belief: str = "gaussian"
    n_particles: int = 1000  # MCL: particle count (the maximum with KLD sampling)
    resampling: str = "systematic"  # MCL: "systematic" (low variance) or "stratified"
    resample_threshold: float = 0.5  # MCL: resample when ESS < threshold * particles
    augmented: bool = False  # MCL: random-particle injection (augmented MCL, for kidnapping)
    # augmented MCL: smoothing rates of the long- and short-term likelihood averages (AMCL's
    # recovery_alpha_slow / _fast); injection rate = max(0, 1 - w_fast / (rho w_slow)), rho the
    # recovery_threshold in (0, 1] (1: augmented MCL's rate; lower: no injection on small dips)
    recovery_alpha_slow: float = 0.001
    recovery_alpha_fast: float = 0.1
    recovery_threshold: float = 1.0
    kld: bool = False  # MCL: KLD-sampling adaptive particle count
    min_particles: int = 100  # MCL with KLD: the minimum count (AMCL's default)
    # MCL and grid: the power each scan's likelihood is raised to (see MCLBelief); 1 = the
    # plain filter
    likelihood_exponent: float = 1.0
    # MCL: "motion" (plain MCL) or "mixture" (mixture MCL: a share mixture_share of every
    # update's particles drawn from the scan: its detections, or the lidar's scored lattice)
    proposal: str = "motion"
    mixture_share: float = 0.2
    # grid (Markov localization, Algorithm 1; grid maps only): the side of the belief's cells
    # (m), laid over the map from its origin, and the number of heading bins
    grid_cell_size: float = 0.25
    grid_headings: int = 36

    # --- agent interface -----------------------------------------------------------------
    action_type: str = "continuous"  # "continuous": Box(-1, 1, (2,)); "discrete": primitives
    # "belief": a vector (the belief's summary, an 8 x 8 histogram of its mass, the scan);
    # "image" (MCL and grid beliefs): a Dict of that vector and the belief as an image over the
    # map, image_headings heading channels and a map channel of image_size x image_size cells
    # (active_loc.envs.belief_image)
    observation: str = "belief"
    image_size: int = 32
    image_headings: int = 8
    reward: str = "info_gain"  # "info_gain", "neg_entropy", "logdet" or "trace"
    step_cost: float = 0.0  # subtracted every step (>= 0)
    collision_penalty: float = 1.0  # subtracted on a blocked move (>= 0)
    # added on the step the episode terminates (confident belief): + when the belief is right
    # (is_success), - when it is confidently wrong (>= 0; needs terminate_when_localized)
    outcome_reward: float = 0.0

    # --- termination and success ---------------------------------------------------------
    terminate_when_localized: bool = True
    localized_position_std: float = 0.15  # belief confident: largest position std below (m)
    localized_heading_std: float = 0.05  # ... and heading std below (rad)
    success_position_tol: float = 0.3  # success: confident and position error below (m)
    success_heading_tol: float = 0.15  # ... and heading error below (rad)

    # --- kidnapping ----------------------------------------------------------------------
    # once per episode, at a step drawn uniformly in kidnap_window x horizon, the robot is moved
    # to a random free pose without the filter being told
    kidnap: bool = False
    kidnap_window: tuple[float, float] = (0.2, 0.6)
    # steps after the kidnapping in which the episode neither ends nor succeeds: the filter's
    # time to react (a belief confident about the old pose is not yet a verdict)
    kidnap_grace: int = 10
    horizon: int = 200  # episode length the kidnap window refers to (the registered limit)

    def __post_init__(self) -> None:
        for name in ("belief", "ekf_backend", "sensor", "action_type", "observation", "reward",
                     "start", "initial_belief", "lidar_model", "resampling", "proposal"):
            check_choice(name, getattr(self, name), _CHOICES[name])
        check_bool_fields(self, tuple(f.name for f in fields(self) if f.type == "bool"))
        for f in fields(self):
            if f.type == "float":
                check_number(f.name, getattr(self, f.name))
        self._check_map()
        self._check_combinations()
        self._check_sensor()
        self._check_robot_and_filter()
        self._check_episode()
        self._check_start()
        check_memory(memory_parts(self, *self._known_map_cells()))

    def _check_map(self) -> None:
        if isinstance(self.map, str):
            if self.uses_grid:
                if self.map not in GRID_MAPS and not self.map.endswith((".yaml", ".yml")):
                    raise ValueError(
                        f"map={self.map!r}: with sensor='lidar' map must be one of {GRID_MAPS}, "
                        "an OccupancyGrid or a path to a ROS map YAML file"
                    )
            else:
                check_choice("map", self.map, LANDMARK_MAPS)
        elif self.uses_grid:
            if not isinstance(self.map, OccupancyGrid):
                raise ValueError(
                    f"with sensor='lidar' map must be a grid map name, an OccupancyGrid or a "
                    f"path to a ROS map YAML, got {type(self.map).__name__}"
                )
        elif not isinstance(self.map, LandmarkMap):
            try:
                positions = np.asarray(self.map, dtype=np.float64)
            except (TypeError, ValueError):
                raise ValueError(
                    "map must be 'random', 'textbook', a LandmarkMap or a non-empty (N, 2) "
                    f"array of landmark positions, got a {type(self.map).__name__} that is not "
                    "numeric"
                ) from None
            if positions.ndim != 2 or positions.shape[1] != 2 or positions.shape[0] == 0:
                raise ValueError(
                    "map must be 'random', 'textbook', a LandmarkMap or a non-empty (N, 2) "
                    f"array of landmark positions, got shape {positions.shape}"
                )
            if not np.isfinite(positions).all():
                raise ValueError("map landmark positions must be finite, got NaN or inf")
            if positions.shape[0] > MAX_LANDMARKS:
                raise ValueError(
                    f"map holds {positions.shape[0]} landmarks, more than {MAX_LANDMARKS}"
                )
        width, height = numbers("map_size (width m, height m)", self.map_size, 2)
        if min(width, height) <= 2.0 or max(width, height) > MAX_MAP_SIDE_M:
            raise ValueError(f"map_size must be (width, height) in (2, {MAX_MAP_SIDE_M:g}] m "
                             f"each, got {self.map_size}")
        check_integer("max_landmarks", self.max_landmarks, 1, MAX_LANDMARKS)
        low, high = integers("n_landmarks (low, high)", self.n_landmarks, 2)
        if not 1 <= low <= high <= self.max_landmarks:
            raise ValueError(
                f"n_landmarks must satisfy 1 <= low <= high <= max_landmarks="
                f"{self.max_landmarks}, got {self.n_landmarks}"
            )
        if self.map_pool is not None:
            check_integer("map_pool", self.map_pool, 1, MAX_MAP_POOL)
            if not self.generated_map:
                raise ValueError(
                    f"map_pool={self.map_pool} pools generated maps: it needs map='random' "
                    f"(landmarks) or a generator of {GRID_MAPS} (lidar), got map={self.map!r}"
                )
        x, y, _ = numbers("start_pose (x m, y m, theta rad)", self.start_pose, 3)
        if self.start == "fixed":
            self._check_start_pose(x, y)

    def _check_start_pose(self, x: float, y: float) -> None:
        """A fixed start must be a free pose of the map, where the map is known now: a given
        map, or a generated map's box. The cores check the rest (a map file, the textbook
        map, each generated grid) with :func:`check_start_pose` once they hold the map."""
        if isinstance(self.map, (OccupancyGrid, LandmarkMap)):
            check_start_pose(self.map, (x, y))
        elif self.generated_map:
            width, height = self.map_size
            if not (0.0 <= x <= width and 0.0 <= y <= height):
                raise ValueError(f"start_pose ({x}, {y}) is outside the map of map_size "
                                 f"{self.map_size} (m, from (0, 0))")

    def _check_combinations(self) -> None:
        if self.belief == "ekf" and (self.sensor == "lidar" or self.initial_belief == "uniform"):
            raise ValueError(
                "belief='ekf' tracks a Gaussian with landmark sensors; lidar and "
                "initial_belief='uniform' need belief='mcl' or 'grid'"
            )
        if self.belief == "grid" and not self.uses_grid:
            raise ValueError(
                f"belief='grid' runs on grid maps: it needs sensor='lidar', got "
                f"sensor={self.sensor!r}"
            )
        if self.proposal == "mixture" and self.belief != "mcl":
            raise ValueError(f"proposal='mixture' is mixture MCL: it needs belief='mcl', got "
                             f"belief={self.belief!r}")
        if self.observation == "image" and self.belief == "ekf":
            raise ValueError("observation='image' pictures a particle or grid belief: it needs "
                             "belief='mcl' or 'grid', got belief='ekf'")
        check_integer("image_size", self.image_size, MIN_IMAGE_SIZE, MAX_IMAGE_SIZE)
        check_integer("image_headings", self.image_headings, 1, MAX_IMAGE_HEADINGS)
        if self.kidnap and self.belief != "mcl":
            raise ValueError("kidnap=True needs belief='mcl' (the EKF cannot recover from it)")

    def _check_start(self) -> None:
        if self.start == "unseen" and (self.belief != "ekf" or self.uses_grid):
            raise ValueError("start='unseen' draws a start with no landmark in view: it needs "
                             f"belief='ekf' on a landmark map, got belief={self.belief!r}")

    def _check_sensor(self) -> None:
        if not (is_finite_number(self.miss_probability) and 0 <= self.miss_probability < 1):
            raise ValueError(f"miss_probability must be in [0, 1), got {self.miss_probability!r}")
        clutter = self.clutter_rate
        if not (is_finite_number(clutter) and 0 <= clutter <= MAX_CLUTTER_RATE):
            raise ValueError(
                f"clutter_rate must be in [0, {MAX_CLUTTER_RATE}] false detections per scan, "
                f"got {self.clutter_rate!r}"
            )
        if (self.miss_probability > 0 or self.clutter_rate > 0) and (
            self.belief != "ekf" or self.known_correspondences
        ):
            raise ValueError(
                f"miss_probability={self.miss_probability} and clutter_rate={self.clutter_rate}: "
                "misses and clutter need belief='ekf' with known_correspondences=False "
                "(identical-looking landmarks)"
            )
        if self.association_gate is not None and not (
            is_finite_number(self.association_gate) and 0 < self.association_gate <= 1
        ):
            raise ValueError(
                f"association_gate must be None or in (0, 1], got {self.association_gate!r}"
            )
        check_integer("n_beams", self.n_beams, 1, MAX_BEAMS)
        mixture = numbers("lidar_mixture (hit, short, max, random)", self.lidar_mixture, 4)
        if min(mixture) < 0 or abs(sum(mixture) - 1.0) > 1e-6:
            raise ValueError(
                f"lidar_mixture must be 4 weights (hit, short, max, random) >= 0 summing to 1, "
                f"got {self.lidar_mixture}"
            )
        for name in ("lidar_sigma_hit", "lidar_noise_std", "range_std", "bearing_std",
                     "position_std"):
            check_std(name, getattr(self, name))
        check_positive("lidar_lambda_short", self.lidar_lambda_short)
        check_integer("lidar_range_bins", self.lidar_range_bins, 0)
        if 0 < self.lidar_range_bins < 4:
            raise ValueError(f"lidar_range_bins must be 0 (off) or >= 4, got "
                             f"{self.lidar_range_bins}")
        if self.lidar_beam_skip is not None:
            skip = numbers("lidar_beam_skip (distance m, threshold, error threshold)",
                           self.lidar_beam_skip, 3)
            if not (skip[0] > 0 and 0 <= skip[1] <= 1 and 0 <= skip[2] <= 1):
                raise ValueError(
                    f"lidar_beam_skip must be None or (distance m > 0, threshold in [0, 1], "
                    f"error threshold in [0, 1]), got {self.lidar_beam_skip!r}"
                )
        if self.dynamic_obstacles is not None:
            people = self.dynamic_obstacles
            if not isinstance(people, (tuple, list)) or len(people) != 3:
                people = (None, None, None)
            count_ok = isinstance(people[0], (int, np.integer)) and not isinstance(
                people[0], bool) and 0 <= people[0] <= MAX_PEOPLE
            if not count_ok or not all(is_finite_number(v) for v in people[1:]) or not (
                people[1] >= 0 and people[2] > 0
            ):
                raise ValueError(
                    f"dynamic_obstacles must be None or (count in [0, {MAX_PEOPLE}], speed "
                    f"m/s >= 0, radius m > 0), got {self.dynamic_obstacles!r}"
                )
            if people[0] > 0 and not self.uses_grid:
                raise ValueError("dynamic_obstacles needs a grid map (sensor='lidar')")
        if not (0 < self.fov <= 2 * math.pi):
            raise ValueError(f"fov must be in (0, 2*pi] rad, got {self.fov}")
        if not self.max_range > 0:
            raise ValueError(f"max_range must be > 0 m (inf allowed), got {self.max_range}")

    def _check_robot_and_filter(self) -> None:
        check_positive("dt", self.dt)
        check_positive("v_max", self.v_max, allow_zero=True)
        if not (math.isfinite(self.v_min) and self.v_min <= self.v_max):
            raise ValueError(f"v_min must be finite and <= v_max={self.v_max}, got {self.v_min}")
        check_positive("omega_max", self.omega_max, allow_zero=True)
        check_stds("motion_noise_std", self.motion_noise_std, allow_zero=True)
        check_stds("initial_error_std", self.initial_error_std, allow_zero=True)
        check_stds("initial_belief_std", self.initial_belief_std, allow_zero=False)
        check_integer("n_particles", self.n_particles, 1)
        check_integer("min_particles", self.min_particles, 1)
        if self.kld and self.min_particles > self.n_particles:
            raise ValueError(
                f"min_particles={self.min_particles} must be <= n_particles={self.n_particles}"
            )
        if not 0 < self.recovery_alpha_slow < self.recovery_alpha_fast <= 1:
            raise ValueError(
                "recovery rates must satisfy 0 < recovery_alpha_slow < recovery_alpha_fast <= 1, "
                f"got {self.recovery_alpha_slow}, {self.recovery_alpha_fast}"
            )
        if not 0 < self.recovery_threshold <= 1:
            raise ValueError(f"recovery_threshold must be in (0, 1], got {self.recovery_threshold}")
        if not 0 < self.likelihood_exponent <= 1:
            raise ValueError(
                f"likelihood_exponent must be in (0, 1], got {self.likelihood_exponent}"
            )
        if not 0 < self.resample_threshold <= 1:
            raise ValueError(
                f"resample_threshold must be in (0, 1], got {self.resample_threshold}"
            )
        if not 0.0 < self.mixture_share < 1.0:
            raise ValueError(f"mixture_share must be in (0, 1), got {self.mixture_share}")
        check_positive("grid_cell_size", self.grid_cell_size)
        if not MIN_GRID_CELL_M <= self.grid_cell_size <= MAX_GRID_CELL_M:
            raise ValueError(f"grid_cell_size must be in [{MIN_GRID_CELL_M}, {MAX_GRID_CELL_M}] "
                             f"m, got {self.grid_cell_size}")
        check_integer("grid_headings", self.grid_headings, 1, MAX_GRID_HEADINGS)

    def _check_episode(self) -> None:
        for name in ("step_cost", "collision_penalty", "outcome_reward"):
            check_positive(name, getattr(self, name), allow_zero=True)
        if self.outcome_reward > 0 and not self.terminate_when_localized:
            raise ValueError(
                "outcome_reward is paid on the step the belief becomes confident and ends the "
                "episode: it needs terminate_when_localized=True"
            )
        for name in (
            "localized_position_std",
            "localized_heading_std",
            "success_position_tol",
            "success_heading_tol",
        ):
            check_positive(name, getattr(self, name))
        check_integer("horizon", self.horizon, 1)
        lo, hi = numbers("kidnap_window (low, high)", self.kidnap_window, 2)
        if not 0 <= lo <= hi <= 1:
            raise ValueError(
                f"kidnap_window must satisfy 0 <= lo <= hi <= 1, got {self.kidnap_window}"
            )
        check_integer("kidnap_grace", self.kidnap_grace, 0)

    def _known_map_cells(self) -> tuple[int, float]:
        """The grid map's cell count and resolution (m) where the config knows them (a
        generated map at the generators' resolution, or a given grid); ``(0, 0.1)`` for a
        landmark map or a map file, whose size is checked when it is read."""
        if isinstance(self.map, OccupancyGrid):
            return int(self.map.values.size), float(self.map.resolution)
        if self.uses_grid and self.generated_map:
            width, height = self.map_size
            return math.ceil(width / GENERATOR_RESOLUTION_M) * math.ceil(
                height / GENERATOR_RESOLUTION_M), GENERATOR_RESOLUTION_M
        return 0, GENERATOR_RESOLUTION_M

    @property
    def generated_map(self) -> bool:
        """Whether every episode generates its map (a generator name, or random landmarks)."""
        if not isinstance(self.map, str):
            return False
        return self.map in GRID_MAPS if self.uses_grid else self.map == "random"

    @property
    def uses_grid(self) -> bool:
        """Whether the task is on an occupancy grid (lidar) rather than a landmark map."""
        return self.sensor == "lidar"

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))


def check_start_pose(lmap: LandmarkMap | OccupancyGrid, position: tuple[float, float]) -> None:
    """A fixed start ``(x, y)`` (m) must lie inside ``lmap``, and on a grid in a free cell."""
    x, y = position
    x_min, y_min, x_max, y_max = lmap.bounds
    if not (x_min <= x <= x_max and y_min <= y <= y_max):
        where = "outside the map"
    elif isinstance(lmap, OccupancyGrid) and not bool(lmap.is_free(np.array([[x, y]]))[0]):
        where = "in an occupied or unknown cell of the map"
    else:
        return
    raise ValueError(f"start_pose ({x}, {y}) is {where}; the map spans x in [{x_min}, {x_max}], "
                     f"y in [{y_min}, {y_max}] m")


def memory_parts(cfg: LocalizationConfig, map_cells: int, resolution: float) -> dict[str, float]:
    """The largest arrays an env of ``cfg`` allocates (what -> bytes), for a grid map of
    ``map_cells`` cells of ``resolution`` m (0 cells for a landmark map)."""
    k = cfg.n_particles if cfg.belief == "mcl" else 1
    parts = {
        "n_particles": k * PARTICLE_BYTES,
        "n_beams": cfg.n_beams * 8.0 * (k if cfg.uses_grid else 1),
        "max_landmarks": cfg.max_landmarks * 8.0 * (k + 16),
        "the grid map": map_cells * (MAP_CELL_BYTES + 2 * cfg.lidar_range_bins),
    }
    if cfg.belief == "grid" and map_cells:
        belief_cells = map_cells * (resolution / cfg.grid_cell_size) ** 2
        parts["grid_cell_size and grid_headings"] = (
            belief_cells * cfg.grid_headings * GRID_POSE_BYTES)
    return parts
