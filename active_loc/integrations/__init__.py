"""Adapters to RL libraries (each imports its library, so import the submodule you need).

* :mod:`active_loc.integrations.sb3`: ``NativeVecEnv``, a stable-baselines3 ``VecEnv`` over the
  package's own vector env, and ``make_native_vec_env``.
"""
