"""Train a stable-baselines3 agent on an ``ActiveLoc`` env.

``python train.py --help`` (the same as ``active-loc train --help``) lists the arguments, the
fields of :class:`TrainArgs`. For example::

    python train.py --env ActiveLoc/Maze-v0 --algo ppo --total-steps 500000 --n-envs 8
    python train.py --env ActiveLoc/LandmarkEKF-v0 --algo sac --env-kwargs '{"reward": "trace"}'

The output folder (``--out``, default ``runs/<env name>-<algo>-<seed>``) holds:

* ``model.zip``: the final model (load it with :class:`active_loc.agents.sb3.SB3Agent`);
* ``config.json``: the arguments as given, what they resolved to (env kwargs, policy,
  hyperparameters, logged info keys), package versions, and the outcome of the run;
* ``learning_curve.png``: episode return and success rate against timesteps, training
  (Monitor files) and evaluation;
* ``tb/``: tensorboard logs (``tensorboard --logdir runs``); ``monitor/``: one Monitor CSV per
  training env (one for all of them with ``--vec-env native``); ``checkpoints/``: periodic
  checkpoints; ``eval/``: the evaluation env's Monitor CSV, ``evaluations.npz`` and
  ``best_model.zip``.

Evaluations replay the same seeded episodes every time (deterministic actions), so their
success rates compare across the run; SB3's ``EvalCallback`` logs them as
``eval/success_rate``. The env's scalar info keys (``is_success``, ``entropy``,
``pose_error``, ...) are written by the Monitor wrappers and logged as ``rollout/<key>`` and
``eval/<key>`` (means over episodes, values at the episode's last step).
"""

from __future__ import annotations

import csv
import json
import math
import os
import platform
import sys
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from functools import partial
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any, Literal

import gymnasium as gym
import numpy as np
import torch
import tyro
from stable_baselines3.common.callbacks import (
    BaseCallback,
    CallbackList,
    CheckpointCallback,
    EvalCallback,
)
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.utils import set_random_seed
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv

import active_loc
from active_loc.agents.registry import make_agent
from active_loc.agents.sb3 import ALGORITHMS, CONFIG_FILE, MODEL_FILE, algorithm_class
from active_loc.envs.action_repeat import ActionRepeat
from active_loc.envs.localization_env import ActiveLocalizationEnv
from active_loc.envs.registration import ENTRY_POINT, MAZE_ID
from active_loc.envs.vector_engines import batched_core
from active_loc.imitation import ImitationRound, dagger
from active_loc.integrations.sb3 import make_native_vec_env
from active_loc.integrations.timing import VecEnvTimer
from active_loc.policies import BeliefImageExtractor, PooledBeliefCNN, SmallCNN

Algo = Literal["ppo", "a2c", "dqn", "sac", "recurrent_ppo"]

#: the eval env's seed is the training seed plus this (its episodes differ from training's)
EVAL_SEED_OFFSET = 1_000_000
#: the imitation rollouts' seeds are the training seed plus this (and the round)
IMITATION_SEED_OFFSET = 2_000_000
#: the imitation's log, one row per DAgger round (in --out)
IMITATION_LOG = "imitation.csv"
#: the algorithms whose policies :func:`active_loc.imitation.fit` can fit
IMITATING_ALGOS = ("ppo", "a2c")

#: per algorithm, the hyperparameters it takes and their defaults (a ``TrainArgs`` field left
#: at None takes the value here; setting a field the algorithm does not take is an error)
ALGO_DEFAULTS: dict[str, dict[str, Any]] = {
    "ppo": {
        "learning_rate": 5e-4, "n_steps": 128, "batch_size": 256, "n_epochs": 4,
        "ent_coef": 0.01, "net_arch": (64, 64),
    },
    "a2c": {"learning_rate": 7e-4, "n_steps": 5, "ent_coef": 0.01, "net_arch": (64, 64)},
    "dqn": {
        "learning_rate": 1e-4, "batch_size": 64, "buffer_size": 100_000,
        "learning_starts": 1_000, "net_arch": (64, 64),
    },
    "sac": {
        "learning_rate": 3e-4, "batch_size": 256, "buffer_size": 100_000,
        "learning_starts": 1_000, "ent_coef": "auto", "net_arch": (256, 256),
    },
    "recurrent_ppo": {
        "learning_rate": 3e-4, "n_steps": 128, "batch_size": 128, "n_epochs": 10,
        "ent_coef": 0.01, "net_arch": (64, 64),
    },
}

#: the action spaces each algorithm accepts
ALGO_ACTION_SPACES: dict[str, tuple[type[gym.Space], ...]] = {
    "ppo": (gym.spaces.Box, gym.spaces.Discrete, gym.spaces.MultiDiscrete, gym.spaces.MultiBinary),
    "a2c": (gym.spaces.Box, gym.spaces.Discrete, gym.spaces.MultiDiscrete, gym.spaces.MultiBinary),
    "dqn": (gym.spaces.Discrete,),
    "sac": (gym.spaces.Box,),
    "recurrent_ppo": (
        gym.spaces.Box, gym.spaces.Discrete, gym.spaces.MultiDiscrete, gym.spaces.MultiBinary,
    ),
}

#: the ``action_type`` an ``ActiveLocalizationEnv`` id gets when env_kwargs does not set it
AUTO_ACTION_TYPE = {"dqn": "discrete", "sac": "continuous"}

#: info keys logged first when an env has them; its other scalar keys follow
PREFERRED_INFO_KEYS = ("is_success", "entropy", "pose_error", "heading_error", "collisions")


