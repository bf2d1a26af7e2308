"""RLlib: the ``ActiveLoc`` ids as registered RLlib envs.

::

    import ray
    from ray.rllib.algorithms.ppo import PPOConfig
    from active_loc.integrations.rllib import register_rllib_envs

    ray.init()
    register_rllib_envs()
    config = (
        PPOConfig()
        .environment("ActiveLoc/LandmarkEKF-v0", env_config={"action_type": "discrete"})
        .env_runners(num_env_runners=2)
    )
    algo = config.build_algo()
    print(algo.train()["env_runners"]["episode_return_mean"])

RLlib's env runners may be other processes (Ray actors), where ``import active_loc`` has not
run and the ``ActiveLoc`` ids are not registered with gymnasium. The env creators registered
here import ``active_loc`` themselves before ``gymnasium.make``, so they work in any process.
With ``.env_runners(num_envs_per_env_runner=n, gym_env_vectorize_mode="vector_entry_point")``
each env runner steps the package's native vector env of n sub-envs.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable, Mapping
from typing import Any

import gymnasium as gym

try:
    from ray.tune.registry import register_env
except ImportError as err:  # pragma: no cover - depends on the installed extras
    raise ImportError(
        'active_loc.integrations.rllib needs RLlib: pip install "active-loc[rllib]"'
    ) from err

from active_loc.envs.registration import ALL_ENV_IDS

__all__ = ["RLLIB_ENV_IDS", "env_creator", "make_env", "register_rllib_envs"]

#: every ``ActiveLoc`` id
RLLIB_ENV_IDS: tuple[str, ...] = ALL_ENV_IDS


def make_env(
    env_id: str, config: Mapping[str, Any] | None = None
) -> gym.Env[Any, Any] | gym.vector.VectorEnv[Any, Any, Any]:
    """``gymnasium.make(env_id, **config)`` after ``import active_loc`` in this process.

    Args:
        env_id: an ``ActiveLoc/...`` id.
        config: RLlib's ``EnvContext`` (the ``env_config`` dict of ``.environment()``): the
            keywords of ``gymnasium.make``, e.g. ``{"action_type": "discrete"}``. With
            ``num_envs`` (RLlib adds it under
            ``.env_runners(gym_env_vectorize_mode="vector_entry_point")``) it returns the
            package's native vector env of that many sub-envs instead.
    """
    import active_loc  # noqa: F401 -- registers the ids in this (maybe remote) process

    kwargs = dict(config or {})
    num_envs = kwargs.pop("num_envs", None)
    if num_envs is None:
        return gym.make(env_id, **kwargs)
    return gym.make_vec(env_id, int(num_envs), vectorization_mode="vector_entry_point", **kwargs)


def env_creator(
    env_id: str,
) -> Callable[[Mapping[str, Any]], gym.Env[Any, Any] | gym.vector.VectorEnv[Any, Any, Any]]:
    """The env creator of ``env_id`` for ``ray.tune.registry.register_env`` (picklable)."""
    return functools.partial(make_env, env_id)


def register_rllib_envs(env_ids: Iterable[str] | None = None) -> tuple[str, ...]:
    """Register ``env_ids`` (default: every ``ActiveLoc`` id) with ``register_env`` under
    their own names, so that ``config.environment("ActiveLoc/...")`` finds them.

    Call it after ``ray.init()`` (or let ``ray.init`` pick up the registrations made before);
    calling it again re-registers the same creators. Returns the registered ids.
    """
    ids = RLLIB_ENV_IDS if env_ids is None else tuple(env_ids)
    for env_id in ids:
        if env_id not in RLLIB_ENV_IDS:
            raise ValueError(f"env_id must be an ActiveLoc id ({', '.join(RLLIB_ENV_IDS)}), "
                             f"got {env_id!r}")
        register_env(env_id, env_creator(env_id))
    return ids
