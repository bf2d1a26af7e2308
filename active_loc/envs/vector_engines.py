"""What steps the members of :class:`~active_loc.envs.vector_env.ActiveLocalizationVectorEnv`.

Three engines with one interface (``obs``, ``reset_member``, ``reset_members``, ``step``,
``infos``, ``info_dicts``, ``frame``, ``workers``, and per member ``np_random``,
``np_random_seed``, ``set_np_random``; ``set_specs``):

* :class:`BatchedEngine`: the EKF landmark, MCL and grid Markov ids. One core with B = n
  members advances the whole batch: :class:`LandmarkCore` in one numba kernel call (spread
  over numba's threads for large batches), :class:`~active_loc.envs.grid_core.GridCore` with
  one call of each grid kernel for all members (each on numba's threads),
  :class:`~active_loc.envs.particle_core.ParticleCore` with its members' filters on worker
  threads (the particle kernels release the GIL, so two cores run two members' filters at
  once); the info arrays are read off the core's state matrix in one kernel call.
* :class:`BatchedMazeEngine`: the maze. One :class:`~active_loc.envs.maze_core.MazeCore`
  with B = n steps every member in one kernel call; the n single envs stay attached to it as
  its members, to pick their mazes and starts at a reset and to render.
* :class:`MemberEngine`: the ids with identical-looking landmarks, whose association core
  holds one episode. The engine keeps n unwrapped single envs and steps and autoresets them
  on worker threads, each thread taking the next member left, slowest first. It also skips
  gymnasium's wrapper stack and ``SyncVectorEnv``'s per-step copies.

Either way member ``b`` draws only from its own Generator, in the same order as a single env
seeded the same, so the vector env reproduces n single envs exactly.

The batched info (``infos``) holds arrays ``(n,)`` only, in the dtypes of
:func:`~active_loc.envs.outcome.info_dtype`: a single env's keys, its ``reward_terms`` dict as
the flat ``reward_<term>`` arrays it also carries. Readers that stack every key (TorchRL's
``GymWrapper`` with SAME_STEP autoreset) take no nested dict.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numba
import numpy as np
from gymnasium.envs.registration import EnvSpec
from gymnasium.utils import seeding
from numpy.typing import NDArray

from active_loc.envs.actions import check_actions
from active_loc.envs.grid_core import GridCore
from active_loc.envs.landmark_core import (
    S_COLLIDED,
    S_ENTROPY,
    S_HEAD_ERR,
    S_KIDNAPPED,
    S_LOCALIZED,
    S_N_VISIBLE,
    S_NIS,
    S_OUTCOME,
    S_POS_ERR,
    S_SUCCESS,
    S_TERMINAL,
    S_UNCERTAINTY_REWARD,
    X_STATS,
    LandmarkCore,
)
from active_loc.envs.localization_env import (
    ActiveLocalizationEnv,
    build_frame,
    localization_info,
    reward_settings,
)
from active_loc.envs.maze_env import MazeEnv
from active_loc.envs.outcome import flat_reward_terms, info_dtype
from active_loc.envs.particle_core import ParticleCore
from active_loc.envs.rewards import step_reward
from active_loc.parallel import WorkerThreads

#: the fewest members a worker thread of the batched engine steps (fewer: one thread)
MIN_ROWS_PER_WORKER = 64

#: info dict of a batch: key -> array (n,), plus ``"_key"`` masks
BatchInfo = dict[str, Any]


def batched_core(env: gym.Env) -> bool:
    """Whether ``env`` (unwrapped) runs on a core that holds B members: the fused EKF
    landmark core, the particle (MCL) core or the grid Markov core."""
    if not isinstance(env, ActiveLocalizationEnv):
        return False
    core = type(env.core)
    return core in (ParticleCore, GridCore) or (
        core is LandmarkCore and env.config.ekf_backend == "numba")


class BatchedEngine:
    """n episodes in one core with B = n (:func:`batched_core`).

    Args:
        template: a single env of the id (its config, spaces and reward settings are used).
        num_envs: n.
        render_envs: how many leading members keep the paths the renderer draws (0: none).
        workers: threads (at most the cores numba has). The EKF kernel spreads the members
            over numba's threads when each gets at least :data:`MIN_ROWS_PER_WORKER`; the
            grid kernels spread each member's cells over them; the MCL members step and
            reset on worker threads, ``workers`` at once.
    """

    def __init__(
        self, template: ActiveLocalizationEnv, num_envs: int, render_envs: int, workers: int = 1
    ) -> None:
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        core_type = type(template.core)
        if core_type is ParticleCore:  # Python threads, one member each
            self.workers = min(int(workers), num_envs)
        else:  # numba's threads
            self.workers = min(int(workers), numba.config.NUMBA_NUM_THREADS)
        if core_type is LandmarkCore:
            # more threads pay off only when each gets enough members to outweigh starting them
            self.workers = min(self.workers, max(1, num_envs // MIN_ROWS_PER_WORKER))
        self.config = template.config
        self.core: LandmarkCore | ParticleCore = core_type(template.config,
                                                           batch_size=num_envs)
        self.num_envs = num_envs
        self.single_observation_space = template.observation_space
        self.single_action_space = template.action_space
        self.title = template.spec.id if template.spec is not None else type(template).__name__
        self._continuous = template.config.action_type == "continuous"
        self._primitives = self.core.models.primitives
        self._reward = reward_settings(template.config)
        self._reward_name = self._reward.name
        self._step_cost = self._reward.step_cost
        self._collision_penalty = self._reward.collision_penalty
        self._terminate = bool(template.config.terminate_when_localized)
        self.rngs: list[np.random.Generator | None] = [None] * num_envs
        self.seeds: list[int | None] = [None] * num_envs  # as Env.np_random_seed has them
        self.collisions = np.zeros(num_envs, dtype=np.int64)
        self.steps = np.zeros(num_envs, dtype=np.int64)
        self._render_envs = render_envs
        self._paths: list[tuple[list[NDArray], list[NDArray]]] = [
            ([], []) for _ in range(render_envs)
        ]

    @property
    def obs(self) -> NDArray[np.float32] | dict[str, NDArray[np.float32]]:
        """The current observations (views): ``(n, D)``, or the dict of an image
        observation (:attr:`~active_loc.envs.landmark_core.StateViews.observations`)."""
        return self.core.observations

    def reset_member(self, b: int, seed: int | None, options: dict[str, Any] | None) -> None:
        """New episode of member ``b``; its Generator is (re)seeded as ``Env.reset`` does."""
        if seed is not None or self.rngs[b] is None:
            self.rngs[b], self.seeds[b] = seeding.np_random(seed)
        rng = self.rngs[b]
        assert rng is not None
        self.core.reset_member(b, rng)
        self._start_episode(b)

    def reset_members(self, rows: Sequence[int]) -> None:
        """Autoreset the members in ``rows`` (their Generators go on; the MCL members'
        resets on the worker threads)."""
        if not rows:
            return
        rngs: list[np.random.Generator] = [self.rngs[b] for b in rows]  # type: ignore[misc]
        self.core.reset_members(rows, rngs, threads=self.workers)
        for b in rows:
            self._start_episode(b)

    def _start_episode(self, b: int) -> None:
        """Member ``b``'s counters and paths at the start of its episode."""
        self.collisions[b] = 0
        self.steps[b] = 0
        if b < self._render_envs:
            self._paths[b] = ([self.core.pose[b, :2].copy()],
                              [self.core.belief_mean[b, :2].copy()])

    def np_random(self, b: int) -> np.random.Generator:
        """Member ``b``'s Generator (made unseeded if it has none yet, as ``Env`` does)."""
        if self.rngs[b] is None:
            self.rngs[b], self.seeds[b] = seeding.np_random()
        rng = self.rngs[b]
        assert rng is not None
        return rng

    def np_random_seed(self, b: int) -> int:
        """The seed of member ``b``'s Generator (-1 once one was set, as ``Env`` has it)."""
        self.np_random(b)
        seed = self.seeds[b]
        assert seed is not None
        return seed

    def set_np_random(self, b: int, rng: np.random.Generator) -> None:
        self.rngs[b], self.seeds[b] = rng, -1

    def set_specs(self, specs: Sequence[EnvSpec | None]) -> None:
        """The members' single-env specs (their frames are titled with the id)."""
        spec = specs[0]
        self.title = spec.id if spec is not None else "ActiveLocalizationEnv"

    def step(
        self, actions: Any, active: NDArray[np.bool_], autoreset: Sequence[int] = ()
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_]]:
        """Advance the active members, then autoreset those in ``autoreset`` (inactive ones);
        ``(rewards, terminated, truncated)`` of all n (zero and False for the inactive
        members)."""
        core = self.core
        self._write_actions(actions, active)
        rngs: list[np.random.Generator] = self.rngs  # type: ignore[assignment]
        bad = core.step(rngs, active, threads=self.workers)
        if bad >= 0:  # the kernel checks every action before it moves any member
            raise ValueError(
                f"the action of sub-env {bad} contains NaN or inf: {np.asarray(actions)[bad]!r}"
            )
        n = self.num_envs
        rewards = np.empty(n)
        terminated = np.empty(n, dtype=np.bool_)
        step_outcomes(core.state, active, self._step_cost, self._collision_penalty,
                      self._terminate, rewards, terminated, self.collisions, self.steps)
        for b in range(min(self._render_envs, n)):
            if active[b]:
                self._paths[b][0].append(core.pose[b, :2].copy())
                self._paths[b][1].append(core.belief_mean[b, :2].copy())
        self.reset_members(autoreset)
        return rewards, terminated, np.zeros(n, dtype=np.bool_)

    def infos(self, mask: NDArray[np.bool_]) -> BatchInfo:
        """The members' info arrays (the flat keys of a single env's info, same values), with
        ``mask`` as every ``"_key"`` (one read-only array shared by the keys): all n rows are
        filled, whatever the mask. The arrays are rows of three fresh blocks, one per dtype,
        filled by one kernel call."""
        n = self.num_envs
        reals = np.empty((9, n))
        flags = np.empty((3, n), dtype=np.bool_)
        counts = np.empty((2, n), dtype=np.int64)
        info_columns(self.core.state, self.collisions, self._step_cost, self._collision_penalty,
                     reals, flags, counts)
        mask = mask.copy()
        mask.flags.writeable = False
        terms = {self._reward_name: reals[5], "step_cost": reals[6], "collision": reals[7],
                 "outcome": reals[8]}
        info: BatchInfo = {  # the single env's keys, in its order
            "pose_error": reals[0],
            "heading_error": reals[1],
            "entropy": reals[2],
            "localized": flags[0],
            "is_success": flags[1],
            "collisions": counts[0],
            **flat_reward_terms(terms),
            "n_visible": counts[1],
            "nis": reals[3],
            "kidnapped": flags[2],
            "association_accuracy": reals[4],
        }
        return with_masks(info, mask)

    def info_dicts(self, rows: list[int] | None = None) -> list[dict[str, Any]]:
        """The info dicts of the members in ``rows`` (None: all), as single envs return them
        (cheaper than :meth:`infos` followed by unbatching, for SB3's list of dicts)."""
        picked = slice(None) if rows is None else rows
        collisions = self.collisions[picked].tolist()
        reward = self._reward
        return [
            localization_info(outcome, count, 1.0, reward)
            for outcome, count in zip(self.core.outcomes(picked), collisions, strict=True)
        ]

    def close(self) -> None:
        if isinstance(self.core, ParticleCore):
            self.core.close()  # its worker threads

    def frame(self, b: int) -> Any:
        """The renderer's frame of member ``b`` (< ``render_envs``)."""
        true_path, belief_path = self._paths[b]
        return build_frame(self.core, b, true_path, belief_path, int(self.steps[b]), self.title)

    def _write_actions(self, actions: Any, active: NDArray[np.bool_]) -> None:
        # NaN and inf in continuous actions: the kernel finds them before moving anyone
        actions = check_actions(actions, self.single_action_space, active, check_finite=False)
        if self._continuous:
            self.core.actions[:] = actions
            return
        self.core.actions[:] = self._primitives[np.where(active, actions, 0)]