@dataclass
class TrainArgs:
    """Train a stable-baselines3 agent on an ActiveLoc env; writes the model, the config,
    tensorboard logs, checkpoints, evaluations and a learning curve to --out."""

    env: str = "ActiveLoc/Maze-v0"
    """Gymnasium env id (`active-loc envs` lists the ActiveLoc ids)."""
    env_kwargs: str = "{}"
    """Env kwargs as a JSON object, e.g. '{"size": 15}' (dqn/sac set action_type if absent)."""
    algo: Algo = "ppo"
    """PPO, A2C, DQN (Discrete actions), SAC (Box actions); RecurrentPPO (sb3-contrib)."""
    total_steps: int = 200_000
    """Agent steps to train for (summed over the vectorized envs): env steps, or with
    --action-repeat k, decisions of up to k env steps each."""
    n_envs: int = 8
    """Parallel training envs."""
    seed: int = 0
    """Seed of everything: training env i gets seed + i, the eval env seed + 1000000."""
    policy: Literal["auto", "mlp", "cnn"] = "auto"
    """auto: cnn for image observations ((C, H, W): active_loc.policies.SmallCNN; the Dict of
    observation="image": BeliefImageExtractor with MultiInputPolicy), else mlp."""
    out: Path | None = None
    """Output folder; None: runs/<env name>-<algo>-<seed>, e.g. runs/Maze-v0-ppo-0."""
    eval_freq: int = 10_000
    """Evaluate every this many steps (summed over envs); 0: never."""
    eval_episodes: int = 100
    """Episodes per evaluation (the same seeded episodes every time)."""
    checkpoint_freq: int = 50_000
    """Save a checkpoint every this many steps (summed over envs); 0: never."""
    vec_env: Literal["auto", "dummy", "subproc", "native"] = "auto"
    """dummy: the envs in this process; subproc: one process per env; native: the package's
    own vector env (active_loc.integrations.sb3), in this process, one batched kernel call per
    step for the EKF landmark ids, worker threads for the others (one Monitor CSV for all
    training envs); auto: native where it is faster (EKF landmark ids from 8 envs on, MCL and
    grid ids from 2 on, given 2 cores), dummy otherwise."""
    action_repeat: int = 1
    """Hold each action for this many env steps (the agent decides every k steps; the rewards
    are summed). The evaluation agent holds its actions the same way (SB3Agent reads it from
    config.json). Needs vec_env dummy or subproc; auto picks subproc where it would pick
    native for the threads, else dummy."""
    device: str = "cpu"
    """Torch device."""
    torch_threads: int = 1
    """torch.set_num_threads."""
    progress_bar: bool = True
    """Show a progress bar (tqdm + rich)."""
    time_limit_minutes: float | None = None
    """Stop training once this much wall-clock time has passed (None: no limit)."""
    verbose: int = 0
    """Verbosity of the algorithm (0, 1, 2); evaluations are printed in any case."""

    # a warm start by imitation (ppo and a2c): DAgger from a planner, before the RL run
    imitate: str | None = None
    """An agent spec to imitate first (e.g. horizon): rounds of DAgger (active_loc.imitation)
    fit the policy to its actions and the value head to the rollouts' returns; their time
    counts in --time-limit-minutes, and imitation.csv logs each round."""
    imitate_rounds: int = 4
    """DAgger rounds: the planner drives the first, the policy the others."""
    imitate_steps: int = 50_000
    """States labelled by the planner per round."""
    imitate_epochs: int = 4
    """Passes over all the labels so far after each round."""
    imitate_learning_rate: float = 1e-3
    """Adam's step size for the imitation fits."""

    # hyperparameters; None: the algorithm's default (ALGO_DEFAULTS in active_loc/train.py)
    learning_rate: float | None = None
    """None: ppo 5e-4; sac, recurrent_ppo 3e-4; a2c 7e-4; dqn 1e-4."""
    n_steps: int | None = None
    """Rollout length per env; None: ppo and recurrent_ppo 128, a2c 5."""
    batch_size: int | None = None
    """Minibatch; None: ppo 256 (<= n_steps * n_envs), recurrent_ppo 128, dqn 64, sac 256."""
    n_epochs: int | None = None
    """Epochs per rollout; None: ppo 4, recurrent_ppo 10."""
    gamma: float = 0.99
    """Discount factor."""
    ent_coef: float | None = None
    """Entropy coefficient; None: ppo, a2c, recurrent_ppo 0.01; sac learns it ("auto")."""
    net_arch: tuple[int, ...] | None = None
    """Hidden layers of the policy, value and Q networks; None: 64 64 (sac 256 256)."""
    cnn: Literal["flat", "pooled"] = "flat"
    """Extractor of cnn policies. flat: SmallCNN (convolutions, flattened, a linear layer);
    pooled: PooledBeliefCNN (belief rescaled, convolutions, mean and max over the map: any
    maze size, fewer weights to learn on large mazes)."""
    cnn_channels: tuple[int, ...] = (16, 32, 32)
    """Output channels of the CNN's 3x3 convolutions, one per layer (cnn policies)."""
    features_dim: int = 128
    """Output size of the CNN features extractor (cnn policies)."""
    buffer_size: int | None = None
    """Replay buffer size of dqn and sac; None: 100000."""
    learning_starts: int | None = None
    """Steps collected before dqn and sac start learning; None: 1000."""


class TrainConfigError(ValueError):
    """Arguments that cannot work together (reported without a traceback by :func:`main`)."""


