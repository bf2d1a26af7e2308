"""The batch-first simulator of landmark localization: B robots, B maps, B beliefs.

One step for every member b, as in DESIGN.md:

    controls -> true motion (noise, blocked at walls) -> scan from the true pose
             -> EKF predict + stacked update (the filter never sees the true pose)
             -> metrics (entropy, errors) and the observation row

With the numba EKF this is one fused kernel call for the whole batch. With the filterpy
backend the simulation and observation kernels run around filterpy's predict/update.
The single env is this core with B = 1; a vector env is the same code with B = n.

State layout: every per-member float lives in one row of ``state`` ``(B, STATE_SIZE)`` (true
pose, belief mean and covariance, map box, noise cursor, metrics) and every per-landmark one in
``world`` ``(B, N, WORLD_SIZE)`` (position, measurement, visibility), at the offsets named
below; the kernels read those offsets, and everything else the named views of the holder
(``core.rows["entropy"]``, ``core.pose``, ``core.z``, ...; :data:`ROW_DTYPE`). Few arrays
make the kernel call cheap, which matters at a few microseconds per step.

Randomness: each member owns a ``numpy.random.Generator`` (the env's ``np_random``). Step noise
is drawn from it :data:`NOISE_LENGTH` standard normals at a time into the member's buffer, which
the kernel consumes in order: 3 for the motion, then 2 per landmark in view (only those, so a
step of a robot that sees 1 landmark of 15 uses 5 normals, not 33). A buffer is drawn afresh
when the next step could run past its end, and a reset with a new Generator (a reseeded env)
discards the old one: fast and exactly reproducible, in a single env as in a batch.
"""

from __future__ import annotations

import functools
import math
from collections import namedtuple
from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from active_loc.beliefs.ekf import EKFBelief, ekf_predict, ekf_update
from active_loc.beliefs.ekf_filterpy import FilterpyEKFBelief
from active_loc.beliefs.entropy import LOG_2PIE_3, det3
from active_loc.envs.actions import ControlLimits
from active_loc.envs.belief_image import IMAGE_KEY, VECTOR_KEY
from active_loc.envs.config import LocalizationConfig, check_start_pose
from active_loc.envs.metrics import belief_metrics
from active_loc.envs.observations import belief_observation_size, write_belief_observation
from active_loc.envs.outcome import StepOutcome
from active_loc.envs.rewards import REWARD_CODES, outcome_term, uncertainty_reward
from active_loc.geometry import wrap_angle_scalar
from active_loc.maps import LandmarkMap, random_landmark_map
from active_loc.maps.pool import pool_map_rng, shared_pool
from active_loc.motion import UnicycleModel, move_within_bounds_scalar
from active_loc.parallel import note_parallel_launch, prange_forbidden
from active_loc.sensors.landmarks import (
    LandmarkSensor,
    RangeBearingSensor,
    RelativePositionSensor,
    measure_landmarks,
    sees_a_landmark,
)
from active_loc.sensors.lidar import LidarSensor

#: standard normals in a member's noise buffer (the landmark core; more with many landmarks)
NOISE_LENGTH = 256
#: steps per noise block of the association core (a row of draws per step)
NOISE_BLOCK = 64
#: a noise cursor past any buffer: the next step draws a fresh one
NOISE_EXHAUSTED = float(2**31)
NEED_NOISE = -2
#: from this many members on, a batch steps in the ``prange`` kernel even on one thread:
#: numba compiles that loop's body to faster code (on one thread, 0.73 against 1.1 us per
#: member at 256 members), which outweighs the parallel launch (about 0.3 us) from here on
PRANGE_MIN_MEMBERS = 4


#: draws of a random start before ``start="unseen"`` gives up (a start with no landmark in
#: view is found within a few draws on the registered maps)
MAX_UNSEEN_START_DRAWS = 1000
TEXTBOOK_LANDMARKS = np.array([[0.0, 0.0], [2.0, 8.0], [8.0, 2.0], [10.0, 10.0]])
TEXTBOOK_BOUNDS = (-2.0, -2.0, 14.0, 14.0)

# layout of the parameter vector handed to the kernels (one array: fewer kernel arguments
# make a faster call)
(
    P_DT,
    P_VMIN,
    P_VMAX,
    P_OMEGA,
    P_FOV,
    P_RANGE,
    P_SCALE,
    P_KIND,
    P_CONTINUOUS,
    P_REWARD,
    P_LOC_POS,
    P_LOC_HEAD,
    P_TOL_POS,
    P_TOL_HEAD,
    P_RUN_EKF,
) = range(15)
P_Q, P_QROOT, P_R, P_RROOT = 15, 24, 33, 37
P_OUTCOME = 41  # outcome_reward
N_PARAMS = 42

