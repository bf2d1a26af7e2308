"""``MazeEnv``: ``ActiveLoc/Maze-v0``, the 2-D maze benchmark of Active Neural Localization
(Chaplot, Parisotto, Salakhutdinov, ICLR 2018), with the exact Markov filter of
:mod:`active_loc.beliefs.grid`."""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from active_loc.beliefs.grid import GridBelief
from active_loc.envs.actions import check_action
from active_loc.envs.field_checks import check_positive
from active_loc.envs.maze_core import (
    LOCALIZED_PROB,
    MOVE_FORWARD,
    N_HEADINGS,
    SHIFTS,
    TURN_LEFT,
    TURN_RIGHT,
    TURNS,
    MazeCore,
    maze_move,
)
from active_loc.envs.outcome import RewardSettings, step_info, typed_info
from active_loc.maps.maze import (
    TEST_SET_SEED,
    MazeSet,
    load_maze_set,
    max_test_set_count,
    maze_test_set,
    random_maze,
    random_start,
)
from active_loc.maps.occupancy import OccupancyGrid
from active_loc.sensors.depth import DepthSensor

__all__ = ["LOCALIZED_PROB", "MOVE_FORWARD", "TURN_LEFT", "TURN_RIGHT", "MazeConfig", "MazeEnv",
           "MazeMotion", "MazePlannerView", "render_maze"]

ACTION_NAMES = ("turn_left", "turn_right", "move_forward")
SIZES = (7, 15, 21)
#: the paper's episode lengths per maze size; the first is the default
PAPER_EPISODE_LENGTHS = {7: (15, 30), 15: (20, 40), 21: (30, 60)}
OBSERVATIONS = ("belief", "flat")
REWARDS = ("info_gain", "neg_entropy", "max_prob")
@dataclass(frozen=True)
class MazeConfig:
    """Configuration of ``ActiveLoc/Maze-v0`` (the keyword arguments of :class:`MazeEnv`)."""

    size: int = 7  # maze side n (cells, 1 m each): 7, 15 or 21
    # steps per episode L; None: the paper's shorter length (15, 20, 30 for n = 7, 15, 21)
    episode_length: int | None = None
    observation: str = "belief"  # "belief": (5, n, n) image; "flat": a vector (see MazeEnv)
    reward: str = "info_gain"  # "info_gain" (nats), "neg_entropy", "max_prob" (the paper's)
    # replay: an entry of the test set (every reset), or None
    maze_index: int | None = None
    # replay: a MazeSet; the path of a maze file (.npy in the paper's test-data layout, or
    # MazeSet.save's .npz), read here by load_maze_set, the field then holding the MazeSet; or
    # an int count = the first `count` entries of the standard set maze_test_set(size, count,
    # TEST_SET_SEED). None with maze_index=None: random mazes
    test_set: MazeSet | int | str | os.PathLike[str] | None = None
    terminate_when_localized: bool = False  # end the episode as soon as the belief max is 1
    # subtracted from the reward of a forward move into a wall (0: the paper's reward)
    collision_penalty: float = 0.0
    action_type: str = "discrete"  # the only one: the maze has 3 discrete actions
    belief: str = "grid"  # the only one: the exact Markov filter

    def __post_init__(self) -> None:
        if not _is_int(self.size) or self.size not in SIZES:
            raise ValueError(f"size must be one of {SIZES}, got {self.size!r}")
        length = self.episode_length
        if length is None:
            object.__setattr__(self, "episode_length", PAPER_EPISODE_LENGTHS[self.size][0])
        elif not _is_int(length) or length < 1:
            raise ValueError(f"episode_length must be an integer >= 1, got {length!r}")
        else:
            object.__setattr__(self, "episode_length", int(length))
        if self.observation not in OBSERVATIONS:
            raise ValueError(f"observation must be one of {OBSERVATIONS}, got {self.observation!r}")
        if self.reward not in REWARDS:
            raise ValueError(f"reward must be one of {REWARDS}, got {self.reward!r}")
        if self.action_type != "discrete":
            raise ValueError(
                f"action_type must be 'discrete' for Maze-v0 (turn left, turn right, move "
                f"forward), got {self.action_type!r}"
            )
        if self.belief != "grid":
            raise ValueError(
                f"belief must be 'grid' for Maze-v0 (the exact Markov filter), got "
                f"{self.belief!r}"
            )
        check_positive("collision_penalty", self.collision_penalty, allow_zero=True)
        if not isinstance(self.terminate_when_localized, (bool, np.bool_)):
            raise ValueError(
                f"terminate_when_localized must be a bool, got {self.terminate_when_localized!r}"
            )
        test_set = self.test_set
        if isinstance(test_set, (str, os.PathLike)):
            try:
                test_set = load_maze_set(test_set)
            except ValueError as error:
                raise type(error)(f"test_set: {error}") from None
            object.__setattr__(self, "test_set", test_set)
        most = max_test_set_count(self.size)
        if test_set is not None and not isinstance(test_set, MazeSet):
            if not _is_int(test_set) or not 1 <= test_set <= most:
                raise ValueError(
                    f"test_set must be a MazeSet, the path of a maze file (.npy or .npz), an "
                    f"integer count in [1, {most}] (of the standard {self.size} x {self.size} "
                    f"set) or None, got {test_set!r}"
                )
        if isinstance(test_set, MazeSet) and test_set.size != self.size:
            # the observation space is sized by `size`, so the mazes must fit it
            origin = "" if test_set.source is None else f" {test_set.source}"
            hint = f"; pass size={test_set.size}" if test_set.size in SIZES else ""
            raise ValueError(
                f"test_set{origin} holds {test_set.size} x {test_set.size} mazes but "
                f"size={self.size}{hint}"
            )
        index = self.maze_index
        if index is not None:
            if not _is_int(index) or index < 0:
                raise ValueError(f"maze_index must be an integer >= 0 or None, got {index!r}")
            count = _set_length(test_set)
            if index >= (most if count is None else count):
                raise ValueError(f"maze_index must be in [0, {most if count is None else count}),"
                                 f" got {index}")