# --- resolving the arguments -------------------------------------------------------------------


def parse_env_kwargs(text: str) -> dict[str, Any]:
    """The ``--env-kwargs`` JSON object as a dict."""
    try:
        value = json.loads(text)
    except json.JSONDecodeError as error:
        raise TrainConfigError(f"env_kwargs must be a JSON object, got {text!r}: {error}") from None
    if not isinstance(value, dict):
        raise TrainConfigError(f"env_kwargs must be a JSON object, got {text!r}")
    return value


def resolve_env_kwargs(env_id: str, env_kwargs: dict[str, Any], algo: str) -> dict[str, Any]:
    """``env_kwargs`` plus the ``action_type`` that ``algo`` needs, for the ids served by
    ``ActiveLocalizationEnv`` when the user did not set one."""
    try:
        spec = gym.spec(env_id)
    except gym.error.Error as error:
        ids = ", ".join(sorted(i for i in gym.registry if i.startswith("ActiveLoc/")))
        raise TrainConfigError(
            f"unknown env id {env_id!r} ({error}); ActiveLoc ids: {ids}"
        ) from None
    kwargs = dict(env_kwargs)
    if "action_type" not in kwargs and spec.entry_point == ENTRY_POINT and algo in AUTO_ACTION_TYPE:
        kwargs["action_type"] = AUTO_ACTION_TYPE[algo]
    return kwargs


def make_env(env_id: str, **kwargs: Any) -> gym.Env:
    """``gym.make(env_id, **kwargs)`` after registering the ids (also in subprocesses)."""
    import active_loc  # noqa: F401

    return gym.make(env_id, **kwargs)


def _is_scalar(value: Any) -> bool:
    """Python and numpy scalars, and 0-d arrays (the env's flags)."""
    if isinstance(value, np.ndarray):
        return value.ndim == 0
    return isinstance(value, (bool, int, float, np.bool_, np.number))


def probe_env(
    env_id: str, kwargs: dict[str, Any], seed: int
) -> tuple[gym.Space, gym.Space, tuple[str, ...]]:
    """Make one env and run one step: its observation space, its action space and the
    info keys with scalar values (for Monitor's ``info_keywords``)."""
    try:
        env = make_env(env_id, **kwargs)
    except (ValueError, TypeError) as error:
        raise TrainConfigError(f"{env_id} with env_kwargs {kwargs}: {error}") from None
    try:
        _, reset_info = env.reset(seed=seed)
        env.action_space.seed(seed)
        _, _, _, _, info = env.step(env.action_space.sample())
        observation_space, action_space = env.observation_space, env.action_space
    finally:
        env.close()
    scalar = [k for k, v in info.items() if _is_scalar(v) and _is_scalar(reset_info.get(k))]
    keys = [k for k in PREFERRED_INFO_KEYS if k in scalar]
    keys += [k for k in scalar if k not in keys]
    return observation_space, action_space, tuple(keys)


def check_algorithm(
    algo: str, env_id: str, kwargs: dict[str, Any], action_space: gym.Space
) -> None:
    """Raise a clear error when ``algo`` cannot act in ``action_space``."""
    allowed = ALGO_ACTION_SPACES[algo]
    if isinstance(action_space, allowed):
        return
    name = ALGORITHMS[algo][1]
    need = " or ".join(cls.__name__ for cls in allowed)
    able = [a for a, spaces in ALGO_ACTION_SPACES.items() if isinstance(action_space, spaces)]
    hint = f"algorithms for {action_space}: {', '.join(able)}"
    if env_id == MAZE_ID:
        hint = f"{env_id} has discrete actions only; {hint}"
    elif "action_type" in kwargs:
        hint += f"; or change action_type={kwargs['action_type']!r} in env_kwargs"
    raise TrainConfigError(
        f"{name} ({algo}) needs a {need} action space, but {env_id} with env_kwargs {kwargs} "
        f"has {action_space} ({hint})"
    )


def is_image_space(space: gym.Space) -> bool:
    """A ``Box`` of rank 3, read as a channels-first image ``(C, H, W)``."""
    return isinstance(space, gym.spaces.Box) and len(space.shape) == 3


def is_belief_image_space(space: gym.Space) -> bool:
    """The ``Dict`` of ``observation="image"``: a belief image and the observation vector."""
    return (isinstance(space, gym.spaces.Dict) and set(space.spaces) == {"image", "vector"}
            and is_image_space(space["image"]))


def resolve_policy(
    args: TrainArgs, observation_space: gym.Space
) -> tuple[str, str, dict[str, Any]]:
    """``("mlp" | "cnn", the policy class name, policy_kwargs)``: a ``Dict`` observation
    takes SB3's ``MultiInputPolicy``, with :class:`~active_loc.policies.BeliefImageExtractor`
    when it is a belief image (``cnn``) or SB3's flattening extractor (``mlp``)."""
    multi = is_belief_image_space(observation_space)
    image = multi or is_image_space(observation_space)
    kind = ("cnn" if image else "mlp") if args.policy == "auto" else args.policy
    if kind == "cnn" and not image:
        raise TrainConfigError(
            f"policy 'cnn' needs an image observation space (C, H, W) or a belief image "
            f"(observation='image'), but {args.env} has {observation_space}; use --policy mlp "
            "(or auto)"
        )
    net_arch = args.net_arch if args.net_arch is not None else ALGO_DEFAULTS[args.algo]["net_arch"]
    policy_kwargs: dict[str, Any] = {"net_arch": list(net_arch)}
    if kind == "cnn" and multi:
        policy_kwargs.update(
            features_extractor_class=BeliefImageExtractor,
            features_extractor_kwargs={
                "features_dim": args.features_dim,
                "channels": tuple(args.cnn_channels),
            },
            normalize_images=False,
        )
    elif kind == "cnn":
        policy_kwargs.update(
            features_extractor_class=SmallCNN if args.cnn == "flat" else PooledBeliefCNN,
            features_extractor_kwargs={
                "features_dim": args.features_dim,
                "channels": tuple(args.cnn_channels),
            },
            normalize_images=False,
        )
    base = "MultiInput" if multi else "Cnn" if kind == "cnn" else "Mlp"
    name = f"{base}LstmPolicy" if args.algo == "recurrent_ppo" else f"{base}Policy"
    return kind, name, policy_kwargs