# layout of a row of ``state``
X_POSE, X_MEAN, X_COV, X_BOX, X_NOISE_CURSOR, X_STATS = 0, 3, 6, 15, 21, 22
# within the map box: bounds (x_min, y_min, x_max, y_max), walls flag, landmark count
B_WALLS, B_COUNT = 4, 5
# layout of a landmark's entry in ``world``: position (2), measurement (2), visible (0 / 1)
W_LANDMARK, W_Z, W_VISIBLE = 0, 2, 4
WORLD_SIZE = 5

# layout of the metrics at ``state[:, X_STATS:]``
(
    S_ENTROPY,
    S_LOGDET,
    S_TRACE,
    S_POS_ERR,
    S_HEAD_ERR,
    S_COLLIDED,
    S_N_VISIBLE,
    S_NIS,
    S_POS_STD,
    S_HEAD_STD,
    S_UNCERTAINTY_REWARD,
    S_LOCALIZED,
    S_SUCCESS,
    S_TERMINAL,  # the episode's goal is reached (terminates with terminate_when_localized)
    S_KIDNAPPED,  # the robot was kidnapped on this step
    S_OUTCOME,  # the outcome reward term of this step (``outcome_reward``, signed)
) = range(16)
N_STATS = 16
STATE_SIZE = X_STATS + N_STATS

#: the metrics by name: ``state[b, X_STATS + STAT_OFFSETS[name]]``, in the order of the row
STAT_OFFSETS = {
    "entropy": S_ENTROPY, "logdet": S_LOGDET, "trace": S_TRACE, "pos_err": S_POS_ERR,
    "head_err": S_HEAD_ERR, "collided": S_COLLIDED, "n_visible": S_N_VISIBLE, "nis": S_NIS,
    "pos_std": S_POS_STD, "head_std": S_HEAD_STD, "uncertainty_reward": S_UNCERTAINTY_REWARD,
    "localized": S_LOCALIZED, "success": S_SUCCESS, "terminal": S_TERMINAL,
    "kidnapped": S_KIDNAPPED, "outcome": S_OUTCOME,
}
assert list(STAT_OFFSETS.values()) == list(range(N_STATS))

#: a member's metrics as plain numbers, by name: ``MemberStats._make(core.stats[b].tolist())``
MemberStats = namedtuple("MemberStats", list(STAT_OFFSETS))  # type: ignore[misc]


def _record(fields: dict[str, tuple[object, int]], size: int) -> np.dtype:
    """A record of float64 ``fields`` (name: (shape, offset in floats)) over ``size`` floats."""
    return np.dtype({
        "names": list(fields),
        "formats": [(np.float64, shape) if shape else np.float64 for shape, _ in fields.values()],
        "offsets": [8 * offset for _, offset in fields.values()],
        "itemsize": 8 * size,
    })


#: a row of ``state`` by name, for the Python side (:attr:`StateViews.rows`); the kernels read
#: the packed row at the offsets above. Flags are 0.0 or 1.0.
ROW_DTYPE = _record(
    {"pose": (3, X_POSE), "mean": (3, X_MEAN), "cov": ((3, 3), X_COV), "bounds": (4, X_BOX),
     "walls": ((), X_BOX + B_WALLS), "n_landmarks": ((), X_BOX + B_COUNT),
     "noise_cursor": ((), X_NOISE_CURSOR)}
    | {name: ((), X_STATS + offset) for name, offset in STAT_OFFSETS.items()},
    STATE_SIZE,
)
#: a landmark's entry of ``world`` by name
WORLD_DTYPE = _record(
    {"landmark": (2, W_LANDMARK), "z": (2, W_Z), "visible": ((), W_VISIBLE)}, WORLD_SIZE
)


@dataclass(frozen=True)
class EnvModels:
    """The models of an env: motion, sensor (a landmark sensor or a lidar), the packed kernel
    parameters, the discrete primitives' controls and the control limits."""

    motion: UnicycleModel
    sensor: LandmarkSensor | LidarSensor
    params: NDArray[np.float64]
    primitives: NDArray[np.float64]
    limits: ControlLimits

    @property
    def scale(self) -> float:
        """The length (m) the observation divides landmark offsets by: the sensor's range, or
        the map's diagonal when the range is unlimited."""
        return float(self.params[P_SCALE])


def build_motion(cfg: LocalizationConfig) -> UnicycleModel:
    """The unicycle model of a config (dt and the diagonal Q)."""
    return UnicycleModel(cfg.dt, np.diag(np.square(cfg.motion_noise_std)))