def _is_int(value: Any) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def _set_length(test_set: MazeSet | int | None) -> int | None:
    if test_set is None:
        return None
    return len(test_set) if isinstance(test_set, MazeSet) else int(test_set)


@dataclass(frozen=True)
class MazeMotion:
    """The maze's actions as grid motions: turn left (+1 heading bin), turn right (-1), move
    forward one cell (blocked by a wall: no move). Deterministic."""

    def command(self, action: int) -> tuple[NDArray[np.int64], int]:
        """The per-heading shift ``(4, 2)`` (cells) and the turn (bins) of ``action``."""
        a = _action_index(action)
        return SHIFTS[a], int(TURNS[a])

    def predict(self, belief: GridBelief, action: int) -> None:
        """Prediction step of ``belief`` (any batch size) for ``action``, in place."""
        a = _action_index(action)
        b = belief.batch_size
        shift = np.ascontiguousarray(np.broadcast_to(SHIFTS[a], (b, N_HEADINGS, 2)))
        turn = np.full(b, TURNS[a], dtype=np.int64)
        belief.predict(shift, turn)

    def move(
        self, free: NDArray[np.bool_], pose: tuple[int, int, int], action: int
    ) -> tuple[tuple[int, int, int], bool]:
        """The next pose ``(ix, iy, h)`` on the free mask ``(X, Y)`` and whether a forward move
        was blocked."""
        a = _action_index(action)
        x, y, h, blocked = maze_move(free, pose[0], pose[1], pose[2], SHIFTS[a], int(TURNS[a]))
        return (int(x), int(y), int(h)), bool(blocked)


_ACTION_SPACE = gym.spaces.Discrete(3)


def _action_index(action: Any) -> int:
    """The index in [0, 3) of a maze action (turn left, turn right, move forward), checked by
    :func:`~active_loc.envs.actions.check_action`."""
    return check_action(action, _ACTION_SPACE, "action (turn left 0, turn right 1, forward 2)")