HYPERPARAMETERS = ("learning_rate", "n_steps", "batch_size", "n_epochs", "ent_coef",
                   "buffer_size", "learning_starts")


def resolve_hyperparameters(args: TrainArgs) -> dict[str, Any]:
    """The keyword arguments of the algorithm's constructor (besides policy, env, seed)."""
    defaults = ALGO_DEFAULTS[args.algo]
    name = ALGORITHMS[args.algo][1]
    hyper: dict[str, Any] = {"gamma": args.gamma}
    for key in HYPERPARAMETERS:
        value = getattr(args, key)
        if key not in defaults:
            if value is not None:
                takes = sorted(k for k in defaults if k != "net_arch")
                raise TrainConfigError(
                    f"{name} has no hyperparameter {key!r} (set only {takes} and gamma)"
                )
            continue
        hyper[key] = defaults[key] if value is None else value
    if args.algo in ("ppo", "recurrent_ppo"):
        # a minibatch larger than the rollout would just be the whole rollout
        hyper["batch_size"] = min(hyper["batch_size"], hyper["n_steps"] * args.n_envs)
    return hyper


def check_args(args: TrainArgs) -> None:
    """Ranges of the numeric arguments."""
    checks = [
        ("seed", args.seed >= 0, ">= 0 (numpy and torch take no negative seed)"),
        ("total_steps", args.total_steps >= 1, ">= 1"),
        ("n_envs", args.n_envs >= 1, ">= 1"),
        ("action_repeat", args.action_repeat >= 1, ">= 1"),
        ("eval_freq", args.eval_freq >= 0, ">= 0"),
        ("eval_episodes", args.eval_episodes >= 1, ">= 1"),
        ("checkpoint_freq", args.checkpoint_freq >= 0, ">= 0"),
        ("torch_threads", args.torch_threads >= 1, ">= 1"),
        ("gamma", math.isfinite(args.gamma) and 0.0 < args.gamma <= 1.0, "in (0, 1]"),
        ("features_dim", args.features_dim >= 1, ">= 1"),
        ("cnn_channels", len(args.cnn_channels) >= 1 and min(args.cnn_channels) >= 1,
         "one or more sizes >= 1"),
        ("time_limit_minutes", args.time_limit_minutes is None or args.time_limit_minutes > 0,
         "> 0 or None"),
        ("learning_rate", args.learning_rate is None or 0 < args.learning_rate < math.inf,
         "a finite number > 0"),
        ("n_steps", args.n_steps is None or args.n_steps >= 1, ">= 1"),
        ("batch_size", args.batch_size is None or args.batch_size >= 2, ">= 2"),
        ("n_epochs", args.n_epochs is None or args.n_epochs >= 1, ">= 1"),
        ("ent_coef", args.ent_coef is None or 0 <= args.ent_coef < math.inf,
         "a finite number >= 0"),
        ("net_arch", args.net_arch is None or all(n >= 1 for n in args.net_arch), "sizes >= 1"),
        ("buffer_size", args.buffer_size is None or args.buffer_size >= 1, ">= 1"),
        ("learning_starts", args.learning_starts is None or args.learning_starts >= 0, ">= 0"),
        ("imitate_rounds", args.imitate_rounds >= 1, ">= 1"),
        ("imitate_steps", args.imitate_steps >= 1, ">= 1"),
        ("imitate_epochs", args.imitate_epochs >= 1, ">= 1"),
        ("imitate_learning_rate",
         math.isfinite(args.imitate_learning_rate) and args.imitate_learning_rate > 0,
         "a finite number > 0"),
    ]
    for field, ok, allowed in checks:
        if not ok:
            raise TrainConfigError(f"{field} must be {allowed}, got {getattr(args, field)!r}")
    if args.imitate is not None:
        if args.algo not in IMITATING_ALGOS:
            raise TrainConfigError(
                f"imitate needs an actor-critic policy ({', '.join(IMITATING_ALGOS)}), got "
                f"algo {args.algo}")
        if args.action_repeat > 1:
            raise TrainConfigError(
                f"imitate labels every env step, so it cannot run with action_repeat "
                f"{args.action_repeat}")
    check_device(args.device)


def check_device(device: str) -> None:
    """``device`` is a torch device this machine has: "cuda" without a GPU would otherwise
    train on the CPU while the run records "cuda"."""
    try:
        parsed = torch.device(device)
    except (RuntimeError, TypeError):
        raise TrainConfigError(f"device {device!r} is not a torch device: use cpu, cuda "
                               "or mps") from None
    if parsed.type == "cuda" and not torch.cuda.is_available():
        raise TrainConfigError(f"device {device!r}: torch sees no CUDA GPU on this machine "
                               "(use --device cpu)")
    if parsed.type == "mps" and not torch.backends.mps.is_available():
        raise TrainConfigError(f"device {device!r}: torch has no MPS backend on this machine")
    if parsed.type not in ("cpu", "cuda", "mps"):
        raise TrainConfigError(f"device {device!r}: use cpu, cuda or mps")


