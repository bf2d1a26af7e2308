"""Evaluation: run agents over the same seeded episodes and summarize what happened.

The runner is pure data: :func:`run_episode` plays one episode and returns an
:class:`EpisodeRecord`, :func:`evaluate` plays ``episodes`` of them per agent, :func:`summarize`
turns records into the ``summary.json`` dict and :func:`write_results` writes
``results.csv``, ``summary.json`` and ``summary.md``. Pictures are drawn by
:mod:`active_loc.evaluation_plots` from the same records (:func:`entropy_curves` and
:func:`success_curves` compute what it draws).

Seeding: episode ``i`` of every agent is ``env.reset(seed=seed + i)``, so every agent meets the
same maps, start poses and noise draws up to the point where its actions differ. Before it, the
agent is reseeded from the same episode seed (:func:`reseed_agent`: a random stream of its own,
independent of the env's), so an episode's record does not depend on the episodes run before
it: :func:`evaluate_ray` runs the episodes as Ray tasks, in any order and any process, and gets
the same records as :func:`evaluate`.

Metrics read the truth (the true pose, through ``info`` and the env's simulator state); agents
never do: each step an agent gets the observation and ``env.unwrapped.planner_view()``.

Definitions (per episode; "step" counts the actions taken, 0 being the state after ``reset``):

* **success**: ``info["is_success"]`` at the episode's end (the belief is confident and truly
  within tolerance of the true pose).
* **steps to localize**: the first step ``t`` at which ``info["is_success"]`` holds (``t = 0``
  when it already holds after ``reset``). In an episode that terminates on localization this is
  the episode's end. An episode in which it never holds is *not localized*: its value is None
  (an empty CSV cell, null in JSON), and it is left out of the mean and the median, which are
  therefore over the localized episodes only (null when there are none).
* **step limit**: the most steps the env allows an episode (``env.spec.max_episode_steps``,
  or the ``episode_length`` of an env that truncates itself, such as ``Maze-v0``); None for an
  env without either.
* **final entropy**: ``info["entropy"]`` (nats) at the end.
* **position error**, **heading error**: ``info["pose_error"]`` (m) and
  ``info["heading_error"]`` (rad) at the end.
* **NEES**: ``(x - mu)^T Sigma^-1 (x - mu)`` at the end, with ``x`` the true pose, ``mu`` and
  ``Sigma`` the belief's mean and covariance, and the heading residual wrapped to [-pi, pi).
  Gaussian-comparable (chi-square with 3 degrees of freedom when the filter is consistent)
  for the EKF. For MCL it uses the particle mean and covariance and is reported as well, but it
  is only comparable while the particle set is unimodal. A belief without a mean and
  covariance (the grid belief of ``Maze-v0``) has none (None). A covariance that is not
  positive definite (a particle set collapsed onto one pose) gives NaN.
* **false convergence**: the episode ends with ``info["localized"]`` True (the belief is
  confident) but ``info["is_success"]`` False (it is confident about the wrong pose).
* **collisions**: ``info["collisions"]`` at the end (blocked moves in the episode).
* **path length** (m): the sum of the true robot's displacements over the steps, from
  ``env.unwrapped.core.pose`` (``env.unwrapped.true_pose`` in cells of 1 m for ``Maze-v0``);
  the jump of a kidnapping (a step with ``info["kidnapped"]``) is not a displacement.
* **return**: the sum of the rewards.
* **maze index**: the test-set entry a ``Maze-v0`` episode replayed (its ``maze_index`` after
  ``reset``); None (an empty CSV cell) for random mazes and the other envs.

Summary per agent (:func:`summarize`, over all its episodes unless said otherwise):
``success_rate`` and its Wilson 95% interval ``success_ci95``;
``steps_to_localize_mean``/``_median`` (localized episodes only);
``steps_to_localize_restricted_mean``: the mean over *all* episodes of the steps to localize,
an episode never localized counting as its step limit (the restricted mean time to
localization of survival analysis; null if some episode has no step limit). The mean over the
localized episodes alone rewards an agent that gives up on the hard episodes; this one does
not, and it is lower for an agent that localizes sooner, more often, or both.
``final_entropy_mean``;
``position_rmse`` and ``heading_rmse`` (root mean square of the final errors);
``false_convergence_rate``; ``collisions_mean``; ``return_mean``. Non-finite numbers are
written to JSON as null.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from active_loc.comparison import comparison_markdown, outcomes_of, paired_comparison
from active_loc.geometry import wrap_angle_scalar

#: the columns of ``results.csv``, in order
CSV_COLUMNS: tuple[str, ...] = (
    "agent",
    "episode",
    "seed",
    "success",
    "steps_to_localize",
    "final_entropy",
    "position_error",
    "heading_error",
    "nees",
    "false_convergence",
    "collisions",
    "path_length",
    "return",
    "steps",
    "step_limit",
    "localized",
    "terminated",
    "truncated",
    "belief",
    "maze_index",
)

#: the keys of every agent's entry in ``summary.json``, in order
SUMMARY_KEYS: tuple[str, ...] = (
    "success_rate",
    "success_ci95",
    "steps_to_localize_mean",
    "steps_to_localize_median",
    "steps_to_localize_restricted_mean",
    "final_entropy_mean",
    "position_rmse",
    "heading_rmse",
    "false_convergence_rate",
    "collisions_mean",
    "return_mean",
)


@dataclass(frozen=True)
class EpisodeRecord:
    """One episode of one agent.

    The ``*_trace`` fields have one entry per step, index 0 being the ``info`` of ``reset``
    (length ``steps + 1``); ``reward_trace`` has one per action (length ``steps``).

    Attributes:
        agent: the agent's name.
        episode: the episode's index ``i``; seed: ``reset`` seed (base seed + ``i``).
        env_id: the env's id.
        belief: "ekf", "mcl", "grid" (or the belief's class name for another one).
        steps: actions taken; terminated, truncated: how the episode ended.
        entropy_trace: ``info["entropy"]`` (nats).
        success_trace: ``info["is_success"]``; localized_trace: ``info["localized"]``.
        pose_error_trace: ``info["pose_error"]`` (m); heading_error_trace: (rad).
        reward_trace: the rewards.
        collisions: ``info["collisions"]`` at the end.
        path_length: the true robot's path length (m).
        nees: the NEES at the end, or None for a belief without mean and covariance.
        step_limit: the most steps the env allows an episode; None if it has no limit.
        maze_index: the test-set entry the episode replayed (``Maze-v0`` with ``test_set`` or
            ``maze_index``: ``env.unwrapped.maze_index`` after ``reset``); None for an episode
            on a random maze and for the envs without test sets (an empty CSV cell).
    """

    agent: str
    episode: int
    seed: int
    env_id: str
    belief: str
    steps: int
    terminated: bool
    truncated: bool
    entropy_trace: tuple[float, ...]
    success_trace: tuple[bool, ...]
    localized_trace: tuple[bool, ...]
    pose_error_trace: tuple[float, ...]
    heading_error_trace: tuple[float, ...]
    reward_trace: tuple[float, ...]
    collisions: int
    path_length: float
    nees: float | None
    step_limit: int | None = None
    maze_index: int | None = None

    @property
    def base_seed(self) -> int:
        """The evaluation's seed ``S`` (this episode's seed is ``S + episode``)."""
        return self.seed - self.episode

    @property
    def success(self) -> bool:
        """``info["is_success"]`` at the end."""
        return self.success_trace[-1]

    @property
    def localized(self) -> bool:
        """``info["localized"]`` at the end."""
        return self.localized_trace[-1]

    @property
    def steps_to_localize(self) -> int | None:
        """The first step at which ``info["is_success"]`` holds; None if it never does."""
        for t, ok in enumerate(self.success_trace):
            if ok:
                return t
        return None

    @property
    def steps_to_localize_or_limit(self) -> int | None:
        """:attr:`steps_to_localize`, or :attr:`step_limit` if the episode never localized
        (None if it did not and has no limit)."""
        steps = self.steps_to_localize
        return self.step_limit if steps is None else steps

    @property
    def final_entropy(self) -> float:
        return self.entropy_trace[-1]

    @property
    def position_error(self) -> float:
        """``info["pose_error"]`` (m) at the end."""
        return self.pose_error_trace[-1]

    @property
    def heading_error(self) -> float:
        """``info["heading_error"]`` (rad) at the end."""
        return self.heading_error_trace[-1]

    @property
    def false_convergence(self) -> bool:
        """Ends confident (``localized``) but not successful: confident and wrong."""
        return self.localized and not self.success

    @property
    def episode_return(self) -> float:
        """The sum of the rewards."""
        return math.fsum(self.reward_trace)

    def row(self) -> dict[str, Any]:
        """The episode's row of ``results.csv`` (keys :data:`CSV_COLUMNS`)."""
        return {
            "agent": self.agent,
            "episode": self.episode,
            "seed": self.seed,
            "success": self.success,
            "steps_to_localize": self.steps_to_localize,
            "final_entropy": self.final_entropy,
            "position_error": self.position_error,
            "heading_error": self.heading_error,
            "nees": self.nees,
            "false_convergence": self.false_convergence,
            "collisions": self.collisions,
            "path_length": self.path_length,
            "return": self.episode_return,
            "steps": self.steps,
            "step_limit": self.step_limit,
            "localized": self.localized,
            "terminated": self.terminated,
            "truncated": self.truncated,
            "belief": self.belief,
            "maze_index": self.maze_index,
        }


