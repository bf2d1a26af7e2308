"""``SB3Agent``: a saved stable-baselines3 (or sb3-contrib) model behind the agent interface.

::

    agent = SB3Agent.load("runs/Maze-v0-ppo-0")       # the run folder or its model.zip
    obs, info = env.reset(seed=0)
    action = agent.act(obs, env.unwrapped.planner_view())

stable-baselines3 is imported only when a model is loaded, so importing this module needs
none of the training dependencies.

Model files are trusted input only. A saved model is a zip of pickled Python objects, and
loading one runs whatever code it holds: load only models you trained or got from someone you
trust, as with any pickle.
"""

from __future__ import annotations

import importlib
import json
import os
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

#: algorithm name (as ``active_loc.train`` spells it) -> (module, class)
ALGORITHMS: dict[str, tuple[str, str]] = {
    "ppo": ("stable_baselines3", "PPO"),
    "a2c": ("stable_baselines3", "A2C"),
    "dqn": ("stable_baselines3", "DQN"),
    "sac": ("stable_baselines3", "SAC"),
    "recurrent_ppo": ("sb3_contrib", "RecurrentPPO"),
}

MODEL_FILE = "model.zip"
CONFIG_FILE = "config.json"


def algorithm_class(algo: str) -> Any:
    """The class of ``algo`` (a key of :data:`ALGORITHMS`)."""
    if algo not in ALGORITHMS:
        raise ValueError(f"algo must be one of {sorted(ALGORITHMS)}, got {algo!r}")
    module, name = ALGORITHMS[algo]
    return getattr(importlib.import_module(module), name)


def model_path(path: str | os.PathLike[str]) -> Path:
    """The model file of ``path``: a run folder (its ``model.zip``) or a ``.zip`` file (the
    suffix may be left out, as stable-baselines3 allows)."""
    p = Path(path)
    if p.is_dir():
        p = p / MODEL_FILE
    elif not p.exists() and p.suffix != ".zip" and p.with_suffix(".zip").exists():
        p = p.with_suffix(".zip")
    if not p.is_file():
        raise FileNotFoundError(f"no saved model at {path} (looked for {p})")
    return p


def run_config_args(model_file: Path) -> dict[str, Any]:
    """The ``args`` recorded in the ``config.json`` of the run the model belongs to: next to
    the model, or one folder up (checkpoints/, eval/best_model.zip). Empty if there is none.

    Raises:
        ValueError: the ``config.json`` is not JSON, or not an object with an ``args`` object;
            the message names the file.
    """
    for folder in (model_file.parent, model_file.parent.parent):
        config = folder / CONFIG_FILE
        if config.is_file():
            try:
                data = json.loads(config.read_text(encoding="utf-8"))
            except (UnicodeDecodeError, json.JSONDecodeError) as error:
                raise ValueError(f"{config}: not a JSON run config: {error}") from None
            args = data.get("args", {}) if isinstance(data, dict) else None
            if not isinstance(args, dict):
                raise ValueError(f"{config}: a run config must be a JSON object whose 'args' "
                                 "is an object")
            return dict(args)
    return {}


def _config_file(model_file: Path) -> Path | None:
    for folder in (model_file.parent, model_file.parent.parent):
        if (folder / CONFIG_FILE).is_file():
            return folder / CONFIG_FILE
    return None


def config_algorithm(model_file: Path) -> str | None:
    """The ``algo`` of the model's run (see :func:`run_config_args`), or None when the run
    records none.

    Raises:
        ValueError: the run config names an algorithm that is not one of :data:`ALGORITHMS`.
    """
    algo = run_config_args(model_file).get("algo")
    if algo is None:
        return None
    if algo not in ALGORITHMS:
        raise ValueError(f"{_config_file(model_file)}: algo must be one of "
                         f"{sorted(ALGORITHMS)}, got {algo!r}")
    return str(algo)