class BatchedMazeEngine:
    """n maze episodes in one :class:`~active_loc.envs.maze_core.MazeCore` with B = n.

    Args:
        envs: the n single envs (unwrapped); each is attached to the shared core as its
            member and still picks its member's mazes and starts from its own Generator (and
            renders it).
    """

    def __init__(self, envs: list[MazeEnv]) -> None:
        self.envs = envs
        self.num_envs = len(envs)
        self.core = envs[0].new_core(self.num_envs)
        for b, env in enumerate(envs):
            env.attach(self.core, b)
        self.workers = 1
        self.single_observation_space = envs[0].observation_space
        self.single_action_space = envs[0].action_space
        self._reward = envs[0].reward_settings
        self._actions = np.zeros(self.num_envs, dtype=np.int64)

    @property
    def obs(self) -> NDArray[np.float32]:
        """``(n, *obs_shape)`` the current observations (a view)."""
        return self.core.obs

    def reset_member(self, b: int, seed: int | None, options: dict[str, Any] | None) -> None:
        self.envs[b].reset(seed=seed, options=options)

    def reset_members(self, rows: Sequence[int]) -> None:
        """Autoreset the members in ``rows`` (their Generators go on)."""
        for b in rows:
            self.envs[b].reset()

    def np_random(self, b: int) -> np.random.Generator:
        return self.envs[b].np_random

    def np_random_seed(self, b: int) -> int:
        return self.envs[b].np_random_seed

    def set_np_random(self, b: int, rng: np.random.Generator) -> None:
        self.envs[b].np_random = rng

    def set_specs(self, specs: Sequence[EnvSpec | None]) -> None:
        """The members' single-env specs (as ``gymnasium.make`` would have set them)."""
        for env, spec in zip(self.envs, specs, strict=True):
            env.spec = spec

    def step(
        self, actions: Any, active: NDArray[np.bool_], autoreset: Sequence[int] = ()
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_]]:
        """Step the active members in one kernel call, then autoreset those in ``autoreset``
        (inactive ones); ``(rewards, terminated, truncated)`` of all n (zero and False for
        the inactive members)."""
        actions = check_actions(actions, self.single_action_space, active)
        np.copyto(self._actions, actions, where=active, casting="unsafe")
        self.core.step(self._actions, active)
        state = self.core.state
        rewards = np.where(active, state["reward"], 0.0)
        terminated = active & state["terminated"]
        truncated = active & state["truncated"]
        self.reset_members(autoreset)
        return rewards, terminated, truncated

    def infos(self, mask: NDArray[np.bool_]) -> BatchInfo:
        """The members' info arrays (the flat keys of a single env's info, same values), with
        ``mask`` as every ``"_key"``: all n rows are filled, whatever the mask."""
        state = self.core.state
        mask = mask.copy()
        mask.flags.writeable = False
        n = self.num_envs
        reward = self._reward
        terms = {reward.name: state["uncertainty"],
                 "step_cost": np.full(n, -reward.step_cost),
                 "collision": np.where(state["collided"], -reward.collision_penalty, 0.0)}
        info: BatchInfo = {  # the single env's keys, in its order
            "pose_error": state["pose_error"],
            "heading_error": state["heading_error"],
            "entropy": state["entropy"],
            "localized": state["localized"],
            "is_success": state["success"],
            "collisions": state["collisions"],
            **flat_reward_terms(terms),
            "depth": state["depth"],
            "max_prob": state["max_prob"],
        }
        # copies (the state changes on the next step) in the dtypes of the info rule
        typed = {key: np.array(value, dtype=info_dtype(value)) for key, value in info.items()}
        return with_masks(typed, mask)

    def info_dicts(self, rows: list[int] | None = None) -> list[dict[str, Any]]:
        """The info dicts of the members in ``rows`` (None: all), as single envs return them."""
        return [self.envs[b].last_info() for b in (range(self.num_envs) if rows is None else rows)]

    def frame(self, b: int) -> Any:
        return self.envs[b].render()

    def close(self) -> None:
        for env in self.envs:
            env.close()