# --- one episode -------------------------------------------------------------------------------


def _true_pose(unwrapped: Any) -> NDArray[np.float64]:
    """The robot's true pose ``(x, y, theta)``: the localization envs keep it in
    ``core.pose``, ``Maze-v0`` as ``true_pose`` = ``(ix, iy, h)`` (1 m cells, 4 headings)."""
    core = getattr(unwrapped, "core", None)
    if core is not None:
        return np.array(core.pose[0], dtype=np.float64)
    ix, iy, h = unwrapped.true_pose
    return np.array([float(ix), float(iy), h * math.pi / 2])


def _replayed_maze(unwrapped: Any) -> int | None:
    """The test-set entry the current episode replays: ``Maze-v0``'s ``maze_index`` (None on
    a random maze), None for an env without one."""
    index = getattr(unwrapped, "maze_index", None)
    return None if index is None else int(index)


def belief_moments(
    belief: Any,
) -> tuple[str, NDArray[np.float64] | None, NDArray[np.float64] | None]:
    """The belief's kind and, where it has them, its mean ``(3,)`` and covariance ``(3, 3)``.

    ``("ekf", mean, cov)`` for the EKF beliefs (``EKFBelief``, ``FilterpyEKFBelief``),
    ``("mcl", particle mean, particle covariance)`` for ``MCLBelief``, and
    ``("grid", None, None)`` for the grid (Markov) belief.
    """
    from active_loc.beliefs.grid import GridBelief
    from active_loc.beliefs.mcl import MCLBelief

    if isinstance(belief, MCLBelief):
        return "mcl", *belief.mean_and_covariance()
    if isinstance(belief, GridBelief):
        return "grid", None, None
    mean, cov = getattr(belief, "mean", None), getattr(belief, "cov", None)
    if isinstance(mean, np.ndarray) and isinstance(cov, np.ndarray):
        return "ekf", np.array(mean, dtype=np.float64).reshape(-1, 3)[0], np.array(
            cov, dtype=np.float64
        ).reshape(-1, 3, 3)[0]
    return type(belief).__name__, None, None