def make_out_folder(out: Path) -> None:
    """Create the run folder ``out``, refusing a file or a place that cannot be written before
    any training."""
    if out.exists() and not out.is_dir():
        raise TrainConfigError(f"out {out}: is a file, not a folder for the run")
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / ".write_test"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as error:
        raise TrainConfigError(f"out {out}: cannot write the run there: "
                               f"{error.strerror or error}") from None


def default_out(args: TrainArgs) -> Path:
    """``runs/<env name>-<algo>-<seed>``, the env name without its namespace."""
    return Path("runs") / f"{args.env.split('/')[-1]}-{args.algo}-{args.seed}"


def package_versions() -> dict[str, str]:
    names = ("active-loc", "stable-baselines3", "sb3-contrib", "torch", "gymnasium", "numpy",
             "tyro")
    versions = {"python": platform.python_version()}
    for name in names:
        try:
            versions[name] = version(name)
        except PackageNotFoundError:
            versions[name] = "not installed"
    versions["active_loc.__version__"] = active_loc.__version__
    return versions


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, type):
        return f"{value.__module__}.{value.__qualname__}"
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, (np.bool_, np.number)):
        return value.item()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return repr(value)


# --- callbacks ---------------------------------------------------------------------------------


class TimeLimitCallback(BaseCallback):
    """Stops training once ``minutes`` of wall-clock time have passed since it started."""

    def __init__(self, minutes: float) -> None:
        super().__init__()
        self.seconds = 60.0 * minutes
        self.start = 0.0
        self.stopped = False

    def _on_training_start(self) -> None:
        self.start = time.perf_counter()

    def _on_step(self) -> bool:
        if time.perf_counter() - self.start >= self.seconds:
            self.stopped = True
            return False
        return True


class InfoMetricsCallback(BaseCallback):
    """Logs ``rollout/<key>``: the mean over the recent training episodes (the algorithm's
    episode buffer, filled by Monitor) of each info keyword. ``is_success`` is already logged
    by stable-baselines3 as ``rollout/success_rate``."""

    def __init__(self, info_keywords: Sequence[str]) -> None:
        super().__init__()
        self.info_keywords = [k for k in info_keywords if k != "is_success"]

    def _on_step(self) -> bool:
        return True

    def _on_rollout_end(self) -> None:
        episodes = self.model.ep_info_buffer or []
        for key in self.info_keywords:
            values = [float(ep[key]) for ep in episodes if key in ep]
            if values:
                self.logger.record(f"rollout/{key}", float(np.mean(values)))


class ReplayEvalCallback(EvalCallback):
    """``EvalCallback`` that reseeds the eval env before every evaluation, so each one plays
    the same episodes, and that also logs ``eval/<key>``: the mean over the evaluation's
    episodes of each info keyword's value at the episode's last step."""

    def __init__(
        self, eval_env: Any, *, eval_seed: int, info_keywords: Sequence[str], **kwargs: Any
    ) -> None:
        super().__init__(eval_env, **kwargs)
        self.eval_seed = eval_seed
        self.info_keywords = [k for k in info_keywords if k != "is_success"]
        self._values: dict[str, list[float]] = {}

    def _on_step(self) -> bool:
        if self.eval_freq > 0 and self.n_calls % self.eval_freq == 0:
            self.eval_env.seed(self.eval_seed)
            self._values = {key: [] for key in self.info_keywords}
        return super()._on_step()

    def _log_success_callback(self, locals_: dict[str, Any], globals_: dict[str, Any]) -> None:
        super()._log_success_callback(locals_, globals_)
        if not locals_["done"]:
            return
        info = locals_["info"]
        for key, values in self._values.items():
            if key in info:
                values.append(float(info[key]))
                self.logger.record(f"eval/{key}", float(np.mean(values)))


# --- the learning curve ------------------------------------------------------------------------


def read_monitor_files(folder: Path) -> dict[str, np.ndarray]:
    """The episodes of every ``*.monitor.csv`` in ``folder``, in the order they ended:
    ``timesteps`` (cumulative steps at each episode's end), ``return`` and, when logged,
    ``success``."""
    rows: list[tuple[float, float, int, float]] = []
    for file in sorted(folder.glob("*.monitor.csv")):
        with file.open() as handle:
            handle.readline()  # the JSON header line
            for row in csv.DictReader(handle):
                success = row.get("is_success")
                value = float("nan") if success is None else float(success in ("True", "1"))
                rows.append((float(row["t"]), float(row["r"]), int(row["l"]), value))
    rows.sort(key=lambda r: r[0])
    table = np.array(rows, dtype=np.float64).reshape(-1, 4)
    return {
        "timesteps": np.cumsum(table[:, 2]),
        "return": table[:, 1],
        "success": table[:, 3],
    }


def moving_average(values: np.ndarray, window: int) -> np.ndarray:
    """Mean of the last ``window`` values at each index (fewer at the start)."""
    if values.size == 0:
        return values
    total = np.cumsum(np.concatenate([[0.0], values]))
    index = np.arange(1, values.size + 1)
    start = np.maximum(index - window, 0)
    return (total[index] - total[start]) / (index - start)


