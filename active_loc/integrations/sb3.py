"""stable-baselines3's ``VecEnv`` API over the package's own vector env.

::

    from stable_baselines3 import PPO
    from active_loc.integrations.sb3 import make_native_vec_env

    env = make_native_vec_env("ActiveLoc/LandmarkEKF-v0", 16, seed=0,
                              info_keywords=("is_success", "pose_error"))
    PPO("MlpPolicy", env).learn(100_000)

:class:`NativeVecEnv` returns what SB3's ``DummyVecEnv`` over ``gym.make(env_id)`` returns
(sub-env i seeded seed + i): the same observations, rewards, dones and infos, ended sub-envs
reset at once with ``"terminal_observation"`` and ``"TimeLimit.truncated"`` in their info. But a
step is one step of :class:`~active_loc.envs.vector_env.ActiveLocalizationVectorEnv` (one
batched kernel call for the EKF landmark ids) instead of n single-env steps.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from numpy.typing import NDArray
from stable_baselines3.common.vec_env import VecEnv, VecMonitor
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnvIndices,
    VecEnvObs,
    VecEnvStepReturn,
)

#: keys of a SAME_STEP step's batched info that are not per-step info entries
_FINAL_KEYS = ("final_obs", "final_info")


class NativeVecEnv(VecEnv):
    """n sub-envs of an ``ActiveLoc`` id, stepped by its native vector env, as an SB3 ``VecEnv``.

    Args:
        env_id: an ``ActiveLoc/...`` id.
        n_envs: n >= 1.
        env_kwargs: kwargs of ``gymnasium.make_vec``: the single env's kwargs, and
            ``max_episode_steps``, ``render_mode``, ``render_envs`` of the vector env.

    ``reset()`` returns observations ``(n, *obs_shape)``; ``step_wait()`` returns them with
    rewards ``(n,)`` float32, dones ``(n,)`` bool and a list of n info dicts of Python scalars
    (nested dicts for ``reward_terms``). The sub-envs are not Python objects, so ``get_attr``
    reads the vector env's (shared) attributes and ``set_attr`` and ``env_method`` are not
    supported.

    Attributes:
        vector_env: the gymnasium vector env (autoreset mode ``SAME_STEP``).
    """

    def __init__(self, env_id: str, n_envs: int, env_kwargs: dict[str, Any] | None = None) -> None:
        _check_env_id(env_id)
        if isinstance(n_envs, bool) or not isinstance(n_envs, (int, np.integer)) or n_envs < 1:
            raise ValueError(f"n_envs must be an integer >= 1, got {n_envs!r}")
        kwargs = dict(env_kwargs or {})
        if "autoreset_mode" in kwargs:
            raise ValueError("NativeVecEnv sets autoreset_mode itself (SAME_STEP, as SB3 needs)")
        # SAME_STEP: an ended sub-env is reset within the step, as SB3's VecEnv API requires
        self.vector_env = gym.make_vec(
            env_id, int(n_envs), vectorization_mode="vector_entry_point",
            autoreset_mode=AutoresetMode.SAME_STEP, **kwargs,
        )
        self.env_id = env_id
        self.spec = self.vector_env.spec  # VecMonitor writes its id in the CSV header
        self._actions: Any = None
        super().__init__(
            int(n_envs), self.vector_env.single_observation_space,
            self.vector_env.single_action_space,
        )

    def reset(self) -> VecEnvObs:
        """Reset every sub-env; ``(n, *obs_shape)`` observations. Sub-env i gets seed + i after
        ``seed(seed)``, and the options of ``set_options``; both are used once."""
        obs, infos = self.vector_env.reset(seed=list(self._seeds), options=self._shared_options())
        self.reset_infos = unbatch_info(infos, self.num_envs)
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        """Store the actions: ``(n,)`` integers (Discrete) or ``(n, 2)`` floats (Box)."""
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        """``(obs (n, *obs_shape), rewards (n,) float32, dones (n,) bool, infos)``; an ended
        sub-env's obs is its reset observation and its info is the last step's, plus
        ``"terminal_observation"`` (its reset info goes to ``reset_infos``)."""
        obs, rewards, terminated, truncated, infos, reset_infos = (
            self.vector_env.unwrapped.step_with_info_dicts(self._actions)
        )
        for i, reset_info in reset_infos.items():
            self.reset_infos[i] = reset_info
        for info, cut in zip(infos, (truncated & ~terminated).tolist(), strict=True):
            info["TimeLimit.truncated"] = cut
        # float32 rewards, as DummyVecEnv's buffer gives them
        return obs, rewards.astype(np.float32), terminated | truncated, infos

    def close(self) -> None:
        self.vector_env.close()

    def get_images(self) -> Sequence[NDArray[np.uint8] | None]:
        """One image, not one per sub-env: the vector env's ``render()``, i.e. the first
        sub-env's frame or the first ``render_envs`` frames tiled (``render(mode)`` then returns
        that image)."""
        if self.render_mode != "rgb_array":
            warnings.warn(
                f"the render mode is {self.render_mode!r}; get_images needs 'rgb_array'",
                stacklevel=2,
            )
            return [None]
        return [self.vector_env.render()]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """The vector env's attribute (shared by every sub-env), once per index."""
        if not hasattr(self.vector_env, attr_name):
            raise AttributeError(
                f"the native vector env of {self.env_id} has no attribute {attr_name!r} (its "
                "sub-envs are not Python objects: get_attr reads the vector env's attributes)"
            )
        value = getattr(self.vector_env, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        raise NotImplementedError(
            f"NativeVecEnv cannot set {attr_name!r} on its sub-envs (they are not Python "
            "objects); pass settings in env_kwargs instead"
        )

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        raise NotImplementedError(
            f"NativeVecEnv cannot call {method_name!r} on its sub-envs (they are not Python "
            "objects); use gymnasium.make(env_id) for per-env methods"
        )

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        """All False: no gymnasium wrapper is involved. (Monitoring is ``VecMonitor``'s job,
        which ``evaluate_policy`` recognises; answering True for ``Monitor`` here would make
        ``VecMonitor`` warn that it overwrites a Monitor.)"""
        return [False for _ in self._get_indices(indices)]

    def _shared_options(self) -> dict[str, Any] | None:
        # the vector env resets every sub-env with one options dict
        if not any(self._options):
            return None
        first = self._options[0]
        if any(options != first for options in self._options[1:]):
            raise NotImplementedError(
                "NativeVecEnv resets every sub-env with the same options; got different ones "
                "per sub-env from set_options"
            )
        return dict(first)


def make_native_vec_env(
    env_id: str,
    n_envs: int,
    seed: int | None = None,
    env_kwargs: dict[str, Any] | None = None,
    monitor: bool = True,
    info_keywords: tuple[str, ...] = (),
    monitor_file: str | None = None,
) -> VecEnv:
    """``NativeVecEnv(env_id, n_envs, env_kwargs)``, seeded like SB3's ``make_vec_env`` (sub-env
    i gets seed + i at the first reset) and, with ``monitor``, wrapped in ``VecMonitor``
    (``info["episode"]`` at episode ends; ``info_keywords`` are copied into it and into the
    CSV ``monitor_file``, e.g. ``"runs/x/monitor/0"``, if given)."""
    if not monitor and (info_keywords or monitor_file is not None):
        raise ValueError("info_keywords and monitor_file need monitor=True")
    env = NativeVecEnv(env_id, n_envs, env_kwargs)
    if seed is not None:
        env.seed(seed)
        env.action_space.seed(seed)
    if monitor:
        return VecMonitor(env, filename=monitor_file, info_keywords=tuple(info_keywords))
    return env


def unbatch_info(batch: dict[str, Any], n: int) -> list[dict[str, Any]]:
    """Gymnasium's batched info (arrays ``(n,)`` with ``"_key"`` masks) as n plain dicts of
    Python scalars: row i holds the keys whose mask is set at i; nested dicts recurse.
    ``final_obs`` and ``final_info`` are left out."""
    keys = [key for key in batch if f"_{key}" in batch and key not in _FINAL_KEYS]
    columns = [
        unbatch_info(batch[key], n) if isinstance(batch[key], dict)
        else np.asarray(batch[key]).tolist()
        for key in keys
    ]
    masks = [batch[f"_{key}"] for key in keys]
    # one mask is often shared by every key: check each distinct one once
    if keys and all(mask.all() for mask in {id(mask): mask for mask in masks}.values()):
        # every row has every key: build the rows in C
        return [dict(zip(keys, row, strict=True)) for row in zip(*columns, strict=True)]
    rows: list[dict[str, Any]] = [{} for _ in range(n)]
    for key, values, mask in zip(keys, columns, masks, strict=True):
        for i in np.flatnonzero(mask).tolist():
            rows[i][key] = values[i]
    return rows


def _check_env_id(env_id: Any) -> None:
    ids = sorted(i for i in gym.registry if i.startswith("ActiveLoc/"))
    if env_id not in ids:
        raise ValueError(f"env_id must be an ActiveLoc id ({', '.join(ids)}), got {env_id!r}")
