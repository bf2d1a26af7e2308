"""The examples run: ``examples/cleanrl_ppo.py`` trains a few updates and prints its summary;
rl_zoo3 trains with ``examples/rl_zoo3/ppo.py``."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import pytest

pytest.importorskip("torch")
pytest.importorskip("tyro")

ROOT = Path(__file__).resolve().parents[1]
CLEANRL_PPO = ROOT / "examples" / "cleanrl_ppo.py"
SUMMARY = re.compile(
    r"^summary: steps (\d+) wall_time [\d.]+s SPS \d+ final_return (\S+) "
    r"final_success_rate (\S+) \(last (\d+) episodes\)$",
    re.MULTILINE,
)


def _run(tmp_path: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(CLEANRL_PPO), "--env-id", "ActiveLoc/LandmarkEKF-v0",
         "--total-timesteps", "2048", "--num-envs", "8", "--num-steps", "64",
         "--update-epochs", "2", "--log-every", "1", *extra],
        capture_output=True, text=True, timeout=300, check=False, cwd=tmp_path,
    )


@pytest.mark.parametrize("action_type", ["continuous", "discrete"])
def test_cleanrl_ppo_trains_and_prints_its_summary(tmp_path: Path, action_type: str) -> None:
    model = tmp_path / "ppo.pt"
    result = _run(tmp_path, "--action-type", action_type, "--save", str(model),
                  "--track-tb", "--log-dir", str(tmp_path / "tb"))
    assert result.returncode == 0, result.stderr[-3000:]
    match = SUMMARY.search(result.stdout)
    assert match is not None, result.stdout[-3000:]
    assert int(match.group(1)) == 2048  # 4 updates of 8 envs x 64 steps
    assert int(match.group(4)) > 0  # LandmarkEKF-v0 episodes end within 64 steps mostly
    assert 0.0 <= float(match.group(3)) <= 1.0
    assert len(re.findall(r"^update \d+/4 step", result.stdout, re.MULTILINE)) == 4
    assert model.stat().st_size > 0
    assert any((tmp_path / "tb").rglob("events.out.tfevents.*"))


RL_ZOO3_PPO = ROOT / "examples" / "rl_zoo3" / "ppo.py"


def test_rl_zoo3_hyperparameters_cover_every_id_with_train_py_defaults() -> None:
    from active_loc.envs.registration import ALL_ENV_IDS
    from active_loc.policies import SmallCNN
    from active_loc.train import ALGO_DEFAULTS

    config: dict = {}
    exec(RL_ZOO3_PPO.read_text(), config)  # as rl_zoo3 reads a .py config
    hyperparams = config["hyperparams"]
    assert sorted(hyperparams) == sorted(ALL_ENV_IDS)
    ekf = hyperparams["ActiveLoc/LandmarkEKF-v0"]
    defaults = ALGO_DEFAULTS["ppo"]
    assert (ekf["learning_rate"], ekf["n_steps"], ekf["batch_size"], ekf["n_epochs"]) == (
        defaults["learning_rate"], defaults["n_steps"], defaults["batch_size"],
        defaults["n_epochs"])
    assert ekf["policy"] == "MlpPolicy" and ekf["n_envs"] == 8
    maze = hyperparams["ActiveLoc/Maze-v0"]
    assert maze["policy"] == "CnnPolicy"
    assert maze["policy_kwargs"]["features_extractor_class"] is SmallCNN


@pytest.mark.parametrize("env_id", ["ActiveLoc/LandmarkEKFDiscrete-v0", "ActiveLoc/Maze-v0"])
def test_rl_zoo3_trains_an_id_with_the_hyperparameter_file(tmp_path: Path, env_id: str) -> None:
    """``python -m rl_zoo3.train --gym-packages active_loc -conf examples/rl_zoo3/ppo.py``
    trains, and the saved model plays the env through ``SB3Agent``."""
    pytest.importorskip("rl_zoo3")
    from active_loc.agents.sb3 import SB3Agent

    result = subprocess.run(
        [sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", env_id,
         "--gym-packages", "active_loc", "-conf", str(RL_ZOO3_PPO), "-n", "256", "--seed", "0",
         "-f", "logs", "--eval-freq", "-1",
         "--hyperparams", "n_envs:2", "n_steps:64", "batch_size:64", "n_epochs:1"],
        capture_output=True, text=True, timeout=600, check=False, cwd=tmp_path,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    assert result.returncode == 0, result.stderr[-3000:]
    name = env_id.replace("/", "-")
    model = tmp_path / "logs" / "ppo" / f"{name}_1" / f"{name}.zip"
    assert model.is_file(), result.stdout[-3000:]
    env = gym.make(env_id)
    agent = SB3Agent.load(model)
    agent.check_env(env)
    obs, _ = env.reset(seed=0)
    assert env.action_space.contains(agent.act(obs))