def plot_learning_curve(out: Path, title: str, window: int = 100) -> Path:
    """``out/learning_curve.png``: episode return and success rate against timesteps, from
    the training Monitor files (moving average over ``window`` episodes) and from the
    evaluations (mean, and the spread of the returns)."""
    from matplotlib.figure import Figure  # no pyplot: no global backend state

    train = read_monitor_files(out / "monitor")
    eval_file = out / "eval" / "evaluations.npz"
    fig = Figure(figsize=(8, 6), constrained_layout=True)
    ax_return, ax_success = fig.subplots(2, 1, sharex=True)
    if train["timesteps"].size:
        ax_return.plot(train["timesteps"], moving_average(train["return"], window),
                       label=f"training (mean of last {window} episodes)")
        if not np.isnan(train["success"]).all():
            ax_success.plot(train["timesteps"], moving_average(train["success"], window),
                            label="training")
    if eval_file.is_file():
        with np.load(eval_file) as data:
            steps, results = data["timesteps"], data["results"]
            successes = data["successes"] if "successes" in data else None
        if steps.size:
            mean, std = results.mean(axis=1), results.std(axis=1)
            (line,) = ax_return.plot(steps, mean, "o-", label="evaluation (mean, std)")
            ax_return.fill_between(steps, mean - std, mean + std, color=line.get_color(),
                                   alpha=0.2)
            if successes is not None:
                ax_success.plot(steps, successes.mean(axis=1), "o-", label="evaluation")
    ax_return.set_ylabel("episode return")
    ax_success.set_ylabel("success rate")
    ax_success.set_ylim(-0.02, 1.02)
    ax_success.set_xlabel("timesteps")
    for ax in (ax_return, ax_success):
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="best", fontsize=8)
        else:
            ax.text(0.5, 0.5, "no finished episodes", ha="center", va="center",
                    transform=ax.transAxes)
    fig.suptitle(title)
    path = out / "learning_curve.png"
    fig.savefig(path, dpi=110)
    return path


def eval_summary(out: Path) -> dict[str, Any] | None:
    """The last and the best evaluation of ``out/eval/evaluations.npz`` (None if none)."""
    eval_file = out / "eval" / "evaluations.npz"
    if not eval_file.is_file():
        return None
    with np.load(eval_file) as data:
        steps, results = data["timesteps"], data["results"]
        successes = data["successes"].mean(axis=1) if "successes" in data else None
    if steps.size == 0:
        return None
    returns = results.mean(axis=1)
    summary: dict[str, Any] = {
        "evaluations": int(steps.size),
        "episodes": int(results.shape[1]),
        "last_timesteps": int(steps[-1]),
        "last_mean_return": float(returns[-1]),
    }
    if successes is not None:
        best = int(np.argmax(successes))
        summary.update(
            last_success_rate=float(successes[-1]),
            best_success_rate=float(successes[best]),
            best_timesteps=int(steps[best]),
        )
    return summary


# --- training ----------------------------------------------------------------------------------


#: from this many training envs on, "auto" picks the native vector env for the batched ids
NATIVE_MIN_ENVS = 8
#: beliefs whose steps take milliseconds in kernels that release the GIL: the native vector
#: env's worker threads run two of them at once on two cores
THREADED_BELIEFS = ("mcl",)


def resolve_vec_env(
    vec_env: str, env_id: str, env_kwargs: dict[str, Any], n_envs: int = NATIVE_MIN_ENVS,
    action_repeat: int = 1,
) -> str:
    """``"auto"`` resolved to ``"native"`` where the package's vector env is faster, else
    ``"dummy"``:

    * the EKF ids, whose vector env steps the batch in one kernel call, from
      :data:`NATIVE_MIN_ENVS` envs on. Through SB3's API the native env took 13.8% of PPO's
      wall time at 8 envs against 24.4% for ``DummyVecEnv``, and 9.4% against 33.5% at 256;
    * the grid Markov ids, whose members' beliefs are stepped together, from 2 envs on;
    * the particle filters from 2 envs on, on a machine with 2 cores or more: their
      worker threads step two envs at once (PPO on ``LandmarkMCL-v0`` with 8 envs: 141
      steps/s against 81 with ``DummyVecEnv``). See docs/performance.md.

    The native env steps every sub-env at every call, so it cannot hold actions: with
    ``action_repeat`` > 1, ``"native"`` is an error and ``"auto"`` picks ``"subproc"`` (two
    cores by processes) where it would have picked native for the threads, else ``"dummy"``.
    """
    if action_repeat > 1 and vec_env == "native":
        raise TrainConfigError(
            f"vec_env native cannot hold actions; use dummy or subproc with action_repeat "
            f"{action_repeat}"
        )
    if vec_env != "auto":
        return vec_env
    speed_up = _native_speed_up(env_id, env_kwargs, n_envs)
    if speed_up is None:
        return "dummy"
    if action_repeat > 1:
        return "subproc" if speed_up == "threads" else "dummy"
    return "native"


