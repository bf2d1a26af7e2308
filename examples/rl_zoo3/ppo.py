"""rl_zoo3 hyperparameters for PPO on every ``ActiveLoc`` id.

    python -m rl_zoo3.train --algo ppo --env ActiveLoc/LandmarkEKF-v0 \\
        --gym-packages active_loc -conf examples/rl_zoo3/ppo.py

rl_zoo3 runs this file and reads its ``hyperparams``: one entry per registered id, keyed as
``--env`` names it. The values are train.py's PPO defaults (``active_loc.train.ALGO_DEFAULTS``),
so the zoo and train.py train the same agent: 8 envs, 128 steps each per rollout, minibatches
of 256, 4 epochs, learning rate 5e-4, entropy bonus 0.01, gamma 0.99, 64 x 64 networks, no
observation normalization (the observations are already scaled). Maze-v0's (C, H, W) belief
image gets train.py's convolutional extractor (``active_loc.policies.SmallCNN``); rl_zoo3's
``--hyperparams`` overrides any value, e.g. ``--hyperparams n_timesteps:200000``.
"""

from __future__ import annotations

from typing import Any

from active_loc.envs.registration import ALL_ENV_IDS
from active_loc.policies import SmallCNN
from active_loc.train import ALGO_DEFAULTS, TrainArgs

#: env steps per id: about 30 minutes of training on 2 cores
N_TIMESTEPS = {"ActiveLoc/Maze-v0": 2_500_000}
DEFAULT_TIMESTEPS = 1_000_000


def ppo_hyperparams(env_id: str) -> dict[str, Any]:
    """The rl_zoo3 entry of ``env_id``: train.py's PPO defaults in rl_zoo3's keys."""
    defaults, args = ALGO_DEFAULTS["ppo"], TrainArgs()
    policy_kwargs: dict[str, Any] = {"net_arch": list(defaults["net_arch"])}
    policy = "MlpPolicy"
    if env_id == "ActiveLoc/Maze-v0":
        policy = "CnnPolicy"
        policy_kwargs.update(
            features_extractor_class=SmallCNN,
            features_extractor_kwargs={"features_dim": args.features_dim,
                                       "channels": tuple(args.cnn_channels)},
            normalize_images=False,
        )
    return {
        "n_envs": args.n_envs,
        "n_timesteps": N_TIMESTEPS.get(env_id, DEFAULT_TIMESTEPS),
        "policy": policy,
        "policy_kwargs": policy_kwargs,
        "gamma": args.gamma,
        "normalize": False,
        **{key: defaults[key]
           for key in ("learning_rate", "n_steps", "batch_size", "n_epochs", "ent_coef")},
    }


hyperparams = {env_id: ppo_hyperparams(env_id) for env_id in ALL_ENV_IDS}