def nees(
    truth: NDArray[np.float64], mean: NDArray[np.float64], cov: NDArray[np.float64]
) -> float:
    """``(x - mu)^T Sigma^-1 (x - mu)`` for poses ``(3,)`` with the heading residual wrapped.

    NaN when the covariance is not finite or not positive definite (numerically: its smallest
    eigenvalue is not above ``1e-12`` times its largest), e.g. a particle set collapsed onto
    one pose.
    """
    error = np.asarray(truth, dtype=np.float64) - np.asarray(mean, dtype=np.float64)
    error[2] = wrap_angle_scalar(float(error[2]))
    cov = np.asarray(cov, dtype=np.float64)
    if not (np.all(np.isfinite(cov)) and np.all(np.isfinite(error))):
        return math.nan
    cov = 0.5 * (cov + cov.T)
    eigenvalues = np.linalg.eigvalsh(cov)
    if not eigenvalues[0] > 1e-12 * eigenvalues[-1]:
        return math.nan
    return float(error @ np.linalg.solve(cov, error))


def step_limit(env: gym.Env) -> int | None:
    """The most steps ``env`` allows an episode: its TimeLimit (``env.spec.max_episode_steps``),
    else the ``episode_length`` of an env that truncates itself (``Maze-v0``), else None."""
    if env.spec is not None and env.spec.max_episode_steps is not None:
        return int(env.spec.max_episode_steps)
    length = getattr(env.unwrapped, "episode_length", None)
    return None if length is None else int(length)


def run_episode(
    env: gym.Env,
    agent: Any,
    seed: int,
    *,
    agent_name: str = "agent",
    episode: int = 0,
    callback: Callable[[gym.Env], None] | None = None,
    options: dict[str, Any] | None = None,
) -> EpisodeRecord:
    """Play one episode of ``agent`` in ``env`` from ``env.reset(seed=seed, options=options)``.

    Each step the agent gets the observation and ``env.unwrapped.planner_view()`` and returns
    an action. ``callback(env)``, if given, is called after ``reset`` and after every step (the
    GIF writer renders frames with it).

    Args:
        env: an env of the package (anything ``gymnasium.make`` returns for an ``ActiveLoc``
            id; its ``info`` must hold ``entropy``, ``is_success``, ``localized``,
            ``pose_error``, ``heading_error`` and ``collisions``).
        agent: an object with ``act(observation, view) -> action``.
        seed: the reset seed.
        agent_name, episode: stored in the record (``episode`` is the index ``i`` of the
            evaluation whose seed is ``base seed + i``).

    Returns:
        The :class:`EpisodeRecord`; see the module docstring for the metrics' definitions.
    """
    unwrapped = env.unwrapped
    observation, info = env.reset(seed=seed, options=options)
    maze_index = _replayed_maze(unwrapped)
    if callback is not None:
        callback(env)
    entropy = [float(info["entropy"])]
    success = [bool(info["is_success"])]
    localized = [bool(info["localized"])]
    pose_error = [float(info["pose_error"])]
    heading_error = [float(info["heading_error"])]
    rewards: list[float] = []
    position = _true_pose(unwrapped)[:2]
    path_length = 0.0
    terminated = truncated = False
    while not (terminated or truncated):
        action = agent.act(observation, unwrapped.planner_view())
        observation, reward, terminated, truncated, info = env.step(action)
        if callback is not None:
            callback(env)
        rewards.append(float(reward))
        entropy.append(float(info["entropy"]))
        success.append(bool(info["is_success"]))
        localized.append(bool(info["localized"]))
        pose_error.append(float(info["pose_error"]))
        heading_error.append(float(info["heading_error"]))
        new_position = _true_pose(unwrapped)[:2]
        if not info.get("kidnapped", False):
            path_length += float(np.hypot(*(new_position - position)))
        position = new_position
    kind, mean, cov = belief_moments(unwrapped.planner_view().belief)
    value = None if mean is None or cov is None else nees(_true_pose(unwrapped), mean, cov)
    return EpisodeRecord(
        agent=agent_name,
        episode=int(episode),
        seed=int(seed),
        env_id=env.spec.id if env.spec is not None else type(unwrapped).__name__,
        belief=kind,
        steps=len(rewards),
        terminated=bool(terminated),
        truncated=bool(truncated),
        entropy_trace=tuple(entropy),
        success_trace=tuple(success),
        localized_trace=tuple(localized),
        pose_error_trace=tuple(pose_error),
        heading_error_trace=tuple(heading_error),
        reward_trace=tuple(rewards),
        collisions=int(info["collisions"]),
        path_length=path_length,
        nees=value,
        step_limit=step_limit(env),
        maze_index=maze_index,
    )