def build_models(cfg: LocalizationConfig) -> EnvModels:
    """Motion and sensor models of a landmark config, and the packed parameter vector of the
    kernels."""
    motion = build_motion(cfg)
    sensor: LandmarkSensor
    if cfg.sensor == "range_bearing":
        sensor = RangeBearingSensor.from_std(cfg.range_std, cfg.bearing_std, cfg.fov, cfg.max_range)
    else:
        sensor = RelativePositionSensor(cfg.position_std**2 * np.eye(2), cfg.fov, cfg.max_range)
    params = np.zeros(N_PARAMS)
    params[P_DT] = cfg.dt
    params[P_VMIN] = cfg.v_min
    params[P_VMAX] = cfg.v_max
    params[P_OMEGA] = cfg.omega_max
    params[P_FOV] = cfg.fov
    params[P_RANGE] = cfg.max_range
    if math.isfinite(cfg.max_range):
        params[P_SCALE] = cfg.max_range
    else:
        width, height = _map_extent(cfg)
        params[P_SCALE] = math.hypot(width, height)
    params[P_KIND] = sensor.kind
    params[P_CONTINUOUS] = 1.0 if cfg.action_type == "continuous" else 0.0
    params[P_RUN_EKF] = 1.0 if cfg.ekf_backend == "numba" else 0.0
    params[P_Q : P_Q + 9] = motion.noise_cov.ravel()
    params[P_QROOT : P_QROOT + 9] = motion.noise_root.ravel()
    params[P_R : P_R + 4] = sensor.noise_cov.ravel()
    params[P_RROOT : P_RROOT + 4] = sensor.noise_root.ravel()
    write_task_params(cfg, params)
    limits = ControlLimits(cfg.action_type, cfg.dt, cfg.v_min, cfg.v_max, cfg.omega_max)
    return EnvModels(motion, sensor, params, limits.primitives(), limits)


def write_task_params(cfg: LocalizationConfig, params: NDArray[np.float64]) -> None:
    """The entries of the packed parameter vector ``params`` that :func:`record_metrics`
    reads: the reward, the confidence and success thresholds, the outcome reward."""
    params[P_REWARD] = REWARD_CODES[cfg.reward]
    params[P_LOC_POS] = cfg.localized_position_std
    params[P_LOC_HEAD] = cfg.localized_heading_std
    params[P_TOL_POS] = cfg.success_position_tol
    params[P_TOL_HEAD] = cfg.success_heading_tol
    params[P_OUTCOME] = cfg.outcome_reward


def _map_extent(cfg: LocalizationConfig) -> tuple[float, float]:
    if isinstance(cfg.map, LandmarkMap):
        return cfg.map.size
    if isinstance(cfg.map, str) and cfg.map == "textbook":
        return TEXTBOOK_BOUNDS[2] - TEXTBOOK_BOUNDS[0], TEXTBOOK_BOUNDS[3] - TEXTBOOK_BOUNDS[1]
    if isinstance(cfg.map, str):
        return cfg.map_size
    return fixed_landmark_map(cfg).size


def _pool_landmark_map(
    size: tuple[float, float], n_landmarks: tuple[int, int], index: int
) -> LandmarkMap:
    """Map ``index`` of a pool of random landmark maps."""
    return random_landmark_map(pool_map_rng(index), size, n_landmarks)


def fixed_landmark_map(cfg: LocalizationConfig) -> LandmarkMap:
    """The landmark map of a config that does not draw one per episode."""
    if isinstance(cfg.map, LandmarkMap):
        return cfg.map
    if isinstance(cfg.map, str):
        return LandmarkMap(TEXTBOOK_LANDMARKS, TEXTBOOK_BOUNDS, walls=False)
    positions = np.asarray(cfg.map, dtype=np.float64)
    lo, hi = positions.min(axis=0) - 2.0, positions.max(axis=0) + 2.0
    return LandmarkMap(positions, (lo[0], lo[1], hi[0], hi[1]), walls=False)


# --------------------------------------------------------------------------------------------
# kernels


@numba.njit(cache=True, nogil=True)
def _decode(action: NDArray, params: NDArray) -> tuple[float, float]:
    """Physical control of one action: continuous actions are clipped to [-1, 1] and scaled;
    otherwise the action already is the control (V m/s, omega rad/s)."""
    if params[P_CONTINUOUS] < 0.5:
        return action[0], action[1]
    a_v = min(1.0, max(-1.0, action[0]))
    a_w = min(1.0, max(-1.0, action[1]))
    v = params[P_VMIN] + 0.5 * (a_v + 1.0) * (params[P_VMAX] - params[P_VMIN])
    return v, a_w * params[P_OMEGA]


@numba.njit(cache=True, nogil=True)
def _simulate_one(
    v: float, omega: float, normals: NDArray, params: NDArray, state: NDArray, world: NDArray
) -> tuple[bool, int]:
    """Move the true robot with noise, then scan.

    ``state`` is one row ``(STATE_SIZE,)``, ``world`` one member ``(N, WORLD_SIZE)``,
    ``normals`` the member's unused noise: 3 for the motion, then 2 per landmark in view.

    Returns:
        Whether the move was blocked, and how many normals were used.
    """
    # motion noise L_Q e from the first three normals (L_Q row-major in params)
    q = P_QROOT
    e_x = params[q] * normals[0] + params[q + 1] * normals[1] + params[q + 2] * normals[2]
    e_y = params[q + 3] * normals[0] + params[q + 4] * normals[1] + params[q + 5] * normals[2]
    e_t = params[q + 6] * normals[0] + params[q + 7] * normals[1] + params[q + 8] * normals[2]
    pose = state[X_POSE : X_POSE + 3]
    box = state[X_BOX : X_BOX + 6]
    collided = move_within_bounds_scalar(
        pose, v, omega, params[P_DT], e_x, e_y, e_t, box[:4], box[B_WALLS] > 0.5
    )
    r = P_RROOT
    used = measure_landmarks(
        int(params[P_KIND]), pose, world[:, W_LANDMARK : W_LANDMARK + 2], int(box[B_COUNT]),
        params[P_FOV], params[P_RANGE], (params[r], params[r + 2], params[r + 3]), normals[3:],
        world[:, W_Z : W_Z + 2], world[:, W_VISIBLE],
    )
    return collided, 3 + used


