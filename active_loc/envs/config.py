"""Configuration of the landmark localization environments: one frozen dataclass.

Every field has a documented default and unit; ``gymnasium.make(id, **kwargs)`` passes kwargs
straight into it (over the scenario's preset), and a bad value raises ``ValueError`` naming the
field and the allowed range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from active_loc.maps import LandmarkMap

BELIEFS = ("ekf",)
EKF_BACKENDS = ("numba", "filterpy")
SENSORS = ("range_bearing", "relative_position")
ACTION_TYPES = ("continuous", "discrete")
OBSERVATIONS = ("belief",)
REWARDS = ("info_gain", "neg_entropy", "logdet", "trace")
STARTS = ("random", "fixed")


@dataclass(frozen=True)
class LandmarkEnvConfig:
    """Everything that defines a landmark localization task."""

    # --- map -----------------------------------------------------------------------------
    # "random": a new seeded random landmark map every episode; "textbook": the four
    # landmarks of the chapter's exercise; or a LandmarkMap / (N, 2) array of positions
    map: Any = "random"
    map_size: tuple[float, float] = (20.0, 20.0)  # random maps: width, height (m)
    n_landmarks: tuple[int, int] = (8, 15)  # random maps: inclusive range of the count
    max_landmarks: int = 15  # observation slots; maps may not have more landmarks than this

    # --- robot ---------------------------------------------------------------------------
    dt: float = 0.2  # time step (s)
    # square root of the diagonal of Q, the motion noise per step (m, m, rad)
    motion_noise_std: tuple[float, float, float] = (0.02, 0.02, 0.01)
    v_min: float = 0.0  # forward speed range (m/s)
    v_max: float = 1.0
    omega_max: float = 1.5  # turn rate range [-omega_max, omega_max] (rad/s)
    start: str = "random"  # "random": uniform in the map (1 m from the border), any heading
    start_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)  # used when start == "fixed"

    # --- sensor --------------------------------------------------------------------------
    sensor: str = "range_bearing"  # or "relative_position" (landmark in the robot frame)
    range_std: float = 0.1  # range_bearing: range noise std (m)
    bearing_std: float = 0.035  # range_bearing: bearing noise std (rad), about 2 degrees
    position_std: float = 0.5  # relative_position: noise std per axis (m); R = std^2 I
    fov: float = math.pi / 2  # field of view (rad), centred on the heading; 2*pi = all round
    max_range: float = 6.0  # maximum range (m); inf for unlimited

    # --- belief --------------------------------------------------------------------------
    belief: str = "ekf"
    ekf_backend: str = "numba"  # "filterpy" runs the reference implementation (single envs)
    initial_error_std: tuple[float, float, float] = (0.5, 0.5, 0.3)  # true - mean at reset
    initial_belief_std: tuple[float, float, float] = (0.5, 0.5, 0.3)  # sqrt diag Sigma_0

    # --- agent interface -----------------------------------------------------------------
    action_type: str = "continuous"  # "continuous": Box(-1, 1, (2,)); "discrete": primitives
    observation: str = "belief"
    reward: str = "info_gain"  # "info_gain", "neg_entropy", "logdet" or "trace"
    step_cost: float = 0.0  # subtracted every step (>= 0)
    collision_penalty: float = 1.0  # subtracted on a blocked move (>= 0)

    # --- termination and success ---------------------------------------------------------
    terminate_when_localized: bool = True
    localized_position_std: float = 0.15  # belief confident: largest position std below (m)
    localized_heading_std: float = 0.05  # ... and heading std below (rad)
    success_position_tol: float = 0.3  # success: confident and position error below (m)
    success_heading_tol: float = 0.15  # ... and heading error below (rad)

    def __post_init__(self) -> None:
        _one_of("belief", self.belief, BELIEFS)
        _one_of("ekf_backend", self.ekf_backend, EKF_BACKENDS)
        _one_of("sensor", self.sensor, SENSORS)
        _one_of("action_type", self.action_type, ACTION_TYPES)
        _one_of("observation", self.observation, OBSERVATIONS)
        _one_of("reward", self.reward, REWARDS)
        _one_of("start", self.start, STARTS)
        if isinstance(self.map, str):
            _one_of("map", self.map, ("random", "textbook"))
        elif not isinstance(self.map, LandmarkMap):
            positions = np.asarray(self.map, dtype=np.float64)
            if positions.ndim != 2 or positions.shape[1] != 2 or positions.shape[0] == 0:
                raise ValueError(
                    "map must be 'random', 'textbook', a LandmarkMap or a non-empty (N, 2) "
                    f"array of landmark positions, got shape {positions.shape}"
                )
        for f in fields(self):
            if f.type == "float":
                _number(f.name, getattr(self, f.name))
        _positive("dt", self.dt)
        _positive("v_max", self.v_max, allow_zero=True)
        if not (math.isfinite(self.v_min) and self.v_min <= self.v_max):
            raise ValueError(f"v_min must be finite and <= v_max={self.v_max}, got {self.v_min}")
        _positive("omega_max", self.omega_max, allow_zero=True)
        _stds("motion_noise_std", self.motion_noise_std, allow_zero=True)
        _stds("initial_error_std", self.initial_error_std, allow_zero=True)
        _stds("initial_belief_std", self.initial_belief_std, allow_zero=False)
        _positive("range_std", self.range_std)
        _positive("bearing_std", self.bearing_std)
        _positive("position_std", self.position_std)
        if not (0 < self.fov <= 2 * math.pi):
            raise ValueError(f"fov must be in (0, 2*pi] rad, got {self.fov}")
        if not self.max_range > 0:
            raise ValueError(f"max_range must be > 0 m (inf allowed), got {self.max_range}")
        if int(self.max_landmarks) < 1:
            raise ValueError(f"max_landmarks must be >= 1, got {self.max_landmarks}")
        low, high = self.n_landmarks
        if not 1 <= low <= high <= self.max_landmarks:
            raise ValueError(
                f"n_landmarks must satisfy 1 <= low <= high <= max_landmarks="
                f"{self.max_landmarks}, got {self.n_landmarks}"
            )
        if len(self.map_size) != 2 or min(self.map_size) <= 2.0:
            raise ValueError(
                f"map_size must be (width, height) above 2 m each, got {self.map_size}"
            )
        _positive("step_cost", self.step_cost, allow_zero=True)
        _positive("collision_penalty", self.collision_penalty, allow_zero=True)
        for name in (
            "localized_position_std",
            "localized_heading_std",
            "success_position_tol",
            "success_heading_tol",
        ):
            _positive(name, getattr(self, name))
        if len(self.start_pose) != 3 or not all(math.isfinite(v) for v in self.start_pose):
            raise ValueError(
                f"start_pose must be three finite numbers (x, y, theta), got {self.start_pose}"
            )

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))


def _one_of(name: str, value: object, allowed: tuple[str, ...]) -> None:
    if value not in allowed:
        raise ValueError(f"{name}={value!r} is not one of {allowed}")


def _number(name: str, value: object) -> None:
    if not isinstance(value, (int, float, np.integer, np.floating)) or isinstance(value, bool):
        raise ValueError(f"{name} must be a number, got {value!r}")


def _positive(name: str, value: float, allow_zero: bool = False) -> None:
    _number(name, value)
    ok = math.isfinite(value) and (value >= 0 if allow_zero else value > 0)
    if not ok:
        bound = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name} must be a finite number {bound}, got {value}")


def _stds(name: str, values: tuple[float, ...], allow_zero: bool) -> None:
    if len(values) != 3:
        raise ValueError(f"{name} must have 3 entries (x m, y m, theta rad), got {values}")
    for v in values:
        _positive(name, float(v), allow_zero=allow_zero)