# --- many episodes -----------------------------------------------------------------------------


def episode_seeds(episodes: int, seed: int) -> list[int]:
    """The reset seeds ``seed, seed + 1, ..., seed + episodes - 1`` (the same for every
    agent)."""
    return [seed + i for i in range(episodes)]


#: the spawn key of the agents' random streams. Episode seed ``s`` seeds the env with
#: ``SeedSequence(s)`` (gymnasium's ``np_random(s)``) and the agent with
#: ``SeedSequence(s, spawn_key=(AGENT_SPAWN_KEY,))``: a stream of its own, independent of the
#: env's noise, and the same for every agent.
AGENT_SPAWN_KEY = 1


def agent_rng(episode_seed: int) -> np.random.Generator:
    """The Generator an agent gets for the episode reset with ``episode_seed``."""
    return np.random.default_rng(
        np.random.SeedSequence(int(episode_seed), spawn_key=(AGENT_SPAWN_KEY,))
    )


def reseed_agent(agent: Any, episode_seed: int) -> None:
    """Start ``agent`` afresh for the episode reset with ``episode_seed``.

    An agent with an ``rng`` attribute holding a numpy Generator (``RandomAgent``,
    ``GreedyInfoGainAgent``, ``HorizonPlannerAgent``, ``SB3Agent``, which samples the actions
    of PPO and A2C policies with it) gets :func:`agent_rng` in its place, and
    an agent with a ``reset()`` method (``SB3Agent``) has it called. The package's agents keep
    no other state from one episode to the next (they forget their per-episode memory when
    ``view.step == 0``), so an agent reseeded this way acts exactly as a new one would, and an
    episode's record depends only on the agent, the env and the episode's seed, not on which
    episodes ran before it, in which process. Randomness kept elsewhere (torch's global
    generator, with which SB3 samples the actions of other stochastic policies) is not
    reseeded.
    """
    if isinstance(getattr(agent, "rng", None), np.random.Generator):
        agent.rng = agent_rng(episode_seed)
    reset = getattr(agent, "reset", None)
    if callable(reset):
        reset()


def run_episodes(
    env: gym.Env,
    agent: Any,
    name: str,
    indices: Sequence[int],
    seed: int,
    *,
    reseed_agents: bool = True,
    on_episode: Callable[[EpisodeRecord], None] | None = None,
) -> list[EpisodeRecord]:
    """Episodes ``i`` in ``indices`` (reset seeds ``seed + i``) of ``agent`` in ``env``, in
    that order; with ``reseed_agents``, :func:`reseed_agent` before each. ``on_episode`` is
    called with each record as its episode ends."""
    records = []
    for i in indices:
        episode_seed = int(seed) + int(i)
        if reseed_agents:
            reseed_agent(agent, episode_seed)
        records.append(run_episode(env, agent, episode_seed, agent_name=name, episode=int(i),
                                   options=_test_set_entry(env.unwrapped, int(i))))
        if on_episode is not None:
            on_episode(records[-1])
    return records


def _test_set_entry(unwrapped: gym.Env, episode: int) -> dict[str, Any] | None:
    """The reset options of episode ``episode`` in an env that cycles through a test set
    (``Maze-v0`` with ``test_set``): entry ``episode`` modulo the set's length, whatever ran
    before it in this env (so that :func:`evaluate_ray`'s chunks replay the serial run's
    mazes). None for every other env."""
    test_set = getattr(unwrapped, "test_set", None)
    if test_set is None or getattr(unwrapped.config, "maze_index", None) is not None:
        return None
    return {"maze_index": episode % len(test_set)}