@numba.njit(cache=True, nogil=True)
def record_metrics(
    params: NDArray, state: NDArray, entropy: float, logdet: float, kidnap_unresolved: bool
) -> None:
    """The metrics of a state row's belief (its ``mean`` and ``cov`` already written, with
    ``entropy`` in nats and the covariance's ``logdet``) against the truth (the errors are for
    info only): the uncertainty reward term against the previous values still in the row,
    the errors, the confidence and success flags (:func:`belief_metrics`) and the outcome
    term. Every core records its members' metrics through this one function."""
    pose = state[X_POSE : X_POSE + 3]
    mean = state[X_MEAN : X_MEAN + 3]
    cov = state[X_COV : X_COV + 9].reshape(3, 3)
    stats = state[X_STATS : X_STATS + N_STATS]
    trace = cov[0, 0] + cov[1, 1] + cov[2, 2]
    stats[S_UNCERTAINTY_REWARD] = uncertainty_reward(
        int(params[P_REWARD]), stats[S_ENTROPY], entropy, stats[S_LOGDET], logdet,
        stats[S_TRACE], trace,
    )
    stats[S_ENTROPY] = entropy
    stats[S_LOGDET] = logdet
    stats[S_TRACE] = trace
    pos_err = np.hypot(pose[0] - mean[0], pose[1] - mean[1])
    head_err = abs(wrap_angle_scalar(pose[2] - mean[2]))
    stats[S_POS_ERR] = pos_err
    stats[S_HEAD_ERR] = head_err
    pos_std, head_std, localized, success, terminal = belief_metrics(
        cov, pos_err, head_err, kidnap_unresolved, params[P_LOC_POS], params[P_LOC_HEAD],
        params[P_TOL_POS], params[P_TOL_HEAD],
    )
    stats[S_POS_STD] = pos_std
    stats[S_HEAD_STD] = head_std
    stats[S_LOCALIZED] = 1.0 if localized else 0.0
    stats[S_SUCCESS] = 1.0 if success else 0.0
    stats[S_TERMINAL] = 1.0 if terminal else 0.0
    stats[S_OUTCOME] = outcome_term(terminal, success, params[P_OUTCOME])


@numba.njit(cache=True, nogil=True)
def _finish_one(params: NDArray, state: NDArray, world: NDArray, obs: NDArray) -> None:
    """The EKF belief's metrics (:func:`record_metrics`) and the observation row."""
    mean = state[X_MEAN : X_MEAN + 3]
    cov = state[X_COV : X_COV + 9].reshape(3, 3)
    det = det3(cov)
    logdet = np.log(det) if det > 0 else -np.inf
    entropy = 0.5 * (LOG_2PIE_3 + logdet)
    record_metrics(params, state, entropy, logdet, False)
    visible = world[:, W_VISIBLE]
    state[X_STATS + S_N_VISIBLE] = visible.sum()
    write_belief_observation(
        mean, cov, entropy, world[:, W_Z : W_Z + 2], visible,
        world[:, W_LANDMARK : W_LANDMARK + 2], int(state[X_BOX + B_COUNT]),
        state[X_BOX : X_BOX + 4], int(params[P_KIND]), params[P_SCALE], obs,
    )


@numba.njit(cache=True, nogil=True)
def first_bad_action(actions: NDArray, active: NDArray) -> int:
    """The index of the first active member whose action ``(B, 2)`` is not finite, or -1."""
    for b in range(actions.shape[0]):
        if active[b] and not (np.isfinite(actions[b, 0]) and np.isfinite(actions[b, 1])):
            return b
    return -1