def _native_speed_up(env_id: str, env_kwargs: dict[str, Any], n_envs: int) -> str | None:
    """Why the native vector env is faster for ``n_envs`` of this env: ``"kernel"`` (one
    batched kernel call), ``"threads"`` (worker threads), or None where it is not."""
    if not env_id.startswith("ActiveLoc/") or n_envs < 2:
        return None
    env = make_env(env_id, **env_kwargs)
    try:
        unwrapped = env.unwrapped
        # MCL: the core's worker threads run two members' filters at once on two cores
        if (isinstance(unwrapped, ActiveLocalizationEnv)
                and unwrapped.config.belief in THREADED_BELIEFS):
            return "threads" if (os.cpu_count() or 1) >= 2 else None
        if batched_core(unwrapped):
            # a grid Markov member is milliseconds of kernels: batching pays from 2 on
            grid = unwrapped.config.belief == "grid"
            return "kernel" if grid or n_envs >= NATIVE_MIN_ENVS else None
        return None
    finally:
        env.close()


def make_train_envs(
    args: TrainArgs, env_kwargs: dict[str, Any], info_keywords: tuple[str, ...], out: Path,
    eval_seed: int, vec_mode: str,
) -> tuple[VecEnv, VecEnv]:
    """The training envs (``args.n_envs``, seeded ``args.seed + i``) and the eval env (one,
    seeded ``eval_seed``), both monitored: Monitor CSVs in ``out/monitor`` and ``out/eval``."""
    if vec_mode == "native":
        # VecMonitor over the vector env: one CSV ("0.monitor.csv") for all its sub-envs
        vec_env = make_native_vec_env(
            args.env, args.n_envs, seed=args.seed, env_kwargs=env_kwargs, monitor=True,
            info_keywords=info_keywords, monitor_file=str(out / "monitor" / "0"),
        )
        eval_env = make_native_vec_env(
            args.env, 1, seed=eval_seed, env_kwargs=env_kwargs, monitor=True,
            info_keywords=info_keywords, monitor_file=str(out / "eval" / "0"),
        )
        return vec_env, eval_env
    vec_env_cls = SubprocVecEnv if vec_mode == "subproc" else DummyVecEnv
    env_fn = partial(make_env, args.env)
    # make_vec_env wraps Monitor first, so its episode lengths count env steps
    common = {
        "env_kwargs": env_kwargs, "monitor_kwargs": {"info_keywords": info_keywords},
        "vec_env_cls": vec_env_cls,
        "wrapper_class": ActionRepeat if args.action_repeat > 1 else None,
        "wrapper_kwargs": {"repeat": args.action_repeat},
    }
    vec_env = make_vec_env(
        env_fn, n_envs=args.n_envs, seed=args.seed, monitor_dir=str(out / "monitor"), **common
    )
    eval_env = make_vec_env(
        env_fn, n_envs=1, seed=eval_seed, monitor_dir=str(out / "eval"), **common
    )
    return vec_env, eval_env


