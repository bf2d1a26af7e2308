"""TorchRL envs over the ``ActiveLoc`` ids.

::

    from torchrl.envs.utils import check_env_specs
    from active_loc.integrations.torchrl import make_torchrl_env

    env = make_torchrl_env("ActiveLoc/LandmarkEKF-v0", action_type="discrete")
    check_env_specs(env)
    rollout = env.rollout(200)  # "is_success", "pose_error", ... ride along under "next"

    batched = make_torchrl_env("ActiveLoc/LandmarkEKF-v0", num_envs=64)  # batch_size [64]

:func:`make_torchrl_env` wraps ``gymnasium.make(env_id, **kwargs)`` in TorchRL's
``GymWrapper`` (the base class of ``GymEnv``), reading the scalar info keys along;
``torchrl.envs.GymEnv(env_id)`` works too. With ``num_envs`` it wraps the package's native
vector env (autoreset mode ``DISABLED``, which TorchRL resets by ``reset_mask``).

TorchRL's own pieces work as well: ``GymWrapper`` over the native vector env made with
``autoreset_mode`` ``SAME_STEP`` (TorchRL then reads every info key, and takes an ended step's
observation and info from ``final_obs`` and ``final_info``) or ``DISABLED`` (TorchRL refuses
``NEXT_STEP``), and ``torchrl.envs.libs.gym.default_info_dict_reader(keys)`` over any id: the
info scalars are numpy values of fixed dtypes (float64, int64, 0-d bool arrays) and the
reward terms are also flat keys (``"reward_info_gain"``, ...; see
:mod:`active_loc.envs.outcome`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym

try:
    import torch
    from tensordict import TensorDictBase
    from torchrl.data import Composite, Unbounded
    from torchrl.envs import GymWrapper
    from torchrl.envs.gym_like import BaseInfoDictReader
except ImportError as err:  # pragma: no cover - depends on the installed extras
    raise ImportError(
        'active_loc.integrations.torchrl needs TorchRL: pip install "active-loc[torchrl]"'
    ) from err

__all__ = ["DEFAULT_INFO_KEYS", "InfoReader", "make_torchrl_env"]

#: info entries every ``ActiveLoc`` id has on every step and reset, with their dtypes
DEFAULT_INFO_KEYS: Mapping[str, torch.dtype] = {
    "is_success": torch.bool,
    "localized": torch.bool,
    "pose_error": torch.float32,
    "heading_error": torch.float32,
    "entropy": torch.float32,
    "collisions": torch.int64,
}


class InfoReader(BaseInfoDictReader):
    """Copies named scalar info entries (numpy or Python scalars, or ``(n,)`` arrays of a vector
    env) into the step's tensordict as tensors of the env's batch shape, cast to the given
    dtypes (TorchRL's ``default_info_dict_reader`` keeps the info's own dtypes instead).
    """

    def __init__(self, keys: Mapping[str, torch.dtype], batch_size: torch.Size) -> None:
        self._dtypes = dict(keys)
        self._spec = Composite(
            {key: Unbounded(batch_size, dtype=dtype) for key, dtype in self._dtypes.items()},
            shape=batch_size,
        )

    def __call__(self, info_dict: dict[str, Any], tensordict: TensorDictBase) -> TensorDictBase:
        for key, dtype in self._dtypes.items():
            value = torch.as_tensor(info_dict[key], dtype=dtype)
            tensordict.set(key, value.reshape(tensordict.batch_size))
        return tensordict

    @property
    def info_spec(self) -> Composite:
        return self._spec


def make_torchrl_env(
    env_id: str,
    *,
    num_envs: int | None = None,
    categorical_action_encoding: bool = True,
    info_keys: Sequence[str] | Mapping[str, torch.dtype] | None = None,
    device: str | torch.device = "cpu",
    **env_kwargs: Any,
) -> GymWrapper:
    """An ``ActiveLoc`` id as a TorchRL env.

    Args:
        env_id: an ``ActiveLoc/...`` id.
        num_envs: ``None`` for one env (batch size ``[]``); n >= 1 for the native vector env
            of n sub-envs (batch size ``[n]``; sub-env i of ``reset(seed=s)`` is seeded s + i).
        categorical_action_encoding: discrete actions as an integer index (``Categorical``
            spec, as gymnasium has them) rather than TorchRL's default one-hot vector.
        info_keys: the info entries to copy into every reset and step tensordict: ``None``
            for :data:`DEFAULT_INFO_KEYS`, a sequence of its keys, a mapping of any scalar
            info keys to torch dtypes, or ``()`` for none.
        device: the device of the tensordicts.
        **env_kwargs: keywords of ``gymnasium.make`` (or ``gymnasium.make_vec``), e.g.
            ``action_type="discrete"``, ``max_episode_steps=100``, ``size=15`` for the maze.

    Returns:
        a ``torchrl.envs.GymWrapper`` that passes ``torchrl.envs.utils.check_env_specs``.
    """
    if not isinstance(env_id, str) or not env_id.startswith("ActiveLoc/"):
        raise ValueError(f"env_id must be an ActiveLoc id, got {env_id!r}")
    if num_envs is None:
        env: gym.Env[Any, Any] | gym.vector.VectorEnv[Any, Any, Any] = gym.make(
            env_id, **env_kwargs
        )
    else:
        if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1 or None, got {num_envs!r}")
        if "autoreset_mode" in env_kwargs:
            raise ValueError("make_torchrl_env sets autoreset_mode itself (DISABLED)")
        env = gym.make_vec(
            env_id, num_envs, vectorization_mode="vector_entry_point",
            autoreset_mode=gym.vector.AutoresetMode.DISABLED, **env_kwargs,
        )
    wrapped = GymWrapper(
        env, categorical_action_encoding=categorical_action_encoding, device=device
    )
    if info_keys is None:
        keys: Mapping[str, torch.dtype] = DEFAULT_INFO_KEYS
    elif isinstance(info_keys, Mapping):
        keys = info_keys
    else:
        unknown = [key for key in info_keys if key not in DEFAULT_INFO_KEYS]
        if unknown:
            raise ValueError(
                f"info keys {unknown} have no default dtype; pass a mapping key -> torch dtype "
                f"(the defaults: {list(DEFAULT_INFO_KEYS)})"
            )
        keys = {key: DEFAULT_INFO_KEYS[key] for key in info_keys}
    if keys:
        wrapped.set_info_dict_reader(InfoReader(keys, wrapped.batch_size))
    return wrapped