def configured_action_repeat(model_file: Path) -> int:
    """The ``action_repeat`` the model's run trained with (see :func:`run_config_args`); 1 for
    runs that do not record one.

    Raises:
        ValueError: the recorded ``action_repeat`` is not an integer >= 1.
    """
    repeat = run_config_args(model_file).get("action_repeat", 1)
    if isinstance(repeat, bool) or not isinstance(repeat, int) or repeat < 1:
        raise ValueError(f"{_config_file(model_file)}: action_repeat must be an integer >= 1, "
                         f"got {repeat!r}")
    return repeat


def load_model(path: str | os.PathLike[str], device: str = "cpu") -> Any:
    """Load a saved model with the class named by its run's ``config.json``; without one,
    try PPO, A2C, DQN, SAC and RecurrentPPO in turn.

    The file is trusted input: loading unpickles what it holds, which can run code."""
    file = model_path(path)
    algo = config_algorithm(file)
    if algo is not None:
        return algorithm_class(algo).load(file, device=device)
    errors = []
    for name in ALGORITHMS:
        try:
            cls = algorithm_class(name)
        except ImportError as error:  # sb3-contrib missing
            errors.append(f"{name}: {error}")
            continue
        try:
            return cls.load(file, device=device)
        except Exception as error:
            errors.append(f"{name}: {type(error).__name__}: {error}")
    raise ValueError(f"{file} could not be loaded by any of {list(ALGORITHMS)}: {errors}")