class MemberEngine:
    """n unwrapped single envs stepped in turn (ids whose core holds one episode).

    Args:
        envs: the n members (unwrapped; the first ones built with a render mode render).
        workers: threads that step and autoreset the members, each taking the next member
            left as it finishes one. The filters' numba kernels release the GIL, so on a
            multi-core machine the members' particle updates run side by side; 1 steps them
            in this thread. Every member uses only its own arrays and Generator, so the
            results do not depend on ``workers`` or on which thread took which member.
    """

    def __init__(self, envs: list[gym.Env], workers: int = 1) -> None:
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        self.envs = envs
        self.threads = WorkerThreads(min(int(workers), len(envs)))
        self.num_envs = len(envs)
        self.single_observation_space = envs[0].observation_space
        self.single_action_space = envs[0].action_space
        self.obs = np.zeros(
            (self.num_envs, *self.single_observation_space.shape),  # type: ignore[misc]
            dtype=self.single_observation_space.dtype,
        )
        self._infos: list[dict[str, Any]] = [{} for _ in envs]
        self._seconds = np.zeros(self.num_envs)  # how long each member's last step or reset took

    @property
    def workers(self) -> int:
        """Threads the members are stepped on."""
        return self.threads.workers

    def reset_member(self, b: int, seed: int | None, options: dict[str, Any] | None) -> None:
        self.obs[b], self._infos[b] = self.envs[b].reset(seed=seed, options=options)

    def reset_members(self, rows: Sequence[int]) -> None:
        """Autoreset the members in ``rows`` (their Generators go on), on the threads."""
        self._run([(b, None) for b in rows])

    def np_random(self, b: int) -> np.random.Generator:
        return self.envs[b].np_random

    def np_random_seed(self, b: int) -> int:
        return self.envs[b].np_random_seed

    def set_np_random(self, b: int, rng: np.random.Generator) -> None:
        self.envs[b].np_random = rng

    def set_specs(self, specs: Sequence[EnvSpec | None]) -> None:
        """The members' single-env specs (as ``gymnasium.make`` would have set them)."""
        for env, spec in zip(self.envs, specs, strict=True):
            env.spec = spec

    def step(
        self, actions: Any, active: NDArray[np.bool_], autoreset: Sequence[int] = ()
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_]]:
        """Step the active members and autoreset those in ``autoreset`` (inactive ones), all
        on the threads; ``(rewards, terminated, truncated)`` of all n (zero and False for the
        inactive members)."""
        actions = check_actions(actions, self.single_action_space, active)
        tasks = [(int(b), actions[b]) for b in np.flatnonzero(active)]
        return self._run(tasks + [(b, None) for b in autoreset])

    def _run(
        self, tasks: list[tuple[int, Any]]
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_]]:
        """Run ``(b, action)`` tasks, a step of member ``b`` or, when the action is None, its
        autoreset; ``(rewards, terminated, truncated)`` of all n (zero and False for the
        members not stepped). The threads take first the members whose last step or reset
        took longest, so that a few 100000-particle steps do not all land on one thread."""
        n = self.num_envs
        rewards = np.zeros(n)
        terminated = np.zeros(n, dtype=np.bool_)
        truncated = np.zeros(n, dtype=np.bool_)

        def run(task: tuple[int, Any]) -> None:
            b, action = task
            start = time.perf_counter()
            if action is None:
                self.obs[b], self._infos[b] = self.envs[b].reset()
            else:
                obs, reward, term, trunc, self._infos[b] = self.envs[b].step(action)
                self.obs[b] = obs
                rewards[b], terminated[b], truncated[b] = reward, term, trunc
            self._seconds[b] = time.perf_counter() - start

        if self.threads.workers == 1 or len(tasks) < 2:
            for task in tasks:
                run(task)
        else:
            tasks.sort(key=lambda task: -self._seconds[task[0]])
            self.threads.run_tasks(run, tasks)
        return rewards, terminated, truncated

    def close(self) -> None:
        self.threads.close()
        for env in self.envs:
            env.close()

    def infos(self, mask: NDArray[np.bool_]) -> BatchInfo:
        """The masked members' last info dicts, stacked (gymnasium's vector info layout, the
        nested ``reward_terms`` left to its flat keys)."""
        out: BatchInfo = {}
        for b in np.flatnonzero(mask):
            add_member_info(out, self._infos[b], int(b), self.num_envs)
        return out

    def info_dicts(self, rows: list[int] | None = None) -> list[dict[str, Any]]:
        """The last info dicts of the members in ``rows`` (None: all; copies)."""
        return [dict(self._infos[b]) for b in (range(self.num_envs) if rows is None else rows)]

    def frame(self, b: int) -> Any:
        return self.envs[b].render()


