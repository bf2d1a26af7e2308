"""``ActiveLocalizationVectorEnv``: n episodes of one id behind gymnasium's ``VectorEnv`` API.

Registered as the ``vector_entry_point`` of every ``ActiveLoc`` id, so that::

    envs = gymnasium.make_vec("ActiveLoc/LandmarkEKF-v0", 256,
                              vectorization_mode="vector_entry_point")

returns it. Sub-env i is seeded with seed + i and reproduces, step for step, a single env
made with the same kwargs and seeded seed + i (observations, rewards, flags and infos). The
EKF landmark ids and the maze step the whole batch in one kernel call, the grid Markov ids in
one call of each grid kernel; the others step their members on worker threads
(:mod:`active_loc.envs.vector_engines`).

The sub-envs are rows of batched arrays, not env objects, so ``call``, ``get_attr`` and
``set_attr`` (gymnasium's ``SyncVectorEnv`` API) serve a fixed set of names, the same for
every id: each returns one value per sub-env, equal to what that sub-env's single env would
give (:data:`MEMBER_ATTRIBUTES`, :data:`MEMBER_METHODS`); only ``np_random`` can be set per
sub-env.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.envs.registration import EnvSpec
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from active_loc.envs.belief_image import copy_observation, copy_observations
from active_loc.envs.field_checks import check_integer
from active_loc.envs.localization_env import ActiveLocalizationEnv
from active_loc.envs.maze_env import MazeEnv
from active_loc.envs.vector_engines import (
    BatchedEngine,
    BatchedMazeEngine,
    BatchInfo,
    MemberEngine,
    batched_core,
)

#: the most worker threads (more than any machine's cores, fewer than would exhaust it)
MAX_WORKERS = 1024

#: single-env attributes that ``get_attr`` (and ``call``) read per sub-env
MEMBER_ATTRIBUTES = ("spec", "config", "metadata", "render_mode", "observation_space",
                     "action_space", "np_random", "np_random_seed")
#: single-env methods that ``call`` runs per sub-env
MEMBER_METHODS = ("render",)
#: member attributes that ``set_attr`` sets per sub-env
SETTABLE_ATTRIBUTES = ("np_random",)

#: keywords of the vector env's spec that a single env does not take (left out of a
#: sub-env's spec, whose ``max_episode_steps`` is the spec's field, as ``gymnasium.make`` has it)
VECTOR_KWARGS = frozenset({"num_envs", "vectorization_mode", "vector_kwargs", "wrappers",
                           "autoreset_mode", "render_envs", "workers", "max_episode_steps"})

_FIXED = ("is fixed when the vector env is built: the sub-envs share one configuration and "
          "one batched simulator (make a new vector env to change it)")
#: why set_attr refuses a member attribute
_NOT_SETTABLE = {
    **dict.fromkeys(("spec", "config", "metadata", "render_mode", "observation_space",
                     "action_space"), _FIXED),
    "np_random_seed": ("is read-only: seed the sub-envs with reset(seed=...) or give them "
                       "Generators with set_attr('np_random', [...])"),
    "render": "is a method",
}
#: single-env methods the sub-envs have only together, through the vector env
_VECTOR_METHODS = ("reset", "step", "close")


class ActiveLocalizationVectorEnv(VectorEnv):
    """n active-localization episodes stepped together.

    Args:
        num_envs: n >= 1.
        max_episode_steps: truncate each sub-env after this many steps (the registration's
            limit, passed by ``make_vec``); None: no limit beyond the env's own.
        autoreset_mode: gymnasium's ``AutoresetMode`` (or its string): ``NEXT_STEP``
            (default: the step after an episode ends resets that sub-env and ignores its
            action), ``SAME_STEP`` (reset at once; the last observation and info are in
            ``info["final_obs"]`` and ``info["final_info"]``) or ``DISABLED`` (reset ended
            sub-envs yourself with ``reset(options={"reset_mask": mask})``).
        render_mode: None or ``"rgb_array"``.
        render_envs: how many sub-envs ``render()`` draws, tiled in a grid (1: the first
            sub-env's frame as is).
        workers: threads stepping the sub-envs (the kernels release the GIL). None: one per
            CPU core, at most 2. The MCL ids step and autoreset their sub-envs on Python
            threads, each taking the next one left (MCL: 1.6x to 2x ``SyncVectorEnv`` on 2
            cores); the batched EKF ids spread one kernel over numba's threads once each gets
            64 sub-envs or more; the grid Markov ids spread each kernel's cells over them;
            the maze's one kernel call runs on one thread. The results are the same for any
            value.
        env_class: the single env class (``ActiveLocalizationEnv`` or ``MazeEnv``).
        **env_kwargs: the single env's kwargs (``scenario`` and config fields, or the maze's).

    ``info`` is a dict of arrays ``(n,)`` with gymnasium's ``"_key"`` masks; its keys and
    dtypes are the same on every step: a single env's keys (float64, int64 or bool), its
    nested ``reward_terms`` dict as the flat ``reward_<term>`` arrays it also carries (so that
    readers stacking every key, such as TorchRL's ``GymWrapper`` with SAME_STEP, can).

    ``call(name)``, ``get_attr(name)`` and ``set_attr(name, values)`` work as in gymnasium's
    ``SyncVectorEnv``, with one entry per sub-env, for the names a single env has:

    | name                | one entry per sub-env                                         |
    |---------------------|---------------------------------------------------------------|
    | ``spec``            | the single env's spec (this env's, without its vector kwargs) |
    | ``config``          | the single env's config (one object shared by the sub-envs)  |
    | ``metadata``, ``observation_space``, ``action_space`` | the single env's           |
    | ``render_mode``     | this env's for the first ``render_envs`` sub-envs, else None  |
    | ``np_random``       | the sub-env's Generator; ``set_attr`` gives each its own     |
    | ``np_random_seed``  | the seed of its Generator (-1 once ``set_attr`` set one)      |
    | ``render`` (method) | its frame ``(H, W, 3)`` uint8, None past ``render_envs``      |

    ``set_attr`` of any other name, and ``call`` of ``reset``, ``step`` or ``close``, raise
    ``AttributeError`` saying why; an unknown name raises ``AttributeError`` naming it.
    """

    metadata: dict[str, Any] = {  # noqa: RUF012
        "render_modes": ["rgb_array"],
        "render_fps": 10,
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    _spec: EnvSpec | None = None

    def __init__(
        self,
        num_envs: int = 1,
        *,
        max_episode_steps: int | None = None,
        autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
        render_mode: str | None = None,
        render_envs: int = 1,
        workers: int | None = None,
        env_class: type[gym.Env] = ActiveLocalizationEnv,
        **env_kwargs: Any,
    ) -> None:
        check_integer("num_envs", num_envs, 1)
        if max_episode_steps is not None:
            check_integer("max_episode_steps (or None)", max_episode_steps, 1)
        if workers is not None:
            check_integer("workers (or None)", workers, 1, MAX_WORKERS)
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        check_integer("render_envs", render_envs, 1, int(num_envs))
        try:
            self.autoreset_mode = AutoresetMode(autoreset_mode)
        except ValueError:
            modes = [m.value for m in AutoresetMode]
            raise ValueError(
                f"autoreset_mode must be one of {modes}, got {autoreset_mode!r}"
            ) from None
        self.num_envs = int(num_envs)
        self.max_episode_steps = max_episode_steps
        self.render_mode = render_mode
        self.render_envs = render_envs
        self.metadata = {**self.metadata, "autoreset_mode": self.autoreset_mode}

        template = env_class(**env_kwargs)
        self._single_config = template.config
        self._single_metadata = template.metadata
        self.engine: BatchedEngine | BatchedMazeEngine | MemberEngine
        self._renderer: Any = None
        if workers is None:
            workers = min(2, os.cpu_count() or 1)
        if batched_core(template):
            assert isinstance(template, ActiveLocalizationEnv)
            # the paths a frame draws are kept only when there is something to render
            kept_paths = render_envs if render_mode is not None else 0
            self.engine = BatchedEngine(template, self.num_envs, kept_paths, workers)
        else:
            members = [template] + [env_class(**env_kwargs) for _ in range(1, self.num_envs)]
            if render_mode is not None:
                for b in range(render_envs):
                    members[b] = env_class(render_mode=render_mode, **env_kwargs)
            if isinstance(template, MazeEnv):
                self.engine = BatchedMazeEngine(members)  # type: ignore[arg-type]
            else:
                self.engine = MemberEngine(members, workers)
        self.single_observation_space = self.engine.single_observation_space
        self.single_action_space = self.engine.single_action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)

        n = self.num_envs
        self._elapsed = np.zeros(n, dtype=np.int64)
        self._needs_reset = np.zeros(n, dtype=np.bool_)  # ended last step (autoreset pending)
        self._none = np.zeros(n, dtype=np.bool_)  # read-only masks of no and every sub-env
        self._none.flags.writeable = False
        self._all = np.ones(n, dtype=np.bool_)
        self._all.flags.writeable = False
        self._has_reset = False

    # -- gymnasium API ----------------------------------------------------------------------

    @property
    def spec(self) -> EnvSpec | None:
        """The spec ``make_vec`` made this env from (None when made directly)."""
        return self._spec

    @spec.setter
    def spec(self, spec: EnvSpec | None) -> None:
        # make_vec sets it after __init__: hand the sub-envs their single-env specs then
        self._spec = spec
        self.engine.set_specs([self._member_spec(b) for b in range(self.num_envs)])

    def reset(
        self,
        *,
        seed: int | list[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[NDArray, BatchInfo]:
        """Reset every sub-env (or those in ``options["reset_mask"]``); sub-env i gets
        ``seed + i`` (an int seed) or ``seed[i]`` (a list)."""
        n = self.num_envs
        seeds = self._member_seeds(seed)
        options = dict(options) if options is not None else None
        mask = np.ones(n, dtype=np.bool_)
        if options is not None and "reset_mask" in options:
            mask = _check_reset_mask(options.pop("reset_mask"), n)
        if not mask.all() and not self._has_reset:
            raise RuntimeError("the first reset() must reset every sub-env (no reset_mask)")
        for b in np.flatnonzero(mask):
            self.engine.reset_member(int(b), seeds[b], options)
        self._elapsed[mask] = 0
        self._needs_reset = self._needs_reset & ~mask
        self._has_reset = True
        return copy_observations(self.engine.obs), self.engine.infos(mask)

    def step(
        self, actions: Any
    ) -> tuple[NDArray, NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], BatchInfo]:
        engine = self.engine
        n = self.num_envs
        rewards, terminated, truncated = self._advance(actions)
        ended = terminated | truncated
        if self.autoreset_mode == AutoresetMode.SAME_STEP and ended.any():
            final_obs = np.full(n, None, dtype=object)
            for b in np.flatnonzero(ended):
                final_obs[b] = copy_observation(engine.obs, b)
            final_info = engine.infos(ended)
            self._reset_ended(np.flatnonzero(ended).tolist())
            infos = engine.infos(self._all)
            infos.update(final_obs=final_obs, _final_obs=ended.copy(),
                         final_info=final_info, _final_info=ended.copy())
        else:
            infos = engine.infos(self._all)
        return copy_observations(engine.obs), rewards, terminated, truncated, infos

    def step_with_info_dicts(
        self, actions: Any
    ) -> tuple[NDArray, NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_],
               list[dict[str, Any]], dict[int, dict[str, Any]]]:
        """:meth:`step` with SAME_STEP autoreset, the infos as one dict per sub-env (what
        stable-baselines3 and other list-of-dicts libraries take), built without the
        batched arrays.

        Returns:
            ``(obs, rewards, terminated, truncated, infos, reset_infos)``: an ended sub-env's
            obs is its reset observation, its entry of ``infos`` is the last step's info
            plus ``"terminal_observation"``, and ``reset_infos[i]`` its reset info.
        """
        if self.autoreset_mode != AutoresetMode.SAME_STEP:
            raise RuntimeError(
                f"step_with_info_dicts needs autoreset_mode=SAME_STEP, got {self.autoreset_mode}"
            )
        engine = self.engine
        rewards, terminated, truncated = self._advance(actions)
        infos = engine.info_dicts()
        reset_infos: dict[int, dict[str, Any]] = {}
        ended = np.flatnonzero(terminated | truncated).tolist()
        if ended:
            for b in ended:
                infos[b]["terminal_observation"] = copy_observation(engine.obs, b)
            self._reset_ended(ended)
            reset_infos = dict(zip(ended, engine.info_dicts(ended), strict=True))
        return copy_observations(engine.obs), rewards, terminated, truncated, infos, reset_infos

    def render(self) -> NDArray[np.uint8] | None:
        """The first sub-env's frame, or the first ``render_envs`` frames tiled in a grid."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array'")
            return None
        if not self._has_reset:
            raise RuntimeError("call reset() before render()")
        frames = [self._member_frame(b) for b in range(self.render_envs)]
        return tile_frames(frames)

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """``name`` of every sub-env: the method's result (``render``) or the attribute's
        value (the args are then ignored, as ``SyncVectorEnv`` does); a tuple of n."""
        if name in MEMBER_METHODS:
            if args or kwargs:
                raise TypeError(f"the sub-envs' {name}() takes no arguments")
            return self._render_members()
        if name in _VECTOR_METHODS:
            raise AttributeError(
                f"the sub-envs of {type(self).__name__} have no {name}() of their own: they "
                f"are stepped, reset and closed together, with this vector env's {name}()"
                + (" (reset(options={'reset_mask': mask}) resets some)" if name == "reset"
                   else "")
            )
        getter = self._member_getters().get(name)
        if getter is None:
            raise AttributeError(self._unknown(name))
        return tuple(getter(b) for b in range(self.num_envs))

    def get_attr(self, name: str) -> tuple[Any, ...]:
        """``name`` of every sub-env, a tuple of n (``call(name)``, as ``SyncVectorEnv``)."""
        return self.call(name)

    def set_attr(self, name: str, values: list[Any] | tuple[Any, ...] | Any) -> None:
        """Set ``name`` of every sub-env: ``values`` one per sub-env (a list or tuple of n),
        or one value for all. Only ``np_random`` can be set, one Generator per sub-env."""
        if name not in SETTABLE_ATTRIBUTES:
            reason = _NOT_SETTABLE.get(name)
            if reason is None:
                raise AttributeError(self._unknown(name))
            raise AttributeError(f"set_attr({name!r}): the sub-envs' {name} {reason}")
        n = self.num_envs
        if not isinstance(values, (list, tuple)):
            values = [values] * n
        if len(values) != n:
            raise ValueError(
                "Values must be a list or tuple with length equal to the number of "
                f"environments. Got `{len(values)}` values for {n} environments."
            )
        self._set_generators(list(values))

    def close_extras(self, **kwargs: Any) -> None:
        self.engine.close()
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # -- helpers ----------------------------------------------------------------------------

    def _advance(
        self, actions: Any
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_]]:
        """Step the sub-envs that are not waiting for a NEXT_STEP reset, and reset those (in
        the same engine call, so that the threads share both); ``(rewards, terminated,
        truncated)`` with the time limit applied. Ended sub-envs are left for the caller to
        reset (SAME_STEP) or marked for the next step."""
        if not self._has_reset:
            raise RuntimeError("call reset() before step()")
        mode = self.autoreset_mode
        if mode == AutoresetMode.DISABLED and self._needs_reset.any():
            ended = np.flatnonzero(self._needs_reset).tolist()
            raise RuntimeError(
                f"sub-envs {ended} have ended and autoreset is disabled: reset them with "
                "reset(options={'reset_mask': mask}) before stepping"
            )
        resetting = self._none
        autoreset: list[int] = []
        if mode == AutoresetMode.NEXT_STEP and self._needs_reset.any():
            resetting = self._needs_reset
            autoreset = np.flatnonzero(resetting).tolist()
            self._elapsed[resetting] = 0
        active = ~resetting
        rewards, terminated, truncated = self.engine.step(actions, active, autoreset)
        self._elapsed += active
        if self.max_episode_steps is not None:
            truncated |= active & (self._elapsed >= self.max_episode_steps)
        if mode != AutoresetMode.SAME_STEP:
            self._needs_reset = terminated | truncated
        return rewards, terminated, truncated

    def _reset_ended(self, rows: list[int]) -> None:
        """Autoreset the sub-envs in ``rows`` (their Generators go on)."""
        self.engine.reset_members(rows)
        self._elapsed[rows] = 0

    def _member_frame(self, b: int) -> NDArray[np.uint8]:
        engine = self.engine
        if isinstance(engine, (MemberEngine, BatchedMazeEngine)):
            return engine.frame(b)
        frame = engine.frame(b)
        if self._renderer is None:
            from active_loc.envs.rendering import GridFrame, GridRenderer, LandmarkRenderer

            grid = isinstance(frame, GridFrame)
            self._renderer = GridRenderer() if grid else LandmarkRenderer()
        return self._renderer.render_rgb(frame)

    def _member_getters(self) -> dict[str, Callable[[int], Any]]:
        """Member attribute name -> its value for sub-env b."""
        engine = self.engine
        return {
            "spec": self._member_spec,
            "config": lambda b: self._single_config,
            "metadata": lambda b: self._single_metadata,
            "render_mode": self._member_render_mode,
            "observation_space": lambda b: self.single_observation_space,
            "action_space": lambda b: self.single_action_space,
            "np_random": engine.np_random,
            "np_random_seed": engine.np_random_seed,
        }

    def _member_spec(self, b: int) -> EnvSpec | None:
        """The spec ``gymnasium.make`` gives sub-env b's single env (None when this env was
        not made by ``make_vec``)."""
        spec = self.spec
        if spec is None:
            return None
        kwargs = {key: value for key, value in spec.kwargs.items() if key not in VECTOR_KWARGS}
        if self._member_render_mode(b) is None:
            kwargs.pop("render_mode", None)
        limit = spec.kwargs.get("max_episode_steps", spec.max_episode_steps)
        return dataclasses.replace(spec, kwargs=kwargs, max_episode_steps=limit)

    def _member_render_mode(self, b: int) -> str | None:
        return self.render_mode if b < self.render_envs else None

    def _render_members(self) -> tuple[NDArray[np.uint8] | None, ...]:
        """Each sub-env's frame (None for those past ``render_envs``)."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array'")
            return (None,) * self.num_envs
        if not self._has_reset:
            raise RuntimeError("call reset() before render()")
        return tuple(self._member_frame(b) if b < self.render_envs else None
                     for b in range(self.num_envs))

    def _set_generators(self, rngs: list[Any]) -> None:
        """Give sub-env b the Generator ``rngs[b]``; checks them all before setting any."""
        for b, rng in enumerate(rngs):
            if not isinstance(rng, np.random.Generator):
                raise TypeError(
                    f"set_attr('np_random'): sub-env {b} needs a numpy.random.Generator, got "
                    f"{type(rng).__name__}"
                )
        if len({id(rng) for rng in rngs}) < len(rngs):
            raise ValueError(
                "set_attr('np_random'): each sub-env needs a Generator of its own (one shared "
                "Generator would make the draws depend on the order the sub-envs take them)"
            )
        for b, rng in enumerate(rngs):
            self.engine.set_np_random(b, rng)

    def _unknown(self, name: str) -> str:
        known = ", ".join(MEMBER_ATTRIBUTES + MEMBER_METHODS)
        return (
            f"the sub-envs of {type(self).__name__} have no attribute {name!r} (they are rows "
            f"of one batched simulator; call and get_attr know {known})"
        )

    def _member_seeds(self, seed: int | list[int | None] | None) -> list[int | None]:
        n = self.num_envs
        if seed is None:
            return [None] * n
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            return [int(seed) + i for i in range(n)]
        seeds = list(seed)
        if len(seeds) != n:
            raise ValueError(f"a list of seeds needs one per sub-env ({n}), got {len(seeds)}")
        return seeds


def maze_vector_env(num_envs: int = 1, **kwargs: Any) -> ActiveLocalizationVectorEnv:
    """The ``vector_entry_point`` of ``ActiveLoc/Maze-v0``."""
    return ActiveLocalizationVectorEnv(num_envs, env_class=MazeEnv, **kwargs)


def tile_frames(frames: list[NDArray[np.uint8]]) -> NDArray[np.uint8]:
    """Frames ``(H, W, 3)`` of equal size in a near-square grid (black where none is left)."""
    if len(frames) == 1:
        return frames[0]
    cols = math.ceil(math.sqrt(len(frames)))
    rows = math.ceil(len(frames) / cols)
    h, w, c = frames[0].shape
    out = np.zeros((rows * h, cols * w, c), dtype=np.uint8)
    for k, frame in enumerate(frames):
        r, q = divmod(k, cols)
        out[r * h : (r + 1) * h, q * w : (q + 1) * w] = frame
    return out


def _check_reset_mask(mask: Any, n: int) -> NDArray[np.bool_]:
    if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_ or mask.shape != (n,):
        raise ValueError(
            f"options['reset_mask'] must be a bool numpy array of shape ({n},), got {mask!r}"
        )
    if not mask.any():
        raise ValueError("options['reset_mask'] selects no sub-env")
    return mask