@dataclass(frozen=True)
class MazePlannerView:
    """What a planner may use in the maze: never the true pose.

    Attributes:
        belief: a copy of the env's belief (B = 1); planners may change it freely.
        map: the maze as an occupancy grid (1 m cells).
        walls: ``(n, n)`` bool, True = wall, ``walls[iy, ix]`` (read-only).
        motion: the action model.
        sensor: the depth sensor of this maze (every pose's reading precomputed).
        action_space: ``Discrete(3)``.
        step: steps taken so far; episode_length: L.
        depth: the reading of the last step or reset (a scalar int, cells): the cells from the
            robot's own cell (counted as 1) to the first wall straight ahead, 1 to n - 2, as
            ``info["depth"]`` and ``sensor.table`` at the true pose give it. What the robot
            sensed, which the belief already holds; the pose it was read from stays hidden.
    """

    belief: GridBelief
    map: OccupancyGrid
    walls: NDArray[np.bool_]
    motion: MazeMotion
    sensor: DepthSensor
    action_space: gym.spaces.Space
    step: int
    episode_length: int
    depth: int

    def simulate(
        self, action: int, belief: GridBelief, rng: np.random.Generator
    ) -> tuple[GridBelief, NDArray[np.int64]]:
        """One hypothetical step from ``belief``: predict, draw a pose from the predicted
        belief with ``rng`` (one uniform per member), read its depth and update.

        Returns:
            The updated copy of the belief and the hypothetical readings ``(B,)``.
        """
        out = belief.copy()
        self.motion.predict(out, action)
        flat = out.prob.reshape(out.batch_size, -1)
        u = rng.random(out.batch_size)
        table = self.sensor.table.reshape(-1)
        z = np.empty(out.batch_size, dtype=np.int64)
        lik = np.empty(out.shape)
        for b in range(out.batch_size):
            cumulative = np.cumsum(flat[b])
            pick = int(np.searchsorted(cumulative, u[b] * cumulative[-1], side="right"))
            z[b] = table[min(pick, flat.shape[1] - 1)]
            lik[b] = self.sensor.likelihood(int(z[b]))
        out.update(lik)
        return out, z

    def outcomes(self, action: int, belief: GridBelief) -> list[tuple[int, float, GridBelief]]:
        """Every possible reading after ``action`` from ``belief`` (B = 1): ``(z, p(z),
        posterior)`` for each depth z of positive probability, most likely first (ties by
        depth)."""
        if belief.batch_size != 1:
            raise ValueError(f"outcomes needs a belief of batch size 1, got {belief.batch_size}")
        predicted = belief.copy()
        self.motion.predict(predicted, action)
        mass = np.bincount(
            self.sensor.table.reshape(-1), weights=predicted.prob.reshape(-1),
            minlength=self.sensor.max_depth + 1,
        )
        result = []
        for z in np.argsort(-mass[1:], kind="stable") + 1:
            if mass[z] <= 0.0:
                continue
            posterior = predicted.copy()
            posterior.update(self.sensor.likelihood(int(z)))
            result.append((int(z), float(mass[z]), posterior))
        return result