def check_env_kwargs(env_kwargs: Mapping[str, Any] | None) -> dict[str, Any]:
    """``env_kwargs`` as a dict, refusing a ``max_episode_steps`` that would never end an
    episode (gymnasium's TimeLimit takes -1 or 1.5 and never truncates)."""
    if env_kwargs is not None and not isinstance(env_kwargs, Mapping):
        raise ValueError(f"env_kwargs must be a mapping, got {type(env_kwargs).__name__}")
    kwargs = dict(env_kwargs or {})
    steps = kwargs.get("max_episode_steps")
    if steps is not None and (isinstance(steps, bool) or not isinstance(steps, (int, np.integer))
                              or steps < 1):
        raise ValueError(f"max_episode_steps must be an integer >= 1 or None, got {steps!r}")
    return kwargs


def _check_episodes_and_seed(episodes: Any, seed: Any) -> None:
    if isinstance(episodes, bool) or not isinstance(episodes, (int, np.integer)) or episodes < 1:
        raise ValueError(f"episodes must be an integer >= 1, got {episodes!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0 (a reset seed), got {seed!r}")


def evaluate(
    env_id: str,
    env_kwargs: Mapping[str, Any] | None,
    agents: Mapping[str, Any],
    episodes: int,
    seed: int,
    progress: bool = True,
    *,
    reseed_agents: bool = True,
    on_record: Callable[[EpisodeRecord], None] | None = None,
) -> list[EpisodeRecord]:
    """Run every agent on the same seeded episodes of ``gymnasium.make(env_id, **env_kwargs)``.

    Each agent gets an env of its own; episode ``i`` is reset with ``seed + i``, and (with
    ``reseed_agents``, the default) the agent is reseeded for it by :func:`reseed_agent`, so
    that episode ``i`` is the same whatever ran before it: :func:`evaluate_ray` gives the same
    records. ``reseed_agents=False`` uses the agents as given (an agent with a random
    generator continues it from episode to episode, as this function did before it reseeded;
    the results of a stochastic agent then depend on the number and order of the episodes).

    Args:
        env_id: a registered id, e.g. ``"ActiveLoc/LandmarkEKF-v0"``.
        env_kwargs: keyword arguments of ``gymnasium.make`` (env fields, or
            ``max_episode_steps``); None for none.
        agents: name -> agent (``act(observation, view) -> action``), in the order to run.
        episodes: episodes per agent, >= 1.
        seed: the base seed S.
        progress: show a progress bar over the episodes (tqdm, on stderr).
        reseed_agents: reseed each agent before each episode (see above).
        on_record: called with each record as its episode ends (e.g.
            :meth:`ResultsStream.add`, so that an interrupted run keeps its episodes).

    Returns:
        The records, agent by agent in the order of ``agents``, episodes in order.
    """
    _check_episodes_and_seed(episodes, seed)
    if not agents:
        raise ValueError("agents must name at least one agent")
    kwargs = check_env_kwargs(env_kwargs)
    indices = range(int(episodes))
    bar = _progress_bar(len(agents) * len(indices), progress)
    records: list[EpisodeRecord] = []
    try:
        for name, agent in agents.items():
            env = gym.make(env_id, **kwargs)
            try:
                if bar is not None:
                    bar.set_postfix_str(name)
                records += run_episodes(
                    env, agent, name, indices, int(seed), reseed_agents=reseed_agents,
                    on_episode=lambda record: _episode_done(record, bar, on_record),
                )
            finally:
                env.close()
    finally:
        if bar is not None:
            bar.close()
    return records


def _episode_done(record: EpisodeRecord, bar: Any,
                  on_record: Callable[[EpisodeRecord], None] | None) -> None:
    if bar is not None:
        bar.update(1)
    if on_record is not None:
        on_record(record)


# --- many episodes on a Ray cluster ------------------------------------------------------------

RAY_MISSING = 'Ray is not installed: pip install "active-loc[ray]" (or pip install "ray>=2.9")'


def _episode_chunk(
    env_id: str,
    env_kwargs: dict[str, Any],
    name: str,
    spec: str,
    seed: int,
    indices: list[int],
) -> list[EpisodeRecord]:
    """A Ray task: episodes ``indices`` of the agent ``spec``, with an env and an agent of its
    own, reseeded per episode (:func:`run_episodes`)."""
    from active_loc.agents import make_agent

    env = gym.make(env_id, **env_kwargs)
    try:
        agent = make_agent(spec, env, seed)
        return run_episodes(env, agent, name, indices, seed, reseed_agents=True)
    finally:
        env.close()


def _chunks(episodes: int, n_agents: int, cpus: float, chunk_size: int | None) -> list[range]:
    """Episode index ranges of one agent: ``chunk_size`` episodes each, or (None) about four
    tasks per CPU over all agents."""
    if chunk_size is None:
        per_agent = max(1, math.ceil(4 * max(cpus, 1.0) / n_agents))
        chunk_size = math.ceil(episodes / per_agent)
    if chunk_size < 1:
        raise ValueError(f"chunk_size must be >= 1, got {chunk_size}")
    return [range(lo, min(lo + chunk_size, episodes)) for lo in range(0, episodes, chunk_size)]