@numba.njit(cache=True, nogil=True, inline="always")
def _step_member(
    b: int, actions: NDArray, params: NDArray, noise: NDArray, state: NDArray, world: NDArray,
    obs: NDArray, pending: NDArray,
) -> None:
    """One step of member ``b`` (arguments as in :func:`step_batch`), or ``pending[b] = True``
    if its noise buffer may not hold the step's normals (3 + 2 per landmark)."""
    cursor = int(state[b, X_NOISE_CURSOR])
    if cursor + 3 + 2 * int(state[b, X_BOX + B_COUNT]) > noise.shape[1]:
        pending[b] = True
        return
    pending[b] = False
    v, omega = _decode(actions[b], params)
    collided, used = _simulate_one(v, omega, noise[b, cursor:], params, state[b], world[b])
    state[b, X_NOISE_CURSOR] = cursor + used
    state[b, X_STATS + S_COLLIDED] = 1.0 if collided else 0.0
    if params[P_RUN_EKF] > 0.5:
        mean = state[b, X_MEAN : X_MEAN + 3]
        cov = state[b, X_COV : X_COV + 9].reshape(3, 3)
        # a blocked robot knows it did not advance (bumper, odometry): predict with V = 0
        ekf_predict(mean, cov, 0.0 if collided else v, omega, params[P_DT],
                    params[P_Q : P_Q + 9].reshape(3, 3))
        state[b, X_STATS + S_NIS] = ekf_update(
            mean, cov, world[b, :, W_Z : W_Z + 2], world[b, :, W_VISIBLE],
            world[b, :, W_LANDMARK : W_LANDMARK + 2], int(params[P_KIND]),
            params[P_R : P_R + 4].reshape(2, 2),
        )
        _finish_one(params, state[b], world[b], obs[b])


@numba.njit(cache=True, nogil=True)
def step_batch(
    actions: NDArray, params: NDArray, noise: NDArray, state: NDArray, world: NDArray,
    obs: NDArray, active: NDArray, pending: NDArray,
) -> int:
    """One step of the batch's active members, one after the other.

    Args:
        actions: ``(B, 2)`` continuous actions in [-1, 1] (clipped) or, for discrete action
            sets, the primitives' physical controls (V m/s, omega rad/s).
        params: the packed parameter vector of :func:`build_models`; ``P_RUN_EKF`` = 0 leaves
            the belief update to the caller, who then calls :func:`finish_batch`.
        noise: ``(B, L)`` standard normals, consumed in order from each member's
            cursor ``state[:, X_NOISE_CURSOR]``.
        state: ``(B, STATE_SIZE)``, world: ``(B, N, WORLD_SIZE)``: updated in place.
        obs: ``(B, D)`` float32 out.
        active: ``(B,)`` bool; inactive members are left untouched (a vector env resets them
            this step instead), their actions unread.
        pending: ``(B,)`` bool out: the active members left untouched because their noise
            buffer may run out this step; the caller refills them and steps just those.

    Returns:
        -1 when every active member stepped; :data:`NEED_NOISE` when some are pending; or
        the index of an active member whose action is not finite (then nothing has changed).
    """
    bad = first_bad_action(actions, active)
    if bad >= 0:
        return bad
    waiting = False
    for b in range(actions.shape[0]):
        if active[b]:
            _step_member(b, actions, params, noise, state, world, obs, pending)
            waiting |= pending[b]
        else:
            pending[b] = False
    return NEED_NOISE if waiting else -1


@numba.njit(cache=True, nogil=True, parallel=True)
def step_batch_parallel(
    actions: NDArray, params: NDArray, noise: NDArray, state: NDArray, world: NDArray,
    obs: NDArray, active: NDArray, pending: NDArray,
) -> int:
    """:func:`step_batch` with the members spread over numba's threads. Each member touches
    only its own rows, so the result does not depend on the thread count."""
    bad = first_bad_action(actions, active)
    if bad >= 0:
        return bad
    for b in numba.prange(actions.shape[0]):
        if active[b]:
            _step_member(b, actions, params, noise, state, world, obs, pending)
        else:
            pending[b] = False
    for b in range(actions.shape[0]):
        if pending[b]:
            return NEED_NOISE
    return -1


@numba.njit(cache=True, nogil=True)
def finish_batch(params: NDArray, state: NDArray, world: NDArray, obs: NDArray) -> None:
    """Metrics and observations of the whole batch (after an external belief update)."""
    for b in range(state.shape[0]):
        _finish_one(params, state[b], world[b], obs[b])


@numba.njit(cache=True, nogil=True)
def random_start_pose(bounds: NDArray, uniforms: NDArray) -> tuple[float, float, float]:
    """The start pose ``(x, y, theta)`` (m, m, rad) that 3 uniforms in [0, 1) place uniformly
    in the map of ``bounds`` ``(x_min, y_min, x_max, y_max)``, 1 m from the border (or a
    quarter of a small map), with any heading."""
    margin = min(1.0, 0.25 * (bounds[2] - bounds[0]), 0.25 * (bounds[3] - bounds[1]))
    x = bounds[0] + margin + uniforms[0] * (bounds[2] - bounds[0] - 2 * margin)
    y = bounds[1] + margin + uniforms[1] * (bounds[3] - bounds[1] - 2 * margin)
    return x, y, -np.pi + 2.0 * np.pi * uniforms[2]