class SB3Agent:
    """A stable-baselines3 model as an agent: ``act(observation, view) -> action``.

    Args:
        model_or_path: a model object, or the path of a saved model (see :meth:`load`).
        deterministic: take the policy's most likely action instead of sampling.
        device: torch device to load a saved model on.
        action_repeat: hold each action for this many steps, as the model was trained
            (``train.py --action-repeat``): the policy is asked at steps 0, k, 2k, ... of an
            episode. :meth:`load` reads it from the run's ``config.json``.
        seed: seed of the agent's Generator ``rng``, which samples the actions of PPO and A2C
            policies when ``deterministic`` is False (the evaluation gives it a new one each
            episode, so a sampled episode replays exactly). Other policies sample with SB3's
            own ``predict``, from torch's global generator.

    The view (``env.unwrapped.planner_view()``) is not used to choose actions; the policy sees
    only the observation. For recurrent policies (RecurrentPPO) the agent carries the LSTM
    state from step to step and starts a new episode, resetting the state, whenever
    ``view.step == 0`` (the first action after ``env.reset()``). Call :meth:`reset` to start a
    new episode by hand, for views without a ``step``.

    Actions come back in the env's format: an ``int`` for ``Discrete`` spaces, an array of the
    space's shape and dtype otherwise.
    """

    def __init__(
        self, model_or_path: Any, deterministic: bool = True, device: str = "cpu",
        action_repeat: int | None = None, seed: int | None = None,
    ) -> None:
        if isinstance(model_or_path, (str, os.PathLike)):
            file = model_path(model_or_path)
            if action_repeat is None:
                action_repeat = configured_action_repeat(file)
            model_or_path = load_model(file, device=device)
        action_repeat = 1 if action_repeat is None else action_repeat
        if isinstance(action_repeat, bool) or not isinstance(action_repeat, int) or (
            action_repeat < 1
        ):
            raise ValueError(f"action_repeat must be an integer >= 1, got {action_repeat!r}")
        if not hasattr(model_or_path, "predict"):
            raise TypeError(
                f"model_or_path must be a stable-baselines3 model or a path, got "
                f"{type(model_or_path).__name__}"
            )
        self.model = model_or_path
        self.deterministic = deterministic
        self.action_space: spaces.Space = self.model.action_space
        self.recurrent = hasattr(self.model.policy, "lstm_actor")
        self.action_repeat = action_repeat
        self.rng = np.random.default_rng(seed)
        self._own_sampling = not deterministic and _samples_itself(
            self.model.policy, self.action_space
        )
        self._state: Any = None
        self._episode_start = True
        self._held: Any = None  # the action being held
        self._steps = 0  # steps taken in this episode

    @classmethod
    def load(
        cls, path: str | os.PathLike[str], deterministic: bool = True, device: str = "cpu",
        seed: int | None = None,
    ) -> SB3Agent:
        """Load a model saved by ``python train.py``: ``path`` is the run folder, its
        ``model.zip``, or any other saved model of the run (a checkpoint, the best model). The
        algorithm class and the action repeat come from the run's ``config.json``; without
        one, PPO, A2C, DQN, SAC and RecurrentPPO are tried in turn, and actions are not held.

        The model file is trusted input only: loading unpickles its contents, and a crafted
        file runs code. Check the model against an env with :meth:`check_env`."""
        return cls(path, deterministic=deterministic, device=device, seed=seed)

    def check_env(self, env: Any, name: str = "the model") -> None:
        """Refuse an env whose observation or action space differs from the model's, naming
        ``name`` (e.g. the model file) and both spaces.

        Raises:
            ValueError: a space of another type, shape, dtype, bounds or size.
        """
        for what, model_space, env_space in (
            ("observation", self.model.observation_space, env.observation_space),
            ("action", self.action_space, env.action_space),
        ):
            if not _same_space(model_space, env_space):
                raise ValueError(f"{name} was trained on the {what} space {model_space}, but "
                                 f"this env has {env_space}")

    def reset(self) -> None:
        """Forget the recurrent state and the held action: the next action starts a new
        episode."""
        self._state = None
        self._episode_start = True
        self._held = None
        self._steps = 0

    def act(self, observation: Any, view: Any = None) -> Any:
        if getattr(view, "step", None) == 0:
            self.reset()
        if self._steps % self.action_repeat == 0:
            self._held = self._decide(observation)
        self._steps += 1
        return self._held

    def _decide(self, observation: Any) -> Any:
        """The policy's action for ``observation``, in the env's format."""
        if self.recurrent:
            action, self._state = self.model.predict(
                observation,
                state=self._state,
                episode_start=np.array([self._episode_start]),
                deterministic=self.deterministic,
            )
            self._episode_start = False
        elif self._own_sampling:
            action = self._sample(observation)
        else:
            action, _ = self.model.predict(observation, deterministic=self.deterministic)
        space = self.action_space
        if isinstance(space, spaces.Discrete):
            return int(np.asarray(action).reshape(-1)[0])
        return np.asarray(action, dtype=space.dtype).reshape(space.shape)

    def _sample(self, observation: Any) -> np.ndarray:
        """An action drawn with :attr:`rng` from the policy's distribution at
        ``observation``: a category of a Discrete space, or a diagonal Gaussian draw clipped
        to a Box, as SB3's ``predict`` clips it."""
        import torch

        policy = self.model.policy
        obs, _ = policy.obs_to_tensor(observation)
        with torch.no_grad():
            distribution = policy.get_distribution(obs).distribution
        space = self.action_space
        if isinstance(space, spaces.Discrete):
            probs = distribution.probs.reshape(-1).cpu().numpy().astype(np.float64)
            return np.asarray(self.rng.choice(probs.size, p=probs / probs.sum()))
        mean = distribution.mean.reshape(space.shape).cpu().numpy()
        std = distribution.stddev.reshape(space.shape).cpu().numpy()
        return np.clip(mean + std * self.rng.standard_normal(space.shape), space.low, space.high)


def _same_space(a: spaces.Space, b: spaces.Space) -> bool:
    """Whether two spaces take the same values (Box bounds compared to float32 precision)."""
    if type(a) is not type(b) or a.shape != b.shape:
        return False
    if isinstance(a, spaces.Box):
        return bool(a.dtype == b.dtype and np.allclose(a.low, b.low, rtol=1e-6)
                    and np.allclose(a.high, b.high, rtol=1e-6))
    return a == b


def _samples_itself(policy: Any, space: spaces.Space) -> bool:
    """Whether :class:`SB3Agent` draws this policy's actions with its own Generator: PPO and
    A2C policies (not recurrent) over a Discrete space or an unsquashed Box."""
    from stable_baselines3.common.policies import ActorCriticPolicy

    return (
        isinstance(policy, ActorCriticPolicy)
        and not hasattr(policy, "lstm_actor")
        and (isinstance(space, spaces.Discrete)
             or (isinstance(space, spaces.Box) and not policy.squash_output))
    )