def evaluate_ray(
    env_id: str,
    env_kwargs: Mapping[str, Any] | None,
    agents: Mapping[str, str],
    episodes: int,
    seed: int,
    progress: bool = True,
    *,
    address: str | None = None,
    chunk_size: int | None = None,
    on_record: Callable[[EpisodeRecord], None] | None = None,
) -> list[EpisodeRecord]:
    """:func:`evaluate` with the episodes run as Ray tasks: the same records, in the same order.

    Each task plays a chunk of consecutive episodes of one agent with an env and an agent it
    builds itself from picklable specs (the env id and kwargs, the agent's
    :func:`~active_loc.agents.make_agent` spec, the seed) and returns their
    :class:`EpisodeRecord` objects (the CSV row and the per-step traces the plots need).
    Agents are reseeded per episode (:func:`reseed_agent`), as :func:`evaluate` does by
    default, so the records equal those of ``evaluate(env_id, env_kwargs, {name:
    make_agent(spec, env, seed)}, episodes, seed)`` (on machines with the same software:
    every node needs ``active-loc`` installed, and the files of ``sb3:PATH`` agents).

    Args:
        env_id, env_kwargs, episodes, seed, progress: as for :func:`evaluate`.
        agents: name -> agent spec (``"random"``, ``"greedy"``, ``"sb3:PATH"``, ...), in the
            order to report them.
        address: the cluster to connect to when Ray is not initialized yet
            (``ray.init(address=address)``: ``"auto"``, ``"ray://HOST:10001"``, ...; None
            starts a local Ray, or joins the one ``RAY_ADDRESS`` names). A Ray this function
            started is shut down when it returns; one already initialized is used as it is.
        chunk_size: episodes per task; None: about four tasks per CPU of the cluster.
        on_record: called with each record as its task returns (tasks finish in any order).

    Raises:
        ImportError: Ray is not installed.
    """
    _check_episodes_and_seed(episodes, seed)
    if not agents:
        raise ValueError("agents must name at least one agent")
    try:
        import ray
    except ImportError as error:
        raise ImportError(RAY_MISSING) from error
    kwargs = check_env_kwargs(env_kwargs)
    started = not ray.is_initialized()
    if started:
        ray.init(address=address)
    try:
        cpus = float(ray.cluster_resources().get("CPU", 1.0))
        chunks = _chunks(int(episodes), len(agents), cpus, chunk_size)
        task = ray.remote(num_cpus=1)(_episode_chunk)
        pending: dict[Any, tuple[str, int]] = {}
        for name, spec in agents.items():
            for chunk in chunks:
                ref = task.remote(env_id, kwargs, name, spec, int(seed), list(chunk))
                pending[ref] = (name, chunk.start)
        bar = _progress_bar(len(agents) * int(episodes), progress)
        done: dict[tuple[str, int], list[EpisodeRecord]] = {}
        waiting = list(pending)
        try:
            while waiting:
                ready, waiting = ray.wait(waiting, num_returns=1)
                for ref in ready:
                    done[pending[ref]] = chunk_records = ray.get(ref)
                    for record in chunk_records:
                        _episode_done(record, bar, on_record)
        except BaseException:
            for ref in waiting:  # a task failed (or Ctrl-C): drop the rest
                ray.cancel(ref)
            raise
        finally:
            if bar is not None:
                bar.close()
    finally:
        if started:
            ray.shutdown()
    return [r for name in agents for chunk in chunks for r in done[(name, chunk.start)]]


def _progress_bar(total: int, enabled: bool) -> Any:
    """A tqdm bar over ``total`` episodes, or None when disabled or tqdm is missing."""
    if not enabled:
        return None
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm(total=total, desc="evaluate", unit="episode", dynamic_ncols=True)


# --- statistics --------------------------------------------------------------------------------