def train(args: TrainArgs) -> Path:
    """Train as ``args`` say; returns the output folder."""
    check_args(args)
    env_kwargs = resolve_env_kwargs(args.env, parse_env_kwargs(args.env_kwargs), args.algo)
    observation_space, action_space, info_keywords = probe_env(args.env, env_kwargs, args.seed)
    check_algorithm(args.algo, args.env, env_kwargs, action_space)
    check_imitation(args, env_kwargs, observation_space)
    policy_kind, policy, policy_kwargs = resolve_policy(args, observation_space)
    hyper = resolve_hyperparameters(args)
    algo_cls = algorithm_class(args.algo)
    out = args.out if args.out is not None else default_out(args)
    vec_mode = resolve_vec_env(
        args.vec_env, args.env, env_kwargs, args.n_envs, args.action_repeat
    )
    make_out_folder(out)

    # seeding: python, numpy and torch here; the algorithm (seed), the training envs
    # (seed + i) and the eval env (seed + EVAL_SEED_OFFSET, replayed at every evaluation)
    set_random_seed(args.seed)
    torch.set_num_threads(args.torch_threads)
    eval_seed = args.seed + EVAL_SEED_OFFSET

    config: dict[str, Any] = {
        "args": _jsonable(asdict(args)),
        "resolved": _jsonable({
            "out": out,
            "env_kwargs": env_kwargs,
            "algorithm": f"{algo_cls.__module__.split('.')[0]}.{algo_cls.__name__}",
            "policy": policy,
            "policy_kind": policy_kind,
            "policy_kwargs": policy_kwargs,
            "hyperparameters": hyper,
            "info_keywords": info_keywords,
            "observation_space": str(observation_space),
            "action_space": str(action_space),
            "eval_seed": eval_seed,
            "vec_env": vec_mode,
        }),
        "versions": package_versions(),
    }
    config_file = out / CONFIG_FILE
    config_file.write_text(json.dumps(config, indent=2) + "\n")

    vec_env, eval_env = make_train_envs(
        args, env_kwargs, info_keywords, out, eval_seed, vec_mode
    )
    timer = VecEnvTimer(vec_env)
    vec_env = timer
    # the same wrapper type on the eval env (untimed), or EvalCallback warns of a mismatch
    eval_env = VecEnvTimer(eval_env)

    model = algo_cls(
        policy, vec_env, policy_kwargs=policy_kwargs, seed=args.seed, device=args.device,
        tensorboard_log=str(out / "tb"), verbose=args.verbose, **hyper,
    )
    callbacks: list[BaseCallback] = [InfoMetricsCallback(info_keywords)]
    if args.checkpoint_freq > 0:
        callbacks.append(CheckpointCallback(
            save_freq=max(args.checkpoint_freq // args.n_envs, 1),
            save_path=str(out / "checkpoints"), name_prefix="model",
        ))
    if args.eval_freq > 0:
        callbacks.append(ReplayEvalCallback(
            eval_env, eval_seed=eval_seed, info_keywords=info_keywords,
            eval_freq=max(args.eval_freq // args.n_envs, 1), n_eval_episodes=args.eval_episodes,
            log_path=str(out / "eval"), best_model_save_path=str(out / "eval"),
            deterministic=True, verbose=1,
        ))
    time_limit = None
    if args.time_limit_minutes is not None:
        time_limit = TimeLimitCallback(args.time_limit_minutes)
        callbacks.append(time_limit)

    start = time.perf_counter()
    imitation = None
    if args.imitate is not None:
        imitation = warm_start(model, args, env_kwargs, out, start)
        if time_limit is not None:  # the imitation's time counts in the limit
            time_limit.seconds = max(1e-3, time_limit.seconds - (time.perf_counter() - start))
    print(
        f"training {algo_cls.__name__} ({policy}) on {args.env} {env_kwargs} for "
        f"{args.total_steps} steps with {args.n_envs} envs -> {out}"
    )
    learn_start = time.perf_counter()
    try:
        model.learn(
            total_timesteps=args.total_steps, callback=CallbackList(callbacks),
            progress_bar=args.progress_bar, tb_log_name=args.algo,
        )
    finally:
        vec_env.close()
        eval_env.close()
    seconds = time.perf_counter() - start  # the imitation included
    learn_seconds = time.perf_counter() - learn_start
    model_file = out / MODEL_FILE
    model.save(model_file)
    kwargs_text = f" {json.dumps(env_kwargs)}" if env_kwargs else ""
    curve = plot_learning_curve(
        out, f"{algo_cls.__name__} on {args.env}{kwargs_text} (seed {args.seed})"
    )
    evaluation = eval_summary(out)
    stopped = time_limit is not None and time_limit.stopped
    config["result"] = {
        "timesteps": int(model.num_timesteps),
        "wall_time_s": round(seconds, 2),
        "stopped_by_time_limit": stopped,
        "env_time": timer.split(learn_seconds),  # the RL run's
        "eval": evaluation,
    }
    if imitation is not None:
        config["result"]["imitation"] = [asdict(row) for row in imitation]
    config_file.write_text(json.dumps(config, indent=2) + "\n")

    reason = " (stopped by the time limit)" if stopped else ""
    held = f" of up to {args.action_repeat} env steps each" if args.action_repeat > 1 else ""
    print(f"trained {model.num_timesteps} steps{held} in {seconds / 60:.1f} min{reason}; "
          f"{100 * timer.env_seconds / learn_seconds:.1f}% of the RL run in the training envs")
    if evaluation is not None:
        line = (
            f"evaluation ({evaluation['episodes']} episodes, {evaluation['evaluations']} times): "
            f"last mean return {evaluation['last_mean_return']:.3f}"
        )
        if "last_success_rate" in evaluation:
            line += (
                f", last success rate {evaluation['last_success_rate']:.3f}, best "
                f"{evaluation['best_success_rate']:.3f} at step {evaluation['best_timesteps']}"
            )
        print(line)
    print(f"model: {model_file}")
    print(f"config: {config_file}")
    print(f"learning curve: {curve}")
    print(f"tensorboard: tensorboard --logdir {out / 'tb'}")
    return out


def check_imitation(args: TrainArgs, env_kwargs: dict[str, Any],
                    observation_space: gym.Space) -> None:
    """``args.imitate`` names an agent that can drive the env, whose observation the fit
    can batch (a Box)."""
    if args.imitate is None:
        return
    if not isinstance(observation_space, gym.spaces.Box):
        raise TrainConfigError(
            f"imitate needs a Box observation, got {type(observation_space).__name__}")
    probe = make_env(args.env, **env_kwargs)
    try:
        make_agent(args.imitate, probe, seed=args.seed)
    except ValueError as error:
        raise TrainConfigError(f"imitate {args.imitate!r}: {error}") from None
    finally:
        probe.close()


def warm_start(model: Any, args: TrainArgs, env_kwargs: dict[str, Any], out: Path,
               start: float) -> list[ImitationRound]:
    """DAgger of ``model``'s policy from the agent ``args.imitate`` (:func:`dagger`), on
    envs like the training envs seeded from ``args.seed + IMITATION_SEED_OFFSET``; no round
    starts after the time limit (counted from ``start``)."""
    spec = args.imitate
    assert spec is not None
    deadline = None
    if args.time_limit_minutes is not None:
        deadline = start + 60.0 * args.time_limit_minutes
    print(f"imitating {spec}: {args.imitate_rounds} rounds of {args.imitate_steps} states")
    rounds = dagger(
        model.policy, lambda: make_env(args.env, **env_kwargs),
        lambda env: make_agent(spec, env, seed=args.seed), args.imitate_rounds,
        args.imitate_steps, args.imitate_epochs, args.imitate_learning_rate, args.gamma,
        args.seed + IMITATION_SEED_OFFSET, out / IMITATION_LOG, deadline,
    )
    for row in rounds:
        agreement = "" if row.agreement is None else f"agreement {row.agreement:.3f}, "
        print(f"  round {row.round} ({row.driver} drove): {agreement}nll {row.nll:.4f}, "
              f"value mse {row.value_mse:.4f}, {row.seconds:.0f} s")
    return rounds


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> Path:
    """Parse the arguments with tyro and train; argument errors exit with status 2."""
    args = tyro.cli(TrainArgs, args=argv, prog=prog)
    try:
        return train(args)
    except TrainConfigError as error:
        print(f"{prog or 'train.py'}: error: {error}", file=sys.stderr)
        raise SystemExit(2) from None
