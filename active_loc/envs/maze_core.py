"""``MazeCore``: B maze episodes of ``ActiveLoc/Maze-v0`` stepped together.

The maze's simulator, batch-first: a :class:`MazeEnv` is a shell around a core of one member,
and the native vector env steps all its sub-envs in one core, one kernel call per step. Every
member has its own maze, true pose, exact Markov belief (one :class:`GridBelief` of B
members) and observation row; a step moves the robot, predicts the belief, reads the depth,
corrects the belief, and writes the metrics, the reward and the observation, each from the
rules of :mod:`active_loc.beliefs.grid`, :mod:`active_loc.sensors.depth`,
:mod:`active_loc.motion` and :mod:`active_loc.envs.rewards`. A member's arithmetic does not
depend on B, so member b of a batch equals a single env step for step.
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from active_loc.beliefs.grid import (
    GridBelief,
    MotionKernel,
    predict_member,
    stats_member,
    uniform_kernel,
    update_member,
)
from active_loc.envs.outcome import StepOutcome
from active_loc.envs.rewards import REWARD_CODES, step_reward, uncertainty_reward
from active_loc.maps.maze import HEADING_STEPS, maze_to_grid
from active_loc.maps.occupancy import OccupancyGrid
from active_loc.motion import move_on_cells
from active_loc.sensors.depth import DepthSensor, depth_table_kernel, reading_likelihood

N_HEADINGS = 4
TURN_LEFT, TURN_RIGHT, MOVE_FORWARD = 0, 1, 2
#: per action: the commanded shift ``(H, 2)`` (cells) of every heading and the turn (bins)
SHIFTS = np.zeros((3, N_HEADINGS, 2), dtype=np.int64)
SHIFTS[MOVE_FORWARD] = HEADING_STEPS
TURNS = np.array([1, -1, 0], dtype=np.int64)
SHIFTS.setflags(write=False)
TURNS.setflags(write=False)
_NO_NOISE = MotionKernel.deterministic()
#: the belief counts as localized when its largest probability is at least this (the exact
#: filter gives exactly 1.0; the margin only absorbs rounding)
LOCALIZED_PROB = 1.0 - 1e-9
#: the kernel's code of the paper's reward, the belief's largest probability (the other
#: maze rewards use :data:`~active_loc.envs.rewards.REWARD_CODES`)
MAX_PROB_REWARD = -1

#: one member's state, by field: the true pose, the belief's mode, counters, this step's
#: reading and metrics, its reward and whether it ended the episode
MAZE_STATE = np.dtype([
    ("x", np.int64), ("y", np.int64), ("heading", np.int64),
    ("mode_x", np.int64), ("mode_y", np.int64), ("mode_heading", np.int64),
    ("steps", np.int64), ("collisions", np.int64), ("depth", np.int64),
    ("entropy", np.float64), ("max_prob", np.float64), ("pose_error", np.float64),
    ("heading_error", np.float64), ("uncertainty", np.float64), ("reward", np.float64),
    ("collided", np.bool_), ("localized", np.bool_), ("success", np.bool_),
    ("terminated", np.bool_), ("truncated", np.bool_),
], align=True)  # fmt: skip


def reward_code(reward: str) -> int:
    """The kernel's code of a maze reward name (``info_gain``, ``neg_entropy``, ``max_prob``)."""
    return MAX_PROB_REWARD if reward == "max_prob" else REWARD_CODES[reward]


@numba.njit(cache=True, nogil=True)
def maze_move(
    free: NDArray, x: int, y: int, h: int, shift: NDArray, turn: int
) -> tuple[int, int, int, bool]:
    """The maze's motion on a free mask ``(X, Y)``: the commanded ``shift`` of heading ``h``
    (``(H, 2)`` cells per heading; blocked by a wall, staying in place) then the ``turn``
    (bins). Returns the new pose and whether a commanded move was blocked."""
    dx = shift[h, 0]
    dy = shift[h, 1]
    blocked = False
    if dx != 0 or dy != 0:
        x, y, blocked = move_on_cells(free, x, y, dx, dy)
    return x, y, (h + turn) % N_HEADINGS, blocked


@numba.njit(cache=True, nogil=True)
def _observe(
    state: NDArray, b: int, prob: NDArray, free: NDArray, evidence: NDArray, tables: NDArray,
    likelihood: NDArray, log_cell_volume: float, image: NDArray, extra: NDArray,
    episode_length: int,
) -> None:
    """Member ``b`` reads its depth and corrects its belief; its metrics and observation."""
    s = state[b]
    z = tables[b, s.x, s.y, s.heading]
    s.depth = z
    reading_likelihood(tables[b], z, likelihood[b])
    # the true pose reads z, so the likelihood's largest value is 1
    evidence[b] = update_member(prob, likelihood, 1.0, free, b)
    mode = np.empty(3, dtype=np.int64)
    s.entropy, s.max_prob = stats_member(prob, b, log_cell_volume, mode)
    s.mode_x, s.mode_y, s.mode_heading = mode[0], mode[1], mode[2]
    dx = mode[0] - s.x
    dy = mode[1] - s.y
    s.pose_error = math.sqrt(dx * dx + dy * dy)
    dh = (mode[2] - s.heading) % N_HEADINGS
    s.heading_error = min(dh, N_HEADINGS - dh) * (math.pi / 2)
    s.localized = s.max_prob >= LOCALIZED_PROB
    s.success = s.localized and dx == 0 and dy == 0 and dh == 0
    _, nx, ny, nh = prob.shape
    for x in range(nx):
        for y in range(ny):
            for h in range(nh):
                image[b, h, x, y] = prob[b, x, y, h]
            image[b, nh, x, y] = 0.0 if free[b, x, y] else 1.0
    extra[b, 0] = min(z / (nx - 2), 1.0)
    extra[b, 1] = min(s.steps / episode_length, 1.0)