def wilson_interval(successes: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """The Wilson score interval of a binomial proportion ``successes / n``.

    ``(p + z^2/2n -+ z sqrt(p (1 - p)/n + z^2/4n^2)) / (1 + z^2/n)`` with ``p = successes/n``;
    ``z = 1.96`` gives the 95% interval. It stays inside [0, 1] and is not empty at
    ``p = 0`` or ``1``. ``n = 0`` gives ``(nan, nan)``.
    """
    if n < 0 or successes < 0 or successes > n:
        raise ValueError(f"need 0 <= successes <= n, got successes={successes}, n={n}")
    if n == 0:
        return math.nan, math.nan
    p = successes / n
    z2 = z * z
    denominator = 1.0 + z2 / n
    centre = (p + z2 / (2 * n)) / denominator
    half = z * math.sqrt(p * (1.0 - p) / n + z2 / (4 * n * n)) / denominator
    return max(0.0, centre - half), min(1.0, centre + half)


def _group(records: Sequence[EpisodeRecord]) -> dict[str, list[EpisodeRecord]]:
    """Records by agent, in order of first appearance."""
    groups: dict[str, list[EpisodeRecord]] = {}
    for record in records:
        groups.setdefault(record.agent, []).append(record)
    return groups


def _rms(values: Sequence[float]) -> float:
    return math.sqrt(math.fsum(v * v for v in values) / len(values))


def summarize(records: Sequence[EpisodeRecord], baseline: str | None = None) -> dict[str, Any]:
    """The ``summary.json`` dict of an evaluation's records; with ``baseline`` (an agent's
    name), also every other agent's paired comparison with it under the key ``"paired"``
    (:func:`active_loc.comparison.paired_comparison`).

    ``{"env": id, "episodes": N, "seed": S, "agents": {name: {...}}}`` with, per agent, the keys
    of :data:`SUMMARY_KEYS` (definitions in the module docstring). Values are Python floats,
    ints, None (``steps_to_localize_mean``/``_median`` without a localized episode,
    ``steps_to_localize_restricted_mean`` with an episode without step limit) or NaN (mapped
    to null by :func:`write_results`).

    Raises:
        ValueError: no records, records of different envs or base seeds, agents with
            different numbers of episodes, or a ``baseline`` that is not among the agents.
    """
    if not records:
        raise ValueError("summarize needs at least one record")
    env_ids = {r.env_id for r in records}
    if len(env_ids) != 1:
        raise ValueError(f"records come from different envs: {sorted(env_ids)}")
    base_seeds = {r.base_seed for r in records}
    if len(base_seeds) != 1:
        raise ValueError(f"records have different base seeds: {sorted(base_seeds)}")
    groups = _group(records)
    counts = {name: len(group) for name, group in groups.items()}
    if len(set(counts.values())) != 1:
        raise ValueError(f"agents have different numbers of episodes: {counts}")
    agents: dict[str, dict[str, Any]] = {}
    for name, group in groups.items():
        n = len(group)
        successes = sum(r.success for r in group)
        lo, hi = wilson_interval(successes, n)
        steps = [r.steps_to_localize for r in group if r.steps_to_localize is not None]
        capped = [r.steps_to_localize_or_limit for r in group]
        agents[name] = {
            "success_rate": successes / n,
            "success_ci95": [lo, hi],
            "steps_to_localize_mean": float(np.mean(steps)) if steps else None,
            "steps_to_localize_median": float(np.median(steps)) if steps else None,
            "steps_to_localize_restricted_mean": (
                None if None in capped else float(np.mean(capped))
            ),
            "final_entropy_mean": math.fsum(r.final_entropy for r in group) / n,
            "position_rmse": _rms([r.position_error for r in group]),
            "heading_rmse": _rms([r.heading_error for r in group]),
            "false_convergence_rate": sum(r.false_convergence for r in group) / n,
            "collisions_mean": sum(r.collisions for r in group) / n,
            "return_mean": math.fsum(r.episode_return for r in group) / n,
        }
    summary = {
        "env": next(iter(env_ids)),
        "episodes": next(iter(counts.values())),
        "seed": next(iter(base_seeds)),
        "agents": agents,
    }
    if baseline is not None:
        summary["paired"] = paired_comparison(outcomes_of(records), baseline)
    return summary


def json_safe(value: Any) -> Any:
    """``value`` with every non-finite float replaced by None (and numpy scalars and tuples
    turned into Python numbers and lists), recursively."""
    if isinstance(value, Mapping):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value


# --- curves against the step -------------------------------------------------------------------


@dataclass(frozen=True)
class StepCurve:
    """A per-step statistic of one agent over its episodes.

    Attributes:
        steps: ``(T + 1,)`` steps 0..T, T the longest episode of the evaluation.
        mean: ``(T + 1,)`` the mean over episodes.
        lower, upper: ``(T + 1,)`` its 95% interval.
    """

    steps: NDArray[np.int64]
    mean: NDArray[np.float64]
    lower: NDArray[np.float64]
    upper: NDArray[np.float64]


def _held(records: Sequence[EpisodeRecord], field: str, length: int) -> NDArray[np.float64]:
    """``(episodes, length)``: each record's trace, its last value held after the end."""
    out = np.empty((len(records), length))
    for k, record in enumerate(records):
        trace = np.asarray(getattr(record, field), dtype=np.float64)
        out[k, : len(trace)] = trace
        out[k, len(trace) :] = trace[-1]
    return out


def entropy_curves(records: Sequence[EpisodeRecord]) -> dict[str, StepCurve]:
    """Per agent, the mean entropy (nats) at each step with a 95% confidence band of the mean
    (Student t with ``n - 1`` degrees of freedom; no band with one episode).

    An episode that has ended counts with its final entropy at the later steps (a belief that
    terminated confident stays confident), up to the longest episode of any agent.
    """
    from scipy import stats

    length = max(r.steps for r in records) + 1
    curves = {}
    for name, group in _group(records).items():
        values = _held(group, "entropy_trace", length)
        n = values.shape[0]
        mean = values.mean(axis=0)
        if n > 1:
            half = stats.t.ppf(0.975, n - 1) * values.std(axis=0, ddof=1) / math.sqrt(n)
        else:
            half = np.zeros(length)
        curves[name] = StepCurve(np.arange(length), mean, mean - half, mean + half)
    return curves


def success_curves(records: Sequence[EpisodeRecord]) -> dict[str, StepCurve]:
    """Per agent, the fraction of episodes with ``info["is_success"]`` at each step, with the
    Wilson 95% interval; an episode that has ended counts with its final value."""
    length = max(r.steps for r in records) + 1
    curves = {}
    for name, group in _group(records).items():
        values = _held(group, "success_trace", length)
        n = values.shape[0]
        counts = values.sum(axis=0).round().astype(int)
        bounds = np.array([wilson_interval(int(c), n) for c in counts])
        curves[name] = StepCurve(np.arange(length), counts / n, bounds[:, 0], bounds[:, 1])
    return curves


# --- files -------------------------------------------------------------------------------------


def _csv_cell(value: Any) -> Any:
    """None -> empty cell; floats at full precision (repr); others as they are."""
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)
    return value