@numba.njit(cache=True, nogil=True)
def reset_member_kernel(
    b: int,
    positions: NDArray,
    bounds: NDArray,
    walls: bool,
    random_start: bool,
    start: NDArray,
    normals: NDArray,
    error_std: NDArray,
    initial_cov: NDArray,
    params: NDArray,
    state: NDArray,
    world: NDArray,
    obs: NDArray,
) -> None:
    """Write a new episode of member ``b`` into the batch arrays.

    Args:
        positions: ``(n, 2)`` landmarks of the episode's map; bounds ``(4,)``; walls.
        random_start: if True, ``start`` holds 3 uniforms in [0, 1) placing the robot uniformly
            in the map (1 m from the border, or a quarter of a small map) with any heading;
            otherwise ``start`` is the start pose.
        normals: 3 standard normals; the belief mean is the start + ``error_std * normals``.
        initial_cov: ``(3, 3)`` initial belief covariance.
    """
    n = positions.shape[0]
    row = state[b]
    row[:] = 0.0
    world[b] = 0.0
    world[b, :n, W_LANDMARK : W_LANDMARK + 2] = positions
    row[X_BOX : X_BOX + 4] = bounds
    row[X_BOX + B_WALLS] = 1.0 if walls else 0.0
    row[X_BOX + B_COUNT] = n
    if random_start:
        row[X_POSE], row[X_POSE + 1], row[X_POSE + 2] = random_start_pose(bounds, start)
    else:
        row[X_POSE : X_POSE + 3] = start
    for i in range(3):
        row[X_MEAN + i] = row[X_POSE + i] + error_std[i] * normals[i]
    row[X_MEAN + 2] = wrap_angle_scalar(row[X_MEAN + 2])
    row[X_COV : X_COV + 9] = initial_cov.ravel()
    row[X_NOISE_CURSOR] = NOISE_EXHAUSTED  # the first step draws a fresh noise buffer
    _finish_one(params, row, world[b], obs[b])
    row[X_STATS + S_UNCERTAINTY_REWARD] = 0.0
    row[X_STATS + S_OUTCOME] = 0.0


def executed_controls(actions: NDArray, params: NDArray, collided: NDArray) -> NDArray:
    """Physical controls ``(B, 2)`` the filter predicts with, as :func:`step_batch` does."""
    out = np.empty((actions.shape[0], 2))
    for b in range(actions.shape[0]):
        v, omega = _decode(actions[b], params)
        out[b] = (0.0 if collided[b] else v), omega
    return out


# --------------------------------------------------------------------------------------------
# the holders


class StateViews:
    """Named views of the ``state`` array every core keeps (one row per member): outside the
    kernels, the rows are read and written through these, never at offsets. ``pose``,
    ``belief_mean`` and ``belief_cov`` are plain slices, not fields of :attr:`rows`: the shells
    read them every step, and a record view costs about a microsecond to build."""

    state: NDArray[np.float64]
    obs: NDArray[np.float32]
    #: ``(B, C, R, R)`` the belief images of ``observation="image"`` (None: no image)
    image: NDArray[np.float32] | None = None

    @property
    def observations(self) -> NDArray[np.float32] | dict[str, NDArray[np.float32]]:
        """The members' observations (views): ``obs`` ``(B, D)``, or with an image the dict
        of :mod:`active_loc.envs.belief_image` (``"image"`` ``(B, C, R, R)``, ``"vector"``
        ``(B, D)``)."""
        if self.image is None:
            return self.obs
        return {IMAGE_KEY: self.image, VECTOR_KEY: self.obs}

    @property
    def rows(self) -> NDArray[np.void]:
        """``(B,)`` the rows as :data:`ROW_DTYPE` records (a view: writes go to ``state``)."""
        return self.state.view(ROW_DTYPE)[:, 0]

    @property
    def pose(self) -> NDArray[np.float64]:
        """``(B, 3)`` true poses (a view)."""
        return self.state[:, X_POSE : X_POSE + 3]

    @property
    def stats(self) -> NDArray[np.float64]:
        """``(B, N_STATS)`` metrics of the last step, in the order of :data:`STAT_OFFSETS`
        (a view)."""
        return self.state[:, X_STATS : X_STATS + N_STATS]

    @property
    def belief_mean(self) -> NDArray[np.float64]:
        """``(B, 3)`` belief means after the last step (a view)."""
        return self.state[:, X_MEAN : X_MEAN + 3]

    @property
    def belief_cov(self) -> NDArray[np.float64]:
        """``(B, 3, 3)`` belief covariances after the last step (a copy)."""
        return self.state[:, X_COV : X_COV + 9].reshape(-1, 3, 3).copy()

    def outcome(self, b: int) -> StepOutcome:
        """Member ``b``'s last step (or reset), by name."""
        return outcome_from_stats(MemberStats._make(self.stats[b].tolist()))

    def outcomes(self, rows: Sequence[int] | slice = slice(None)) -> list[StepOutcome]:
        """:meth:`outcome` of the members in ``rows`` (all by default)."""
        return [outcome_from_stats(MemberStats._make(stats))
                for stats in self.stats[rows].tolist()]