@numba.njit(cache=True, nogil=True)
def maze_reset_kernel(
    state: NDArray, b: int, x: int, y: int, h: int, prob: NDArray, free: NDArray,
    evidence: NDArray, tables: NDArray, likelihood: NDArray, log_cell_volume: float,
    image: NDArray, extra: NDArray, episode_length: int,
) -> None:
    """Start member ``b``'s episode on its maze ``free[b]`` at pose ``(x, y, h)``: its depth
    table, a uniform belief corrected by the first reading, zero counters and reward."""
    depth_table_kernel(free[b], tables[b])
    uniform_kernel(prob, free, b)
    s = state[b]
    s.x, s.y, s.heading = x, y, h
    s.steps = 0
    s.collisions = 0
    s.collided = False
    s.uncertainty = 0.0
    s.reward = 0.0
    s.terminated = False
    s.truncated = False
    _observe(state, b, prob, free, evidence, tables, likelihood, log_cell_volume, image, extra,
             episode_length)


@numba.njit(cache=True, nogil=True)
def maze_step_kernel(
    state: NDArray, actions: NDArray, active: NDArray, prob: NDArray, scratch: NDArray,
    free: NDArray, evidence: NDArray, tables: NDArray, likelihood: NDArray,
    log_cell_volume: float, offsets: NDArray, weights: NDArray, code: int, terminate: bool,
    image: NDArray, extra: NDArray, episode_length: int, collision_penalty: float,
) -> None:
    """One step of every active member with its action (checked by the caller; inactive
    members are left as they are)."""
    for b in range(state.shape[0]):
        if not active[b]:
            continue
        s = state[b]
        a = actions[b]
        previous = s.entropy
        s.x, s.y, s.heading, s.collided = maze_move(free[b], s.x, s.y, s.heading, SHIFTS[a],
                                                    TURNS[a])
        s.steps += 1
        s.collisions += s.collided
        predict_member(prob, free, b, SHIFTS[a], TURNS[a], offsets, weights, scratch)
        prob[b] = scratch[b]
        _observe(state, b, prob, free, evidence, tables, likelihood, log_cell_volume, image,
                 extra, episode_length)
        if code == MAX_PROB_REWARD:
            s.uncertainty = s.max_prob
        else:
            s.uncertainty = uncertainty_reward(code, previous, s.entropy, 0.0, 0.0, 0.0, 0.0)
        # the maze has no step cost or outcome term
        s.reward = step_reward(s.uncertainty, s.collided, 0.0, collision_penalty, 0.0)
        s.terminated = terminate and s.localized
        s.truncated = not s.terminated and s.steps >= episode_length