class MazeEnv(gym.Env):
    """Active localization in a 2-D maze: ``ActiveLoc/Maze-v0``.

    ## Description

    The protocol of the 2-D experiments of *Active Neural Localization* (Chaplot, Parisotto,
    Salakhutdinov, ICLR 2018), so results compare with the paper's. An ``n x n`` maze of wall
    and free cells (one cell = 1 m) with a wall border is carved by Eller's algorithm
    (:mod:`active_loc.maps.maze`). The robot occupies a free cell and faces one of 4 headings
    (0 east, 1 north, 2 west, 3 south). It knows the maze but not its pose; the env keeps the
    exact Markov belief over cells x headings (:class:`~active_loc.beliefs.grid.GridBelief`,
    Algorithm 1), uniform over the free poses at reset and then updated with the first depth
    reading, and after every action predicted with the action and corrected with the new depth.

    ## Action Space

    ``Discrete(3)``, deterministic:

    | action | name           | effect                                                  |
    |--------|----------------|---------------------------------------------------------|
    | 0      | turn left      | heading + 1 (counterclockwise, 90 degrees)              |
    | 1      | turn right     | heading - 1                                             |
    | 2      | move forward   | one cell ahead; into a wall: no move (a collision)      |

    ``action_type="discrete"`` is accepted for uniformity with the other ids; ``"continuous"``
    raises ``ValueError``.

    ## Observation Space

    After every action and at reset the robot reads its **depth**: the number of cells from its
    own cell (counted as 1) to the first wall straight ahead (:mod:`active_loc.sensors.depth`).
    The agent observes the belief, not the depth itself:

    | ``observation`` | space                                   | content                     |
    |-----------------|-----------------------------------------|-----------------------------|
    | ``"belief"``    | ``Box(0, 1, (5, n, n), float32)``       | image for CNN policies      |
    | ``"flat"``      | ``Box(0, 1, (5 n^2 + 2,), float32)``    | vector for MLP policies     |

    The image's channels ``c = 0..3`` are the belief of heading ``c``, ``obs[c, ix, iy] =
    P(cell (ix, iy), heading c)``, and channel 4 is the map (1.0 on walls, 0.0 on free cells),
    as the paper's policy input. ``"flat"`` is that image raveled, then the last depth / (n - 2)
    and the fraction of the episode elapsed, steps / L. Probabilities are kept as float32, not
    quantized, so small probabilities survive.

    Coordinates. Cell ``(ix, iy)`` is column ``ix`` (x, east) and row ``iy`` (y, north) of the
    maze, ``iy = 0`` at the *bottom* (the map frame's x right, y up; the cell spans ``[ix, ix +
    1) x [iy, iy + 1)`` m of :attr:`grid`). :attr:`walls` is indexed ``walls[iy, ix]`` (as
    :class:`~active_loc.maps.occupancy.OccupancyGrid` values), the belief ``prob[ix, iy, h]``
    and the image ``obs[c, ix, iy]``: x first, so ``obs[4] == walls.T`` and ``obs[c] ==
    prob[..., c]``. Headings ``h``: 0 east (+x), 1 north (+y), 2 west, 3 south. The paper's
    state ``S[c, r, col]`` has row ``r = 0`` at the *top* and the same heading codes (its
    north is toward row 0), so ``S = np.rot90(obs, axes=(1, 2))`` (``S[c] == obs[c].T[::-1]``)
    and ``walls == M[::-1]`` for its map ``M``; the RGB frames are drawn north up.

    ## Rewards

    ``reward="info_gain"`` (default): ``H(b_{t-1}) - H(b_t)`` (nats), the drop in the belief's
    entropy; summed over an episode it telescopes to ``H_0 - H_L`` with ``H_0`` the entropy
    after the first reading. ``"neg_entropy"``: ``-H(b_t)``. ``"max_prob"``: the belief's
    largest probability after the step (the paper's reward). ``info["reward_terms"]`` names the
    term (plus ``step_cost`` and ``collision``, both 0 here). Entropy is the histogram entropy
    plus ``log(1 m * 1 m * pi / 2)``, as for every belief of the package.

    ## Starting State

    Without a test set: a new Eller maze every reset (mazes equal to their own 90- or
    180-degree rotation are redrawn), a free cell and a heading drawn uniformly, all from
    ``self.np_random``. With ``test_set`` (a :class:`~active_loc.maps.maze.MazeSet`, e.g.
    ``maze_test_set(n, 1000, seed)``; the path of a maze file, read at construction by
    :func:`~active_loc.maps.maze.load_maze_set`: a ``.npy`` in the layout of the paper's
    released test data, such as its ``test_data/m7_n1000.npy``, or a ``.npz`` of
    :meth:`MazeSet.save <active_loc.maps.maze.MazeSet.save>`; or a count of the standard set
    ``maze_test_set(size, count, TEST_SET_SEED)``): successive resets replay entries 0, 1, 2,
    ... (cycling); ``maze_index=k`` replays entry ``k`` at every reset (of the standard set
    when no test set is given), and ``reset(options={"maze_index": k})`` picks one for that
    episode. :attr:`maze_index` names the entry of the current episode. A test set's mazes
    must be ``size x size`` (the observation space is sized by ``size``); another size is
    refused, naming the file. An entry of the paper's file is the episode the paper's
    ``Maze2D`` plays with it: map row ``r`` is ``iy = n - 1 - r``, column ``col`` is ``ix``,
    and the orientation is the heading.

    ## Episode End

    Truncated after exactly ``episode_length`` steps (L; default the paper's shorter L: 15, 20,
    30 for n = 7, 15, 21; the paper also used 30, 40, 60). The env counts the steps itself, so
    the id is registered without a ``TimeLimit``. With ``terminate_when_localized=True`` the
    episode terminates as soon as the belief's maximum is 1.

    ## Info

    Every step and at reset: ``pose_error`` (m, from the belief's most probable cell to the
    true cell), ``heading_error`` (rad, 0, pi/2 or pi), ``entropy`` (nats), ``localized``
    (belief max is 1), ``is_success`` (belief max is 1 *at the true pose*; the paper's success
    is its value at the end of the episode), ``collisions`` (blocked forward moves so far),
    ``reward_terms``, ``depth`` (this step's reading, cells), ``max_prob``.

    ## Arguments

    ``gymnasium.make("ActiveLoc/Maze-v0", size=7, episode_length=None, observation="belief",
    reward="info_gain", maze_index=None, test_set=None, terminate_when_localized=False,
    collision_penalty=0.0, render_mode=None)``: the fields of :class:`MazeConfig`.
    ``render_mode="rgb_array"`` draws the maze, the belief as a heat map (max over headings),
    its most probable cell (blue frame) and the true pose (green triangle);
    ``render_mode="human"`` shows that frame in a pyplot window after every reset and step
    (matplotlib; on a non-interactive backend such as Agg it only draws).
    """

    metadata: dict[str, Any] = {"render_modes": ["human", "rgb_array"], "render_fps": 4}  # noqa: RUF012

    def __init__(
        self,
        size: int = 7,
        episode_length: int | None = None,
        observation: str = "belief",
        maze_index: int | None = None,
        test_set: MazeSet | int | str | os.PathLike[str] | None = None,
        terminate_when_localized: bool = False,
        render_mode: str | None = None,
        reward: str = "info_gain",
        action_type: str = "discrete",
        belief: str = "grid",
        collision_penalty: float = 0.0,
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode={render_mode!r} is not one of {self.metadata['render_modes']}"
            )
        self.config = MazeConfig(
            size=size, episode_length=episode_length, observation=observation, reward=reward,
            maze_index=maze_index, test_set=test_set,
            terminate_when_localized=terminate_when_localized, action_type=action_type,
            belief=belief, collision_penalty=collision_penalty,
        )  # fmt: skip
        self.render_mode = render_mode
        self.size: int = self.config.size
        self.episode_length: int = int(self.config.episode_length)  # type: ignore[arg-type]
        n = self.size
        self.action_space = gym.spaces.Discrete(3)
        self._flat = self.config.observation == "flat"
        shape = (5 * n * n + 2,) if self._flat else (5, n, n)
        self.observation_space = gym.spaces.Box(0.0, 1.0, shape, dtype=np.float32)
        self._reward_name = self.config.reward
        # the maze has no step cost or outcome term
        self.reward_settings = RewardSettings(
            self._reward_name, 0.0, float(self.config.collision_penalty), has_outcome=False
        )
        self._terminate_when_localized = bool(self.config.terminate_when_localized)
        test_set = self.config.test_set
        if isinstance(test_set, MazeSet):
            self.test_set: MazeSet | None = test_set
        elif test_set is not None:
            self.test_set = maze_test_set(n, int(test_set), TEST_SET_SEED)
        elif self.config.maze_index is not None:
            self.test_set = maze_test_set(n, self.config.maze_index + 1, TEST_SET_SEED)
        else:
            self.test_set = None
        self.motion = MazeMotion()
        self._window: Any = None  # the ImageWindow of render_mode="human", opened on first use
        self._next_index = 0
        self._maze_index: int | None = None
        self._has_reset = False
        self.attach(self.new_core(1), 0)

    def new_core(self, batch_size: int) -> MazeCore:
        """A :class:`MazeCore` of ``batch_size`` members with this env's settings."""
        return MazeCore(
            self.size, batch_size, flat=self._flat, reward=self._reward_name,
            terminate_when_localized=self._terminate_when_localized,
            episode_length=self.episode_length,
            collision_penalty=self.reward_settings.collision_penalty,
        )  # fmt: skip

    def attach(self, core: MazeCore, member: int) -> None:
        """Run this env's episodes as member ``member`` of ``core`` (the native vector env
        steps all its sub-envs in one core; this env still picks their mazes and starts)."""
        self._core = core
        self._member = member
        self._has_reset = False

    # -- gymnasium API ------------------------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        super().reset(seed=seed)
        walls, start, index = self._episode_maze(options)
        self._core.reset_member(self._member, walls, start)
        self._maze_index = index
        self._has_reset = True
        if self.render_mode == "human":
            self.render()
        return self._observation(), self.last_info()

    def step(
        self, action: Any
    ) -> tuple[NDArray[np.float32], float, bool, bool, dict[str, Any]]:
        if not self._has_reset:
            raise RuntimeError("call reset() before step()")
        b = self._member
        self._core.step_member(b, _action_index(action))
        s = self._core.state[b]
        if self.render_mode == "human":
            self.render()
        return (self._observation(), float(s["reward"]), bool(s["terminated"]),
                bool(s["truncated"]), self.last_info())

    def render(self) -> NDArray[np.uint8] | None:
        """``rgb_array``: the frame of :func:`render_maze`; ``human``: the same frame shown in
        a pyplot window (called by ``reset`` and ``step``), returning None."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode= to make()")
            return None
        if not self._has_reset:
            raise RuntimeError("call reset() before render()")
        b = self._member
        frame = render_maze(self.walls, self._core.belief.prob[b], self._core.pose(b))
        if self.render_mode == "rgb_array":
            return frame
        if self._window is None:
            from active_loc.envs.rendering import ImageWindow

            self._window = ImageWindow("ActiveLoc/Maze-v0")
        self._window.show(frame)
        return None

    def close(self) -> None:
        if self._window is not None:
            self._window.close()
            self._window = None

    # -- planners -----------------------------------------------------------------------------

    def planner_view(self) -> MazePlannerView:
        """A copy of the belief, the maze, the motion and sensor models and the action set;
        never the true pose."""
        if not self._has_reset:
            raise RuntimeError("call reset() before planner_view()")
        b = self._member
        return MazePlannerView(
            belief=self._core.belief.member(b),
            map=self.grid,
            walls=self.walls,
            motion=self.motion,
            sensor=self._core.sensor(b),
            action_space=self.action_space,
            step=int(self._core.state[b]["steps"]),
            episode_length=self.episode_length,
            depth=int(self._core.state[b]["depth"]),
        )

    @property
    def belief(self) -> GridBelief:
        """The exact Markov belief (B = 1; the env's own, or with a shared core a copy)."""
        return self._core.member_belief(self._member)

    @property
    def true_pose(self) -> tuple[int, int, int]:
        """The robot's pose ``(ix, iy, h)``: for evaluation and rendering only; it is never
        part of an observation or of the planner view."""
        return self._core.pose(self._member)

    @property
    def grid(self) -> OccupancyGrid:
        """The current maze as an occupancy grid (1 m cells, origin (0, 0, 0))."""
        return self._core.grid(self._member)

    @property
    def walls(self) -> NDArray[np.bool_]:
        """``(n, n)`` bool, True = wall, ``walls[iy, ix]``: the current maze (read-only)."""
        return self._core.walls[self._member]

    @property
    def maze_index(self) -> int | None:
        """The test-set entry of the current episode (None for a random maze)."""
        return self._maze_index

    def last_info(self) -> dict[str, Any]:
        """The info dict of the last step or reset."""
        b = self._member
        info = step_info(self._core.outcome(b), int(self._core.state[b]["collisions"]),
                         self.reward_settings)
        info["depth"] = int(self._core.state[b]["depth"])
        info["max_prob"] = float(self._core.state[b]["max_prob"])
        return typed_info(info)

    # -- helpers ------------------------------------------------------------------------------

    def _episode_maze(
        self, options: dict[str, Any] | None
    ) -> tuple[NDArray[np.bool_], NDArray[np.int64], int | None]:
        """The maze, start pose and test-set index of a new episode."""
        index = None if options is None else options.get("maze_index")
        if index is not None:
            # a given set bounds the index by its length, the standard set by what it can hold
            if self.config.test_set is not None:
                assert self.test_set is not None
                most, what = len(self.test_set), " (the test set's length)"
            else:
                most, what = max_test_set_count(self.size), ""
            if not _is_int(index) or not 0 <= index < most:
                raise ValueError(
                    f"options['maze_index'] must be an integer in [0, {most}){what}, got "
                    f"{index!r}"
                )
            if self.test_set is None or index >= len(self.test_set):
                self.test_set = maze_test_set(self.size, int(index) + 1, TEST_SET_SEED)
            index = int(index)
            self._next_index = index + 1
        elif self.config.maze_index is not None:
            index = self.config.maze_index
        elif self.test_set is not None:
            index = self._next_index % len(self.test_set)
            self._next_index = index + 1
        if index is None:
            walls = random_maze(self.size, self.np_random)
            return walls, random_start(walls, self.np_random), None
        walls, start = self.test_set[index]  # type: ignore[index]
        return walls, start, index

    def _observation(self) -> NDArray[np.float32]:
        return self._core.obs[self._member].copy()


# --- drawing (numpy only) ----------------------------------------------------------------------

_WALL_RGB = np.array([45, 45, 52], dtype=np.float64)
_FREE_RGB = np.array([255, 255, 255], dtype=np.float64)
_HEAT_RGB = np.array([214, 39, 40], dtype=np.float64)
_TRUE_RGB = np.array([44, 160, 44], dtype=np.uint8)
_MODE_RGB = np.array([31, 119, 180], dtype=np.uint8)
_FRAME_PX = 336  # target image side (px); each cell gets 336 // n px (at least 8)


def render_maze(
    walls: NDArray[np.bool_], prob: NDArray[np.float64], pose: tuple[int, int, int] | None
) -> NDArray[np.uint8]:
    """An RGB image ``(n c, n c, 3)`` uint8 of a maze, ``c = max(8, 336 // n)`` px per cell.

    Args:
        walls: ``(n, n)`` bool, True = wall, ``walls[iy, ix]`` (row 0 at the bottom; the image
            is drawn north up).
        prob: ``(n, n, 4)`` belief ``[ix, iy, h]``: free cells are shaded white (0) to red (the
            largest probability) by the max over headings; the most probable cell gets a blue
            frame.
        pose: the true pose ``(ix, iy, h)``, drawn as a green triangle pointing along the
            heading, or None.
    """
    n = walls.shape[0]
    c = max(8, _FRAME_PX // n)
    heat = prob.max(axis=2).T  # (iy, ix)
    top = heat.max()
    t = np.sqrt(heat / top) if top > 0 else np.zeros_like(heat)
    cells = _FREE_RGB + t[..., None] * (_HEAT_RGB - _FREE_RGB)
    cells[walls] = _WALL_RGB
    cells = np.flipud(cells).round().astype(np.uint8)  # image row 0 = the top of the maze
    image = np.repeat(np.repeat(cells, c, axis=0), c, axis=1)

    if top > 0:
        flat = int(np.argmax(prob))
        mx, my = np.unravel_index(flat, prob.shape)[:2]
        r0, c0 = (n - 1 - int(my)) * c, int(mx) * c
        w = max(1, c // 10)
        image[r0 : r0 + c, c0 : c0 + w] = _MODE_RGB
        image[r0 : r0 + c, c0 + c - w : c0 + c] = _MODE_RGB
        image[r0 : r0 + w, c0 : c0 + c] = _MODE_RGB
        image[r0 + c - w : r0 + c, c0 : c0 + c] = _MODE_RGB

    if pose is not None:
        x, y, h = pose
        # pixel centres of the cell in cell units, centred, y up; then in the heading frame
        u = (np.arange(c) + 0.5) / c - 0.5
        gx, gy = np.meshgrid(u, -u)  # rows go down, y goes up
        angle = h * np.pi / 2
        fwd = np.cos(angle) * gx + np.sin(angle) * gy
        left = -np.sin(angle) * gx + np.cos(angle) * gy
        # triangle: tip at fwd = 0.38, base at fwd = -0.3, half-width 0.28 at the base
        inside = (fwd >= -0.3) & (np.abs(left) <= 0.28 * (0.38 - fwd) / 0.68)
        r0, c0 = (n - 1 - y) * c, x * c
        image[r0 : r0 + c, c0 : c0 + c][inside] = _TRUE_RGB
    return image
