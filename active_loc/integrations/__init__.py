"""Adapters to RL libraries (each imports its library, so import the submodule you need).

* :mod:`active_loc.integrations.sb3`: ``NativeVecEnv``, a stable-baselines3 ``VecEnv`` over the
  package's own vector env, and ``make_native_vec_env``.
* :mod:`active_loc.integrations.timing`: ``VecEnvTimer``, the training envs' share of a run.
* :mod:`active_loc.integrations.torchrl`: ``make_torchrl_env`` (TorchRL ``GymWrapper``, single
  or over the native vector env).
* :mod:`active_loc.integrations.rllib`: ``register_rllib_envs`` (every id for RLlib's
  ``register_env``).
"""