def outcome_from_stats(s: MemberStats) -> StepOutcome:
    """The named outcome of a member's metrics."""
    return StepOutcome(
        s.pos_err, s.head_err, s.entropy, s.uncertainty_reward, bool(s.collided), s.outcome,
        bool(s.localized), bool(s.success), bool(s.terminal), bool(s.kidnapped),
        int(s.n_visible), s.nis,
    )


class LandmarkCore(StateViews):
    """State arrays of B landmark-localization episodes and the calls that advance them.

    Args:
        config: the task.
        batch_size: B.

    The numba belief's ``mean`` and ``cov`` are views into :attr:`state`; pickling and
    copying rebuild those views (``__setstate__``).
    """

    def __init__(self, config: LocalizationConfig, batch_size: int = 1) -> None:
        if config.ekf_backend == "filterpy" and batch_size != 1:
            raise ValueError("ekf_backend='filterpy' runs single envs only (batch size 1)")
        self.config = config
        self.models = build_models(config)
        self._fused = config.ekf_backend == "numba"  # the kernel runs the EKF itself
        self.batch_size = batch_size
        n = config.max_landmarks
        draws_maps = isinstance(config.map, str) and config.map == "random"
        self.fixed_map = None if draws_maps else fixed_landmark_map(config)
        if self.fixed_map is not None and config.start == "fixed":
            check_start_pose(self.fixed_map, config.start_pose[:2])
        if self.fixed_map is not None and self.fixed_map.n_landmarks > n:
            raise ValueError(
                f"the map has {self.fixed_map.n_landmarks} landmarks but max_landmarks={n}; "
                "raise max_landmarks"
            )
        self.maps: list[LandmarkMap | None] = [None] * batch_size
        self.state = np.zeros((batch_size, STATE_SIZE))
        self.world = np.zeros((batch_size, n, WORLD_SIZE))
        self.obs = np.zeros((batch_size, belief_observation_size(n)), dtype=np.float32)
        # room for several steps that see every landmark, even with a large max_landmarks
        self.noise = np.zeros((batch_size, max(NOISE_LENGTH, 4 * (3 + 2 * n))))
        #: the Generator each member's noise buffer came from; a reset with another one (a
        #: reseeded env) discards the buffer, so an episode never uses an old seed's draws
        self.noise_source: list[np.random.Generator | None] = [None] * batch_size
        #: the actions of the next step, written by the env: ``(B, 2)``, see :func:`step_batch`
        self.actions = np.zeros((batch_size, 2))
        self._all_active = np.ones(batch_size, dtype=np.bool_)
        self._pending = np.zeros(batch_size, dtype=np.bool_)  # see step_batch
        self._random_start = config.start in ("random", "unseen")
        self._start_pose = np.array(config.start_pose, dtype=np.float64)
        self._error_std = np.array(config.initial_error_std, dtype=np.float64)
        self._initial_cov = np.diag(np.square(config.initial_belief_std))
        rows = self.rows
        rows["noise_cursor"] = NOISE_EXHAUSTED
        rows["cov"] = self._initial_cov
        self.belief: EKFBelief | FilterpyEKFBelief
        if config.ekf_backend == "filterpy":
            self.belief = FilterpyEKFBelief(
                np.zeros(3), self._initial_cov, self.models.motion, self.models.sensor
            )
        else:
            self._bind_belief()

    # -- named views of the packed arrays ------------------------------------------------------

    @property
    def entries(self) -> NDArray[np.void]:
        """``(B, N)`` the landmarks' entries of ``world`` as :data:`WORLD_DTYPE` records (a
        view)."""
        return self.world.view(WORLD_DTYPE)[..., 0]

    @property
    def landmarks(self) -> NDArray[np.float64]:
        """``(B, N, 2)`` landmark positions, zero-padded (a view)."""
        return self.entries["landmark"]

    @property
    def z(self) -> NDArray[np.float64]:
        """``(B, N, 2)`` the last scan, zero where unseen (a view)."""
        return self.entries["z"]

    @property
    def visible(self) -> NDArray[np.bool_]:
        """``(B, N)`` which landmarks the last scan saw (a copy)."""
        return self.entries["visible"].astype(np.bool_)

    # -- reset ---------------------------------------------------------------------------------

    def reset_member(self, b: int, rng: np.random.Generator) -> None:
        """New episode for member ``b``: map, true start, initial belief; no scan yet."""
        cfg = self.config
        if self.fixed_map is not None:
            lmap = self.fixed_map
        elif cfg.map_pool is not None:
            build = functools.partial(_pool_landmark_map, cfg.map_size, cfg.n_landmarks)
            key = ("landmarks", repr((cfg.map_size, cfg.n_landmarks)))
            lmap = shared_pool(key, cfg.map_pool, build).draw(rng)
        else:
            lmap = random_landmark_map(rng, cfg.map_size, cfg.n_landmarks)
        self.maps[b] = lmap
        if cfg.start == "unseen":
            uniforms = self._unseen_start(lmap, rng)
        else:
            uniforms = rng.random(3) if self._random_start else self._start_pose
        normals = rng.standard_normal(3)
        row = self.rows[b]
        cursor = row["noise_cursor"]
        reset_member_kernel(
            b, lmap.positions, np.asarray(lmap.bounds), lmap.walls, self._random_start, uniforms,
            normals, self._error_std, self._initial_cov, self.models.params, self.state,
            self.world, self.obs,
        )
        if self.noise_source[b] is rng:
            # the same Generator goes on (no reseeding): so does its noise buffer
            row["noise_cursor"] = cursor
        if isinstance(self.belief, FilterpyEKFBelief):
            self.belief.set(row["mean"], self._initial_cov)

    def _unseen_start(self, lmap: LandmarkMap, rng: np.random.Generator) -> NDArray:
        """Uniforms of a random start (see :func:`random_start_pose`) from which no landmark
        is in view, so that the first scan tells nothing and the agent must look: drawn
        again until one is found, at most :data:`MAX_UNSEEN_START_DRAWS` times."""
        bounds = np.asarray(lmap.bounds)
        cfg = self.config
        for _ in range(MAX_UNSEEN_START_DRAWS):
            uniforms = rng.random(3)
            x, y, theta = random_start_pose(bounds, uniforms)
            if not sees_a_landmark(x, y, theta, lmap.positions, cfg.fov, cfg.max_range):
                return uniforms
        raise ValueError(
            f"start='unseen': no start pose without a landmark in view in "
            f"{MAX_UNSEEN_START_DRAWS} draws (fov={cfg.fov}, max_range={cfg.max_range}, "
            f"{lmap.n_landmarks} landmarks); use start='random'"
        )

    # -- step ----------------------------------------------------------------------------------

    def refill_noise(self, b: int, rng: np.random.Generator) -> None:
        """Draw a fresh noise buffer of member ``b`` from its Generator."""
        rng.standard_normal(out=self.noise[b])  # the same draws as standard_normal(L)
        self.rows[b]["noise_cursor"] = 0
        self.noise_source[b] = rng

    def reset_members(
        self, rows: Sequence[int], rngs: Sequence[np.random.Generator],
        threads: int | None = None,
    ) -> None:
        """:meth:`reset_member` of each member in ``rows`` with its Generator in ``rngs``
        (aligned with ``rows``), in turn (a reset is microseconds: ``threads`` is unused)."""
        for b, rng in zip(rows, rngs, strict=True):
            self.reset_member(b, rng)

    def step(
        self,
        rngs: Sequence[np.random.Generator],
        active: NDArray[np.bool_] | None = None,
        threads: int = 1,
    ) -> int:
        """Advance the members with the actions in :attr:`actions` ``(B, 2)``.

        Args:
            rngs: the Generator of each member, to refill used-up noise buffers.
            active: ``(B,)`` which members to advance; None: all.
            threads: numba threads to spread the members over (the fused EKF from
                :data:`PRANGE_MIN_MEMBERS` members on); the result does not depend on it.

        Returns:
            -1, or the index of a member whose action is not finite (nothing advanced then).
        """
        params = self.models.params
        if active is None:
            active = self._all_active
        if (self._fused and self.batch_size >= PRANGE_MIN_MEMBERS
                and not prange_forbidden()):
            note_parallel_launch()
            numba.set_num_threads(threads)  # a setting of the calling thread: set every call
            kernel = step_batch_parallel
        else:
            kernel = step_batch
        pending = self._pending
        code = kernel(self.actions, params, self.noise, self.state, self.world, self.obs, active,
                      pending)
        if code == NEED_NOISE:  # a few members per call at most: refill them, step just them
            waiting = pending.copy()
            for b in np.flatnonzero(waiting):
                self.refill_noise(int(b), rngs[b])
            code = step_batch(self.actions, params, self.noise, self.state, self.world, self.obs,
                              waiting, pending)
            assert code != NEED_NOISE, "a fresh noise buffer holds a step's normals"
        if code >= 0:
            return code
        if self._fused:
            return code
        rows = self.rows
        collided = rows["collided"].astype(np.bool_)
        belief = self.belief
        belief.predict(executed_controls(self.actions, params, collided))
        belief.update(self.z, self.visible, self.landmarks)
        rows["mean"] = belief.mean
        rows["cov"] = belief.cov
        rows["nis"] = belief.last_nis
        finish_batch(params, self.state, self.world, self.obs)
        return -1

    # -- the numba belief's arrays are views of the state -------------------------------------

    def _bind_belief(self) -> None:
        rows = self.rows
        self.belief = EKFBelief.wrap(rows["mean"], rows["cov"], self.models.motion,
                                     self.models.sensor)

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        if isinstance(self.belief, EKFBelief):
            del state["belief"]
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        if "belief" not in state:
            self._bind_belief()
