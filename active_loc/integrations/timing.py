"""How much of a training run's wall time the env takes: a stable-baselines3 ``VecEnv`` wrapper.

``train.py`` wraps its training envs in :class:`VecEnvTimer` and writes the split into
``config.json`` (``result.env_time``): seconds inside ``reset``/``step`` of the envs (the
simulation, the filters, the observations, Monitor's bookkeeping) against the whole run, whose
rest is the policy (rollout inference, gradient steps) and the callbacks (evaluations,
checkpoints). Evaluation envs are not timed: their time counts as callback time.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper
from stable_baselines3.common.vec_env.base_vec_env import VecEnvObs, VecEnvStepReturn


class VecEnvTimer(VecEnvWrapper):
    """Accumulates the wall time (s) spent in the wrapped envs' ``reset`` and ``step``.

    Attributes:
        env_seconds: total seconds inside the envs so far.
        steps: ``step`` calls so far (each steps every sub-env once).
    """

    def __init__(self, venv: VecEnv) -> None:
        super().__init__(venv)
        self.env_seconds = 0.0
        self.steps = 0

    def reset(self) -> VecEnvObs:
        start = time.perf_counter()
        obs = self.venv.reset()
        self.env_seconds += time.perf_counter() - start
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        start = time.perf_counter()
        self.venv.step_async(actions)
        self.env_seconds += time.perf_counter() - start

    def step_wait(self) -> VecEnvStepReturn:
        start = time.perf_counter()
        result = self.venv.step_wait()
        self.env_seconds += time.perf_counter() - start
        self.steps += 1
        return result

    def split(self, total_seconds: float) -> dict[str, Any]:
        """The env's share of a run that took ``total_seconds``."""
        return {
            "env_s": round(self.env_seconds, 2),
            "total_s": round(total_seconds, 2),
            "env_share": round(self.env_seconds / total_seconds, 4) if total_seconds > 0 else 0.0,
            "env_steps_per_s": round(self.steps * self.num_envs / self.env_seconds, 1)
            if self.env_seconds > 0 else 0.0,
        }