def _fmt(value: float | None, digits: int = 3) -> str:
    if value is None or not math.isfinite(value):
        return "n/a"
    return f"{value:.{digits}f}"


def summary_markdown(summary: Mapping[str, Any]) -> str:
    """``summary`` (as :func:`summarize` returns it) as a Markdown table, followed by the
    paired comparison's table if ``summary`` has one (key ``"paired"``)."""
    episodes, seed = summary["episodes"], summary["seed"]
    lines = [
        f"# Evaluation: {summary['env']}",
        "",
        f"{episodes} episodes per agent, seeds {seed}..{seed + episodes - 1} (the same for "
        "every agent).",
        "",
        "| agent | success (Wilson 95%) | steps to localize, mean | median | restricted mean "
        "| final entropy (nats) | position RMSE (m) | heading RMSE (rad) | false convergence | "
        "collisions | return |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, s in summary["agents"].items():
        lo, hi = s["success_ci95"]
        cells = [
            f"`{name}`",
            f"{_fmt(s['success_rate'], 2)} [{_fmt(lo, 2)}, {_fmt(hi, 2)}]",
            _fmt(s["steps_to_localize_mean"], 1),
            _fmt(s["steps_to_localize_median"], 1),
            _fmt(s["steps_to_localize_restricted_mean"], 1),
            _fmt(s["final_entropy_mean"], 2),
            _fmt(s["position_rmse"]),
            _fmt(s["heading_rmse"]),
            _fmt(s["false_convergence_rate"], 2),
            _fmt(s["collisions_mean"], 2),
            _fmt(s["return_mean"], 2),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    lines += [
        "",
        "Success: `is_success` at the episode's end, with the Wilson 95% interval. Steps to "
        "localize: the first step with `is_success`; mean and median over the localized "
        "episodes only (n/a: none localized); the restricted mean over all episodes, one "
        "never localized counting as the env's step limit. RMSE: over the final errors of all "
        "episodes. False convergence: ends `localized` (confident) without `is_success`. "
        "Means per episode.",
        "",
    ]
    if "paired" in summary:
        lines.append(comparison_markdown(summary["paired"]))
    return "\n".join(lines)


class ResultsStream:
    """``results.csv`` written row by row as episodes finish, so that an interrupted run keeps
    every episode it ended; :func:`write_results` rewrites it in order at the end.

    Opening it checks that ``out_dir`` can hold the results (created if missing) before any
    episode runs.

    Raises:
        OSError: ``out_dir`` is a file, or cannot be created or written (the message names it).
    """

    def __init__(self, out_dir: str | Path) -> None:
        out = Path(out_dir)
        if out.exists() and not out.is_dir():
            raise OSError(f"{out}: is a file, not a folder for the results")
        try:
            out.mkdir(parents=True, exist_ok=True)
            self.path = out / "results.csv"
            self._file = self.path.open("w", newline="", encoding="utf-8")
        except OSError as error:
            raise OSError(f"{out}: cannot write results there: "
                          f"{error.strerror or error}") from None
        self._writer = csv.DictWriter(self._file, fieldnames=CSV_COLUMNS)
        self._writer.writeheader()
        self._file.flush()

    def add(self, record: EpisodeRecord) -> None:
        """Append ``record``'s row and flush it to disk."""
        self._writer.writerow({k: _csv_cell(v) for k, v in record.row().items()})
        self._file.flush()

    def close(self) -> None:
        self._file.close()


def write_results(
    records: Sequence[EpisodeRecord], summary: Mapping[str, Any], out_dir: str | Path
) -> dict[str, Path]:
    """Write ``results.csv`` (one row per agent and episode, columns :data:`CSV_COLUMNS`),
    ``summary.json`` (non-finite numbers as null) and ``summary.md`` into ``out_dir``
    (created if missing).

    Returns:
        ``{"csv": path, "json": path, "md": path}``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"csv": out / "results.csv", "json": out / "summary.json", "md": out / "summary.md"}
    with paths["csv"].open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=CSV_COLUMNS)
        writer.writeheader()
        for record in records:
            writer.writerow({k: _csv_cell(v) for k, v in record.row().items()})
    paths["json"].write_text(
        json.dumps(json_safe(summary), indent=2, allow_nan=False) + "\n", encoding="utf-8"
    )
    paths["md"].write_text(summary_markdown(summary), encoding="utf-8")
    return paths