@numba.njit(cache=True, nogil=True)
def step_outcomes(
    state: NDArray, active: NDArray, step_cost: float, collision_penalty: float,
    terminate: bool, rewards: NDArray, terminated: NDArray, collisions: NDArray,
    steps: NDArray,
) -> None:
    """Rewards and terminations ``(n,)`` (out) of a batch step read off the metrics in
    ``state``, as a single env computes them; counts the active members' collisions and
    steps. Inactive members get reward 0 and are not terminated."""
    for b in range(state.shape[0]):
        if not active[b]:
            rewards[b] = 0.0
            terminated[b] = False
            continue
        collided = state[b, X_STATS + S_COLLIDED] > 0.5
        rewards[b] = step_reward(state[b, X_STATS + S_UNCERTAINTY_REWARD], collided, step_cost,
                                 collision_penalty, state[b, X_STATS + S_OUTCOME])
        terminated[b] = terminate and state[b, X_STATS + S_TERMINAL] > 0.5
        collisions[b] += collided
        steps[b] += 1


@numba.njit(cache=True, nogil=True)
def info_columns(
    state: NDArray, collisions: NDArray, step_cost: float, collision_penalty: float,
    reals: NDArray, flags: NDArray, counts: NDArray,
) -> None:
    """The info values of every member as :func:`localization_info` has them, a column per
    member (out): ``reals`` ``(9, n)``: pose error, heading error, entropy, NIS, association
    accuracy, then the reward terms (uncertainty, step cost, collision, outcome); ``flags``
    ``(3, n)``: localized, success, kidnapped; ``counts`` ``(2, n)``: collisions, landmarks in
    view."""
    for b in range(state.shape[0]):
        stats = state[b, X_STATS:]
        reals[0, b] = stats[S_POS_ERR]
        reals[1, b] = stats[S_HEAD_ERR]
        reals[2, b] = stats[S_ENTROPY]
        reals[3, b] = stats[S_NIS]
        reals[4, b] = 1.0  # known correspondences: every association is right
        reals[5, b] = stats[S_UNCERTAINTY_REWARD]
        reals[6, b] = -step_cost
        reals[7, b] = -collision_penalty if stats[S_COLLIDED] > 0.5 else 0.0
        reals[8, b] = stats[S_OUTCOME]
        flags[0, b] = stats[S_LOCALIZED] > 0.5
        flags[1, b] = stats[S_SUCCESS] > 0.5
        flags[2, b] = stats[S_KIDNAPPED] > 0.5
        counts[0, b] = collisions[b]
        counts[1, b] = int(stats[S_N_VISIBLE])


def with_masks(info: dict[str, Any], mask: NDArray[np.bool_]) -> BatchInfo:
    """``info`` with ``mask`` as the ``"_key"`` of every key."""
    out: BatchInfo = {}
    for key, value in info.items():
        out[key] = value
        out[f"_{key}"] = mask
    return out


def add_member_info(out: BatchInfo, info: dict[str, Any], b: int, n: int) -> None:
    """Write member ``b``'s info into the stacked ``out``: scalars become arrays (n,) in the
    dtype of :func:`~active_loc.envs.outcome.info_dtype`, anything else an object array;
    nested dicts (``reward_terms``, whose flat keys the info has too) are left out;
    ``"_key"`` marks the members that have the key."""
    for key, value in info.items():
        if isinstance(value, dict):
            continue
        if key not in out:
            if isinstance(value, np.ndarray) and value.ndim > 0:
                raise TypeError("array-valued info entries are not stacked")  # none exist
            out[key] = np.zeros(n, dtype=info_dtype(value) or object)
        out[key][b] = value
        mask = out.setdefault(f"_{key}", np.zeros(n, dtype=np.bool_))
        mask[b] = True