class MazeCore:
    """B maze episodes (the members) stepped together.

    Args:
        size: the maze side n (cells).
        batch_size: B >= 1.
        flat: observations are vectors ``(5 n^2 + 2,)`` (else images ``(5, n, n)``).
        reward: ``"info_gain"``, ``"neg_entropy"`` or ``"max_prob"``.
        terminate_when_localized: a member's episode terminates when its belief max is 1.
        episode_length: L, steps per episode (truncation).
        collision_penalty: subtracted from the reward of a forward move into a wall (>= 0).

    Attributes:
        state: ``(B,)`` :data:`MAZE_STATE` records; ``state["entropy"]`` is every member's
            entropy, ``state[b]`` member b's fields.
        belief: the B beliefs (``prob`` ``(B, n, n, 4)``).
        obs: ``(B, 5, n, n)`` or ``(B, 5 n^2 + 2)`` float32, the members' observations.
        walls: member b's maze, ``(n, n)`` bool read-only, True = wall, ``walls[b][iy, ix]``.
    """

    def __init__(
        self, size: int, batch_size: int, *, flat: bool, reward: str,
        terminate_when_localized: bool, episode_length: int, collision_penalty: float = 0.0,
    ) -> None:
        n, nb = int(size), int(batch_size)
        self.size = n
        self.batch_size = nb
        self.episode_length = int(episode_length)
        self.state = np.zeros(nb, dtype=MAZE_STATE)
        # every member's map is replaced at its first reset
        self.belief = GridBelief(np.ones((nb, n, n), dtype=bool), N_HEADINGS, 1.0)
        self.tables = np.zeros((nb, n, n, N_HEADINGS), dtype=np.int64)
        self._likelihood = np.zeros((nb, n, n, N_HEADINGS))
        cells = 5 * n * n
        if flat:
            self.obs = np.zeros((nb, cells + 2), dtype=np.float32)
            self._image = self.obs[:, :cells].reshape(nb, 5, n, n)
            self._extra = self.obs[:, cells:]
        else:
            self.obs = np.zeros((nb, 5, n, n), dtype=np.float32)
            self._image = self.obs
            self._extra = np.zeros((nb, 2), dtype=np.float32)  # not observed
        self._code = reward_code(reward)
        self._terminate = bool(terminate_when_localized)
        self._collision_penalty = float(collision_penalty)
        self.walls: list[NDArray[np.bool_]] = [np.ones((n, n), dtype=bool)] * nb
        self._sensors: list[DepthSensor | None] = [None] * nb
        self._grids: list[OccupancyGrid | None] = [None] * nb
        self._one_action = np.zeros(nb, dtype=np.int64)
        self._one_active = np.zeros(nb, dtype=np.bool_)

    def reset_member(self, b: int, walls: NDArray[np.bool_], start: NDArray[np.int64]) -> None:
        """New episode of member ``b`` in the maze ``walls`` ``(n, n)`` (``[iy, ix]``) from
        the pose ``start`` ``(ix, iy, h)``."""
        walls = np.array(walls, dtype=bool)
        walls.setflags(write=False)
        self.walls[b] = walls
        self._sensors[b] = None
        self._grids[b] = None
        self.belief.set_member_free(b, ~walls.T)
        prob, _, free, evidence = self.belief.state_arrays()
        maze_reset_kernel(self.state, b, int(start[0]), int(start[1]), int(start[2]), prob, free,
                          evidence, self.tables, self._likelihood, self.belief.log_cell_volume,
                          self._image, self._extra, self.episode_length)

    def step(self, actions: NDArray[np.int64], active: NDArray[np.bool_]) -> None:
        """Step the ``active`` ``(B,)`` members with their ``actions`` ``(B,)`` int64 (each
        in [0, 3), checked by the caller); the others are left as they are."""
        prob, scratch, free, evidence = self.belief.state_arrays()
        maze_step_kernel(self.state, actions, active, prob, scratch, free, evidence, self.tables,
                         self._likelihood, self.belief.log_cell_volume, _NO_NOISE.offsets,
                         _NO_NOISE.weights, self._code, self._terminate, self._image,
                         self._extra, self.episode_length, self._collision_penalty)

    def step_member(self, b: int, action: int) -> None:
        """Step member ``b`` alone with ``action`` (in [0, 3), checked by the caller)."""
        self._one_action[b] = action
        self._one_active[b] = True
        try:
            self.step(self._one_action, self._one_active)
        finally:
            self._one_active[b] = False

    def outcome(self, b: int) -> StepOutcome:
        """Member ``b``'s last step (or reset) by name."""
        s = self.state[b]
        localized = bool(s["localized"])
        return StepOutcome(
            float(s["pose_error"]), float(s["heading_error"]), float(s["entropy"]),
            float(s["uncertainty"]), bool(s["collided"]), 0.0, localized, bool(s["success"]),
            localized, False, 0, math.nan,
        )

    def pose(self, b: int) -> tuple[int, int, int]:
        """Member ``b``'s true pose ``(ix, iy, h)``."""
        s = self.state[b]
        return int(s["x"]), int(s["y"]), int(s["heading"])

    def set_pose(self, b: int, pose: tuple[int, int, int]) -> None:
        """Put member ``b``'s robot at ``pose`` ``(ix, iy, h)`` (a free cell; the belief is
        left as it is)."""
        s = self.state[b]
        s["x"], s["y"], s["heading"] = (int(v) for v in pose)

    def sensor(self, b: int) -> DepthSensor:
        """The depth sensor of member ``b``'s maze (built on first use each episode)."""
        sensor = self._sensors[b]
        if sensor is None:
            sensor = DepthSensor.from_free(np.ascontiguousarray(~self.walls[b].T))
            self._sensors[b] = sensor
        return sensor

    def grid(self, b: int) -> OccupancyGrid:
        """Member ``b``'s maze as an occupancy grid (built on first use each episode)."""
        grid = self._grids[b]
        if grid is None:
            grid = maze_to_grid(self.walls[b])
            self._grids[b] = grid
        return grid

    def member_belief(self, b: int) -> GridBelief:
        """Member ``b``'s belief: the core's own when B = 1, else a copy of the member."""
        return self.belief if self.batch_size == 1 else self.belief.member(b)

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        del state["_image"], state["_extra"]  # views of obs: rebuilt on unpickling
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        n, nb = self.size, self.batch_size
        if self.obs.ndim == 2:
            self._image = self.obs[:, : 5 * n * n].reshape(nb, 5, n, n)
            self._extra = self.obs[:, 5 * n * n :]
        else:
            self._image = self.obs
            self._extra = np.zeros((nb, 2), dtype=np.float32)
