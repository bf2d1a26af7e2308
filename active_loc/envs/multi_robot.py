"""Multi-robot cooperative localization as a PettingZoo ``ParallelEnv``.

``n_robots`` unicycle robots share one known landmark map. Each localizes itself with its own
filter (EKF, the chapter's Algorithm 2, or MCL, Algorithm 4) fed by its own landmark sensor,
and each detects the others that come into its field of view: range and bearing of the other
robot, whose identity it knows. A robot that detects another fuses that detection into its own
belief together with the other robot's belief, without counting shared information twice:
covariance intersection for the EKF; for MCL, reciprocal sampling, a waiting time per pair and,
by default, only from a robot that is localized (:mod:`active_loc.envs.multi_robot_fusion`
derives both and says why).

## Agents, actions, observations

Agents ``"robot_0"`` ... ``"robot_{n-1}"``. Each has the single env's action space
(``action_type="continuous"``: ``Box(-1, 1, (2,), float32)`` mapped to speed and turn rate;
``"discrete"``: ``Discrete(6)`` motion primitives) and a flat ``Box(-1, 1, (D,), float32)``
observation built from its own belief and sensors, never from the true pose:

| part                    | size               | content                                         |
|-------------------------|--------------------|-------------------------------------------------|
| belief header           | 11                 | as :mod:`active_loc.envs.observations`          |
| particle histogram      | 64 (MCL only)      | the belief's mass on an 8 x 8 grid over the map |
| landmark slots          | 6 max_landmarks    | as :mod:`active_loc.envs.observations` (1)      |
| robot slots             | 4 (n_robots - 1)   | per other robot k = i+1, i+2, ... (mod n): seen |
|                         |                    | this step, range / scale, bearing / pi, fused   |

(1) With identical-looking landmarks (``known_correspondences=False``) the measurements fill
the slots in order of range: a slot's measurement is not that slot's landmark.

## Rewards, episode end, info

Reward of a robot: its information gain ``H(b_{t-1}) - H(b_t)`` (nats, its own belief, fusion
included) ``- step_cost - collision_penalty`` on a blocked move; with ``team_reward=True`` every
robot gets the sum over the robots that acted this step. A robot terminates when its belief is
confident (largest position std <= ``localized_position_std`` and heading std <=
``localized_heading_std``); it then stops where it is, stays visible to the others, and its
belief stays as it was (a static, well-localized anchor). With
``terminate_when_localized=False`` no robot terminates: a confident robot acts and filters on
(the fixed set of agents SuperSuit's vector wrappers need). Every robot is truncated after
``max_cycles`` steps. Info per robot: ``pose_error`` (m), ``heading_error`` (rad), ``entropy``
(nats), ``localized``, ``is_success`` (localized and within ``success_position_tol`` /
``success_heading_tol`` of the truth), ``collisions`` (this episode), ``fused`` (a detection was
fused into its belief this step), ``detected`` (the robots it saw this step), ``n_visible``
(landmarks seen) and ``reward_terms``. Errors use the truth: they are for evaluation only.

## Randomness

``reset(seed=...)`` seeds the env's Generator ``np_random``; from it, at every reset, come
the Generators of the world (map, starts, motion and sensor noise), of each robot's filter and
of the fusion. Separate streams make runs with and without fusion see the same world noise, so
that they can be compared episode by episode.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any

import gymnasium
import numpy as np
from gymnasium.utils import seeding
from numpy.typing import NDArray
from pettingzoo import AECEnv, ParallelEnv
from pettingzoo.utils.conversions import parallel_to_aec

from active_loc.beliefs.ekf import EKFBelief
from active_loc.beliefs.entropy import gaussian_entropy
from active_loc.beliefs.mcl import FreeSpace, MCLBelief
from active_loc.envs.actions import ControlLimits, action_space, check_action
from active_loc.envs.config import MAX_LANDMARKS, MAX_MAP_SIDE_M, PARTICLE_BYTES
from active_loc.envs.field_checks import (
    check_bool,
    check_bool_fields,
    check_choice,
    check_integer,
    check_memory,
    check_positive,
    check_std,
    check_stds,
    integers,
    numbers,
)
from active_loc.envs.metrics import belief_metrics
from active_loc.envs.multi_robot_fusion import (
    MultiRobotRenderer,
    detect_robots,
    fuse_ekf,
    fuse_mcl,
    symmetric_landmark_map,
)
from active_loc.envs.observations import (
    BELIEF_HEADER,
    SLOT_SIZE,
    write_belief_header,
    write_landmark_slots,
)
from active_loc.envs.outcome import RewardSettings, StepOutcome, step_info
from active_loc.envs.particle_core import HISTOGRAM_CELLS, mass_histogram
from active_loc.envs.rewards import step_reward
from active_loc.geometry import wrap_angle
from active_loc.maps import LandmarkMap, random_landmark_map
from active_loc.motion import UnicycleModel, move_within_bounds
from active_loc.sensors.landmarks import RANGE_BEARING, RangeBearingSensor

MAPS = ("random", "symmetric")
INITIAL_BELIEFS = ("gaussian", "wide", "uniform")
#: ``initial_belief="wide"``: std of the start error and of the initial belief (m, m, rad)
WIDE_STD = (2.0, 2.0, 0.6)
ROBOT_SLOT = 4
MAX_ROBOTS = 1000  # n_robots


@dataclass(frozen=True)
class MultiRobotConfig:
    """The multi-robot task; defaults follow :class:`~active_loc.envs.config.LocalizationConfig`.

    A bad value raises ``ValueError`` naming the field.
    """

    n_robots: int = 2  # robots, >= 1
    belief: str = "ekf"  # "ekf" (Algorithm 2) or "mcl" (Algorithm 4)
    # "random": a random landmark map per episode; "symmetric": the 180-degree symmetric arena
    # with one cue landmark (multi_robot_fusion.symmetric_landmark_map); a LandmarkMap; or an
    # (N, 2) array of landmark positions (box 2 m around them, walled)
    map: Any = "random"
    map_size: tuple[float, float] = (20.0, 20.0)  # generated maps: width, height (m)
    n_landmarks: tuple[int, int] = (8, 15)  # generated maps: inclusive range of the count
    max_landmarks: int = 15  # observation slots; maps may not have more landmarks
    # landmark identities known (Algorithm 2); False: identical-looking landmarks, MCL only
    # (each particle matches each measurement to its most likely landmark). None: True,
    # except on the symmetric arena
    known_correspondences: bool | None = None
    # --- robots: as the single env -------------------------------------------------------
    dt: float = 0.2  # time step (s)
    motion_noise_std: tuple[float, float, float] = (0.02, 0.02, 0.01)  # sqrt diag Q (m, m, rad)
    v_min: float = 0.0  # forward speed range (m/s)
    v_max: float = 1.0
    omega_max: float = 1.5  # turn rate range (rad/s)
    range_std: float = 0.1  # landmark range noise std (m)
    bearing_std: float = 0.035  # landmark bearing noise std (rad)
    fov: float = math.pi / 2  # landmark sensor field of view (rad)
    max_range: float = 6.0  # landmark sensor range (m); inf allowed
    # --- robot-robot detections ----------------------------------------------------------
    detection_range_std: float = 0.1  # range noise std (m)
    detection_bearing_std: float = 0.035  # bearing noise std (rad)
    detection_fov: float | None = None  # field of view (rad); None: the landmark sensor's
    detection_max_range: float | None = None  # range (m); None: the landmark sensor's
    # --- beliefs -------------------------------------------------------------------------
    # "gaussian": N(true start + N(0, initial_error_std^2), diag(initial_belief_std^2));
    # "wide": the same with WIDE_STD for both; "uniform": the whole map (MCL only). One name
    # for every robot, or a tuple with one per robot
    initial_belief: str | tuple[str, ...] = "gaussian"
    initial_error_std: tuple[float, float, float] = (0.5, 0.5, 0.3)
    initial_belief_std: tuple[float, float, float] = (0.5, 0.5, 0.3)
    n_particles: int = 2000  # MCL: particles per robot
    resample_threshold: float = 0.5  # MCL: resample when ESS < threshold * particles
    likelihood_exponent: float = 1.0  # MCL: landmark likelihood tempering, in (0, 1]
    # --- fusion --------------------------------------------------------------------------
    fuse_detections: bool = True  # False: robots localize alone (detections still observed)
    ci_criterion: str = "det"  # EKF: omega minimizes "det" or "trace" of the fused covariance
    fusion_interval: int = 10  # MCL: steps a pair of robots waits before fusing again
    # MCL: robot i fuses robot j's belief only when j is localized (confident, see below);
    # False: whenever i detects j (Fox et al.'s rule, the interval alone)
    fusion_sender_localized: bool = True
    fusion_samples: int = 2000  # MCL: samples of the reciprocal density
    fusion_bandwidth: tuple[float, float, float] = (0.25, 0.25, 0.15)  # MCL: KDE (m, m, rad)
    # --- agent interface and episode -----------------------------------------------------
    action_type: str = "continuous"  # "continuous" or "discrete"
    step_cost: float = 0.0  # subtracted every step (>= 0)
    collision_penalty: float = 1.0  # subtracted on a blocked move (>= 0)
    team_reward: bool = False  # every robot gets the team's summed reward
    # False: a confident robot stays in the episode, acting and filtering, until max_cycles
    # truncates every robot at once (the fixed agent set of SuperSuit's vector wrappers)
    terminate_when_localized: bool = True
    localized_position_std: float = 0.15  # confident: largest position std below (m)
    localized_heading_std: float = 0.05  # ... and heading std below (rad)
    success_position_tol: float = 0.3  # success: confident and position error below (m)
    success_heading_tol: float = 0.15  # ... and heading error below (rad)
    max_cycles: int = 200  # truncation (steps)
    initial_beliefs: tuple[str, ...] = field(init=False)  # one per robot (derived)

    def __post_init__(self) -> None:
        check_integer("n_robots", self.n_robots, 1, MAX_ROBOTS)
        check_choice("belief", self.belief, ("ekf", "mcl"))
        check_choice("action_type", self.action_type, ("continuous", "discrete"))
        check_choice("ci_criterion", self.ci_criterion, ("det", "trace"))
        if isinstance(self.map, str):
            check_choice("map", self.map, MAPS)
        elif not isinstance(self.map, LandmarkMap):
            positions = np.asarray(self.map, dtype=np.float64)
            if positions.ndim != 2 or positions.shape[1] != 2 or positions.shape[0] == 0:
                raise ValueError(f"map must be one of {MAPS}, a LandmarkMap or a non-empty (N, 2) "
                                 f"array of landmark positions, got shape {positions.shape}")
        kinds = self.initial_belief
        kinds = (kinds,) * self.n_robots if isinstance(kinds, str) else tuple(kinds)
        if len(kinds) != self.n_robots:
            raise ValueError(f"initial_belief must be one name or {self.n_robots} (one per "
                             f"robot), got {self.initial_belief!r}")
        for kind in kinds:
            check_choice("initial_belief", kind, INITIAL_BELIEFS)
        object.__setattr__(self, "initial_beliefs", kinds)
        check_bool_fields(self, ("fuse_detections", "fusion_sender_localized", "team_reward",
                                 "terminate_when_localized"))
        known = self.known_correspondences
        if known is not None:
            check_bool("known_correspondences", known)
        if known is None:
            known = not (isinstance(self.map, str) and self.map == "symmetric")
            object.__setattr__(self, "known_correspondences", known)
        if self.belief == "ekf" and (not known or "uniform" in kinds):
            raise ValueError("belief='ekf' tracks a Gaussian with known correspondences: "
                             "known_correspondences=False and initial_belief='uniform' need "
                             "belief='mcl'")
        for name in ("range_std", "bearing_std", "detection_range_std", "detection_bearing_std"):
            check_std(name, getattr(self, name))
        for name in ("dt", "step_cost", "collision_penalty",
                     "localized_position_std", "localized_heading_std", "success_position_tol",
                     "success_heading_tol", "v_max", "omega_max"):
            zero_ok = name in ("step_cost", "collision_penalty", "v_max", "omega_max")
            check_positive(name, getattr(self, name), allow_zero=zero_ok)
        if not (math.isfinite(self.v_min) and self.v_min <= self.v_max):
            raise ValueError(f"v_min must be finite and <= v_max={self.v_max}, got {self.v_min}")
        check_stds("motion_noise_std", self.motion_noise_std, allow_zero=True)
        check_stds("initial_error_std", self.initial_error_std, allow_zero=True)
        check_stds("initial_belief_std", self.initial_belief_std, allow_zero=False)
        check_stds("fusion_bandwidth", self.fusion_bandwidth, allow_zero=False)
        for name in ("fov", "detection_fov"):
            value = getattr(self, name)
            ok = isinstance(value, (int, float)) and 0 < value <= 2 * math.pi
            if value is not None and not ok:
                raise ValueError(f"{name} must be in (0, 2*pi] rad, got {value!r}")
        for name in ("max_range", "detection_max_range"):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, (int, float)) and value > 0):
                raise ValueError(f"{name} must be > 0 m (inf allowed), got {value!r}")
        check_integer("max_landmarks", self.max_landmarks, 1, MAX_LANDMARKS)
        low, high = integers("n_landmarks (low, high)", self.n_landmarks, 2)
        if not 1 <= low <= high <= self.max_landmarks:
            raise ValueError(f"n_landmarks must satisfy 1 <= low <= high <= max_landmarks="
                             f"{self.max_landmarks}, got {self.n_landmarks}")
        if min(numbers("map_size (width m, height m)", self.map_size, 2)) <= 2.0 or max(
                self.map_size) > MAX_MAP_SIDE_M:
            raise ValueError(f"map_size must be (width, height) in (2, {MAX_MAP_SIDE_M:g}] m "
                             f"each, got {self.map_size}")
        for name in ("n_particles", "fusion_interval", "fusion_samples", "max_cycles"):
            check_integer(name, getattr(self, name), 1)
        k = self.n_particles if self.belief == "mcl" else 1
        check_memory({"n_robots x n_particles": self.n_robots * k * PARTICLE_BYTES,
                      "fusion_samples": self.n_robots * self.fusion_samples * PARTICLE_BYTES,
                      "max_landmarks": self.n_robots * self.max_landmarks * 8.0 * (k + 16)})
        if not 0 < self.resample_threshold <= 1:
            raise ValueError(f"resample_threshold must be in (0, 1], got "
                             f"{self.resample_threshold}")
        if not 0 < self.likelihood_exponent <= 1:
            raise ValueError(f"likelihood_exponent must be in (0, 1], got "
                             f"{self.likelihood_exponent}")

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls) if f.init)


class MultiRobotLocalizationEnv(ParallelEnv):
    """Cooperative localization of ``n_robots`` robots in a shared landmark map (see the module
    docstring for spaces, rewards and info).

    Args:
        n_robots: number of robots (>= 1).
        render_mode: None, ``"rgb_array"`` or ``"human"``.
        **kwargs: fields of :class:`MultiRobotConfig`.
    """

    metadata: dict[str, Any] = {  # noqa: RUF012
        "render_modes": ["human", "rgb_array"],
        "name": "multi_robot_localization_v0",
        "render_fps": 10,
        "is_parallelizable": True,
    }

    def __init__(self, n_robots: int = 2, render_mode: str | None = None, **kwargs: Any) -> None:
        unknown = set(kwargs) - set(MultiRobotConfig.field_names())
        if unknown:
            raise TypeError(f"unknown env kwargs {sorted(unknown)}; valid ones are the fields of "
                            "MultiRobotConfig")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode={render_mode!r} is not one of "
                             f"{self.metadata['render_modes']}")
        self.config = cfg = MultiRobotConfig(n_robots=n_robots, **kwargs)
        self.render_mode = render_mode
        self.n = n = cfg.n_robots
        self.possible_agents = [f"robot_{i}" for i in range(n)]
        self.agents: list[str] = []
        self.max_cycles = cfg.max_cycles  # pettingzoo's tests set it
        self.motion = UnicycleModel(cfg.dt, np.diag(np.square(cfg.motion_noise_std)))
        self.sensor = RangeBearingSensor.from_std(cfg.range_std, cfg.bearing_std, cfg.fov,
                                                  cfg.max_range)
        self.limits = ControlLimits(cfg.action_type, cfg.dt, cfg.v_min, cfg.v_max, cfg.omega_max)
        self._det_fov = float(cfg.fov if cfg.detection_fov is None else cfg.detection_fov)
        self._det_range = float(cfg.max_range if cfg.detection_max_range is None
                                else cfg.detection_max_range)
        self._det_std = np.array([cfg.detection_range_std, cfg.detection_bearing_std])
        self._det_cov = np.diag(np.square(self._det_std))
        self.fixed_map = _fixed_map(cfg.map)
        if self.fixed_map is not None and self.fixed_map.n_landmarks > cfg.max_landmarks:
            raise ValueError(f"the map has {self.fixed_map.n_landmarks} landmarks but "
                             f"max_landmarks={cfg.max_landmarks}; raise max_landmarks")
        size = BELIEF_HEADER + SLOT_SIZE * cfg.max_landmarks + ROBOT_SLOT * (n - 1)
        if cfg.belief == "mcl":
            size += HISTOGRAM_CELLS * HISTOGRAM_CELLS
        self._obs_size = size
        self._obs_spaces = {a: gymnasium.spaces.Box(-1.0, 1.0, (size,), dtype=np.float32)
                            for a in self.possible_agents}
        self._act_spaces = {a: action_space(cfg.action_type) for a in self.possible_agents}
        # information gain per robot; the team reward sums the acting robots' (no outcome term)
        self._reward = RewardSettings("info_gain", float(cfg.step_cost),
                                      float(cfg.collision_penalty), has_outcome=False)
        self.np_random, self.np_random_seed = seeding.np_random(None)
        self._renderer: Any = None
        self._has_reset = False

    # -- spaces ---------------------------------------------------------------------------------

    def observation_space(self, agent: str) -> gymnasium.spaces.Box:
        return self._obs_spaces[agent]

    def action_space(self, agent: str) -> gymnasium.spaces.Space:
        return self._act_spaces[agent]

    # -- reset ----------------------------------------------------------------------------------

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, NDArray[np.float32]], dict[str, dict[str, Any]]]:
        if seed is not None:
            self.np_random, self.np_random_seed = seeding.np_random(seed)
        cfg, n = self.config, self.n
        seeds = self.np_random.integers(0, 2**63, size=n + 2)
        self._world_rng = np.random.default_rng(seeds[0])
        self._fusion_rng = np.random.default_rng(seeds[1])
        self._robot_rngs = [np.random.default_rng(s) for s in seeds[2:]]
        world = self._world_rng
        self.map = self.fixed_map if self.fixed_map is not None else self._draw_map(world)
        if self.map.n_landmarks > cfg.max_landmarks:
            raise ValueError(f"the map has {self.map.n_landmarks} landmarks but max_landmarks="
                             f"{cfg.max_landmarks}; raise max_landmarks")
        x0, y0, x1, y1 = self.map.bounds
        self._bounds = np.array(self.map.bounds)
        self._landmarks = np.zeros((cfg.max_landmarks, 2))
        self._landmarks[: self.map.n_landmarks] = self.map.positions
        margin = min(1.0, 0.25 * (x1 - x0), 0.25 * (y1 - y0))
        u = world.random((n, 3))
        self.poses = np.column_stack([x0 + margin + u[:, 0] * (x1 - x0 - 2 * margin),
                                      y0 + margin + u[:, 1] * (y1 - y0 - 2 * margin),
                                      -np.pi + 2 * np.pi * u[:, 2]])
        self._init_beliefs(world.standard_normal((n, 3)))
        self._z = np.zeros((n, cfg.max_landmarks, 2))
        self._visible = np.zeros((n, cfg.max_landmarks), dtype=np.bool_)
        self._det_z = np.zeros((n, n, 2))
        self._det_seen = np.zeros((n, n), dtype=np.bool_)
        self._fused_pairs = np.zeros((n, n), dtype=np.bool_)
        self._last_fusion = np.full((n, n), -(10**9), dtype=np.int64)
        self._collisions = np.zeros(n, dtype=np.int64)
        self._live = np.ones(n, dtype=np.bool_)
        self.steps = 0
        self.agents = list(self.possible_agents)
        self._has_reset = True
        self._summarize()
        self._paths = [[p[:2].copy()] for p in self.poses]
        obs = {a: self._observe(i) for i, a in enumerate(self.agents)}
        zero = np.zeros(n, dtype=np.bool_)
        infos = {a: self._info(i, zero, 0.0) for i, a in enumerate(self.agents)}
        if self.render_mode == "human":
            self.render()
        return obs, infos

    def _draw_map(self, rng: np.random.Generator) -> LandmarkMap:
        cfg = self.config
        if cfg.map == "symmetric":
            return symmetric_landmark_map(rng, cfg.map_size, cfg.n_landmarks)
        return random_landmark_map(rng, cfg.map_size, cfg.n_landmarks)

    def _init_beliefs(self, normals: NDArray[np.float64]) -> None:
        """Each robot's initial belief from the true starts and ``normals`` ``(n, 3)``."""
        cfg, n = self.config, self.n
        means = np.empty((n, 3))
        covs = np.empty((n, 3, 3))
        for i, kind in enumerate(cfg.initial_beliefs):
            err, std = ((WIDE_STD, WIDE_STD) if kind == "wide"
                        else (cfg.initial_error_std, cfg.initial_belief_std))
            means[i] = self.poses[i] + np.asarray(err) * normals[i]
            means[i, 2] = wrap_angle(means[i, 2])
            covs[i] = np.diag(np.square(std))
        if cfg.belief == "ekf":
            self.ekf = EKFBelief(means, covs, self.motion, self.sensor)
            return
        self._free = FreeSpace.from_box(*self.map.bounds)
        self.particle_beliefs = []
        for i, kind in enumerate(cfg.initial_beliefs):
            belief = MCLBelief(self._free, self.motion, cfg.n_particles,
                               resample_threshold=cfg.resample_threshold,
                               likelihood_exponent=cfg.likelihood_exponent)
            if kind == "uniform":
                belief.initialize_uniform(self._robot_rngs[i])
            else:
                belief.initialize_gaussian(means[i], covs[i], self._robot_rngs[i])
            self.particle_beliefs.append(belief)

    # -- step -----------------------------------------------------------------------------------

    def step(self, actions: dict[str, Any]) -> tuple[
        dict[str, NDArray[np.float32]], dict[str, float], dict[str, bool], dict[str, bool],
        dict[str, dict[str, Any]],
    ]:
        if not self._has_reset:
            raise RuntimeError("call reset() before step()")
        controls = self._decode_actions(actions)
        cfg, n, world = self.config, self.n, self._world_rng
        acting = self._live.copy()
        # the world: every draw is made whether or not a robot still acts (aligned streams)
        noise = world.standard_normal((n, 3)) @ self.motion.noise_root.T
        collided = np.zeros(n, dtype=np.bool_)
        for i in np.flatnonzero(acting):
            collided[i] = move_within_bounds(self.poses[i], controls[i, 0], controls[i, 1],
                                             cfg.dt, noise[i], self._bounds, self.map.walls)
        z, visible = self.sensor.measure(self.poses, self.map.positions, world)
        detect_robots(self.poses, acting, self._det_fov, self._det_range, self._det_std,
                      world.standard_normal((n, n, 2)), self._det_z, self._det_seen)
        self.steps += 1
        self._collisions += collided
        # the filters: a blocked robot knows it did not advance (bumper)
        executed = np.where(collided[:, None], np.column_stack([np.zeros(n), controls[:, 1]]),
                            controls)
        visible &= acting[:, None]
        self._store_scans(z, visible)
        self._filter_step(executed, z, visible, acting)
        self._fused_pairs[:] = False
        if cfg.fuse_detections:
            self._fuse(acting)
        entropy_before = self._entropy.copy()
        self._summarize()
        gains = entropy_before - self._entropy
        reward = self._reward
        rewards = np.array([
            step_reward(float(g), bool(c), reward.step_cost, reward.collision_penalty, 0.0)
            for g, c in zip(gains, collided, strict=True)
        ])
        if cfg.team_reward:
            rewards = np.where(acting, rewards[acting].sum(), rewards)
        agents = [self.possible_agents[i] for i in np.flatnonzero(acting)]
        obs, rew, term, trunc, infos = {}, {}, {}, {}, {}
        for a in agents:
            i = int(a.rsplit("_", 1)[1])
            obs[a] = self._observe(i)
            rew[a] = float(rewards[i])
            term[a] = bool(self._localized[i]) and cfg.terminate_when_localized
            trunc[a] = self.steps >= self.max_cycles
            infos[a] = self._info(i, collided, float(gains[i]))
            self._paths[i].append(self.poses[i, :2].copy())
            if term[a] or trunc[a]:
                self._live[i] = False
        self.agents = [a for a in agents if not (term[a] or trunc[a])]
        if self.render_mode == "human":
            self.render()
        return obs, rew, term, trunc, infos

    def _decode_actions(self, actions: Any) -> NDArray[np.float64]:
        """Validate the actions of the live agents; physical controls ``(n, 2)`` (zero for the
        robots that no longer act). Nothing changes when this raises."""
        if not isinstance(actions, dict):
            raise ValueError(f"actions must be a dict agent -> action, got "
                             f"{type(actions).__name__}")
        unknown = sorted(set(actions) - set(self.possible_agents))
        if unknown:
            raise ValueError(f"actions: unknown agents {unknown}; agents are "
                             f"{self.possible_agents}")
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise ValueError(f"actions: no action for the live agents {missing}")
        controls = np.zeros((self.n, 2))
        for a in self.agents:
            i = int(a.rsplit("_", 1)[1])
            action = check_action(actions[a], self._act_spaces[a], f"actions[{a!r}]")
            controls[i] = self.limits.decode(action)
        return controls

    def _store_scans(self, z: NDArray, visible: NDArray) -> None:
        """Keep this step's scans for the observations: by landmark, or, with identical-looking
        landmarks, in order of range (the slot tells nothing of the landmark's identity)."""
        count = self.map.n_landmarks
        self._z[:] = 0.0
        self._visible[:] = False
        if self.config.known_correspondences:
            self._z[:, :count] = np.where(visible[..., None], z, 0.0)
            self._visible[:, :count] = visible
            return
        for i in range(self.n):
            seen = np.flatnonzero(visible[i])
            seen = seen[np.argsort(z[i, seen, 0], kind="stable")]
            self._z[i, : seen.size] = z[i, seen]
            self._visible[i, : seen.size] = True

    def _filter_step(self, controls: NDArray, z: NDArray, visible: NDArray,
                     acting: NDArray) -> None:
        """Predict and correct the beliefs of the acting robots; the others stay as they are."""
        if self.config.belief == "ekf":
            ekf, frozen = self.ekf, ~acting
            kept = ekf.mean[frozen].copy(), ekf.cov[frozen].copy()
            ekf.predict(controls)
            ekf.update(z, visible, self.map.positions)
            ekf.mean[frozen], ekf.cov[frozen] = kept
            return
        for i in np.flatnonzero(acting):
            belief, rng = self.particle_beliefs[i], self._robot_rngs[i]
            belief.predict(controls[i], rng)
            belief.update_landmarks(z[i], visible[i], self.map.positions, self.sensor, rng,
                                    known_correspondence=bool(self.config.known_correspondences))

    def _fuse(self, acting: NDArray) -> None:
        """Fuse this step's robot detections: every update uses the other robot's belief as it
        was before this step's fusions (a simultaneous exchange, never a loop)."""
        cfg = self.config
        pairs = [(int(i), int(j)) for i, j in zip(*np.nonzero(self._det_seen), strict=True)
                 if acting[i]]
        if cfg.belief == "ekf":
            for i, j in fuse_ekf(self.ekf.mean, self.ekf.cov, self._det_z, pairs, self._det_cov,
                                 cfg.ci_criterion):
                self._fused_pairs[i, j] = True
            return
        pairs = [(i, j) for i, j in pairs
                 if self.steps - self._last_fusion[i, j] >= cfg.fusion_interval]
        if cfg.fusion_sender_localized:
            pairs = [(i, j) for i, j in pairs if self._localized[j]]
        fuse_mcl(self.particle_beliefs, pairs, self._det_z, self._det_std, cfg.fusion_bandwidth,
                 self._free.area, cfg.fusion_samples, self._fusion_rng)
        for i, j in pairs:
            self._fused_pairs[i, j] = True
            self._last_fusion[i, j] = self._last_fusion[j, i] = self.steps

    # -- metrics, observations, info ------------------------------------------------------------

    def _summarize(self) -> None:
        """Means ``(n, 3)``, covariances ``(n, 3, 3)``, entropies ``(n,)`` and confidence."""
        if self.config.belief == "ekf":
            self._means, self._covs = self.ekf.mean.copy(), self.ekf.cov.copy()
            self._entropy = gaussian_entropy(self._covs)
        else:
            beliefs = self.particle_beliefs
            summaries = [b.mean_and_covariance() for b in beliefs]
            self._means = np.array([mean for mean, _ in summaries])
            self._covs = np.array([cov for _, cov in summaries])
            self._entropy = np.array([b.entropy() for b in beliefs])
        cfg = self.config
        errors = self.poses - self._means
        self._pos_err = np.hypot(errors[:, 0], errors[:, 1])
        self._head_err = np.abs(wrap_angle(errors[:, 2]))
        metrics = [
            belief_metrics(cov, float(pe), float(he), False, cfg.localized_position_std,
                           cfg.localized_heading_std, cfg.success_position_tol,
                           cfg.success_heading_tol)
            for cov, pe, he in zip(self._covs, self._pos_err, self._head_err, strict=True)
        ]
        self._localized = np.array([m[2] for m in metrics], dtype=np.bool_)
        self._success = np.array([m[3] for m in metrics], dtype=np.bool_)

    def _observe(self, i: int) -> NDArray[np.float32]:
        """Robot i's observation: its belief, its scan and its detections (never the truth)."""
        cfg = self.config
        out = np.zeros(self._obs_size, dtype=np.float32)
        mean, cov = self._means[i], self._covs[i]
        write_belief_header(mean, cov, float(self._entropy[i]), self._bounds, out)
        pos = BELIEF_HEADER
        if cfg.belief == "mcl":
            belief = self.particle_beliefs[i]
            hist = mass_histogram(belief.particles[:, :2], belief.weights, self._bounds)
            out[pos : pos + hist.size] = np.clip(hist, 0.0, 1.0)
            pos += hist.size
        width, height = self.map.size
        diagonal = math.hypot(width, height)
        scale = cfg.max_range if math.isfinite(cfg.max_range) else diagonal
        slots = SLOT_SIZE * cfg.max_landmarks
        write_landmark_slots(mean, self._z[i], self._visible[i], self._landmarks,
                             self.map.n_landmarks, RANGE_BEARING, scale, out[pos : pos + slots])
        pos += slots
        det_scale = self._det_range if math.isfinite(self._det_range) else diagonal
        for k in range(1, self.n):
            j = (i + k) % self.n
            if self._det_seen[i, j]:
                out[pos : pos + ROBOT_SLOT] = (
                    1.0, min(self._det_z[i, j, 0] / det_scale, 1.0), self._det_z[i, j, 1] / np.pi,
                    1.0 if self._fused_pairs[i, j] else 0.0)
            pos += ROBOT_SLOT
        return out

    def _info(self, i: int, collided: NDArray, gain: float) -> dict[str, Any]:
        outcome = StepOutcome(
            float(self._pos_err[i]), float(self._head_err[i]), float(self._entropy[i]), gain,
            bool(collided[i]), 0.0, bool(self._localized[i]), bool(self._success[i]),
            bool(self._localized[i]), False, int(self._visible[i].sum()), math.nan,
        )
        return step_info(
            outcome, int(self._collisions[i]), self._reward,
            fused=bool(self._fused_pairs[i].any()),
            detected=[self.possible_agents[j] for j in np.flatnonzero(self._det_seen[i])],
            n_visible=outcome.n_visible,
        )

    # -- rendering ------------------------------------------------------------------------------

    def render(self) -> NDArray[np.uint8] | None:
        if self.render_mode is None:
            gymnasium.logger.warn("render() called without a render_mode; pass render_mode=")
            return None
        if not self._has_reset:
            raise RuntimeError("call reset() before render()")
        if self._renderer is None:
            self._renderer = MultiRobotRenderer()
        frame = self._frame()
        if self.render_mode == "rgb_array":
            return self._renderer.render_rgb(frame)
        self._renderer.show(frame)
        return None

    def _frame(self) -> dict[str, Any]:
        """What the renderer draws (truth included: rendering is for people)."""
        mcl = self.config.belief == "mcl"
        seen = self._visible.any(axis=0) if self.config.known_correspondences else None
        return {
            "bounds": self.map.bounds, "landmarks": self.map.positions,
            "seen": seen, "poses": self.poses.copy(), "means": self._means, "covs": self._covs,
            "particles": [b.particles.copy() for b in self.particle_beliefs] if mcl else None,
            "weights": [b.weights for b in self.particle_beliefs] if mcl else None,
            "detections": [(i, j, bool(self._fused_pairs[i, j]))
                           for i, j in zip(*np.nonzero(self._det_seen), strict=True)],
            "paths": [np.array(p) for p in self._paths], "live": self._live.copy(),
            "entropy": self._entropy, "step": self.steps,
        }

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def _fixed_map(spec: Any) -> LandmarkMap | None:
    """The map of a config that does not draw one per episode (None if it does)."""
    if isinstance(spec, str):
        return None
    if isinstance(spec, LandmarkMap):
        return spec
    positions = np.asarray(spec, dtype=np.float64)
    lo, hi = positions.min(axis=0) - 2.0, positions.max(axis=0) + 2.0
    return LandmarkMap(positions, (lo[0], lo[1], hi[0], hi[1]), walls=True)


def parallel_env(n_robots: int = 2, **kwargs: Any) -> MultiRobotLocalizationEnv:
    """The multi-robot env as a PettingZoo ``ParallelEnv`` (kwargs: ``render_mode`` and the
    fields of :class:`MultiRobotConfig`)."""
    return MultiRobotLocalizationEnv(n_robots=n_robots, **kwargs)


def env(n_robots: int = 2, **kwargs: Any) -> AECEnv:
    """The same env through PettingZoo's AEC interface (``parallel_to_aec``)."""
    return parallel_to_aec(parallel_env(n_robots=n_robots, **kwargs))


raw_env = env
