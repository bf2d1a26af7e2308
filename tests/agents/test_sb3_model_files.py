"""Saved models a user brings: a model for another env, and run configs that are not JSON,
name an unknown algorithm or a bad action repeat, are refused naming the file."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import pytest

import active_loc  # noqa: F401  (registers the ids)
from active_loc.agents.registry import make_agent
from active_loc.agents.sb3 import SB3Agent

pytest.importorskip("stable_baselines3")


@pytest.fixture(scope="module")
def maze_model(tmp_path_factory: pytest.TempPathFactory) -> Path:
    import torch
    from stable_baselines3 import PPO

    torch.set_num_threads(1)
    env = gym.make("ActiveLoc/Maze-v0")
    model = PPO("MlpPolicy", env, n_steps=16, batch_size=16, seed=0, device="cpu")
    folder = tmp_path_factory.mktemp("run")
    model.save(folder / "model.zip")
    return folder


def test_a_model_for_another_env_is_refused_at_load_naming_both_spaces(
    maze_model: Path,
) -> None:
    env = gym.make("ActiveLoc/LandmarkEKF-v0")
    with pytest.raises(ValueError, match=r"the model .*model.zip was trained on the "
                                         r"observation space Box.*but this env has Box"):
        make_agent(f"sb3:{maze_model / 'model.zip'}", env)
    agent = make_agent(f"sb3:{maze_model / 'model.zip'}", gym.make("ActiveLoc/Maze-v0"))
    assert isinstance(agent, SB3Agent)  # the env it was trained on passes


@pytest.mark.parametrize(
    ("config", "match"),
    [
        ("{not json", r"config.json: not a JSON run config"),
        ('["a", "list"]', r"config.json: a run config must be a JSON object"),
        (json.dumps({"args": {"algo": "ppo2"}}), r"config.json: algo must be one of .*'ppo2'"),
        (json.dumps({"args": {"algo": "ppo", "action_repeat": 0}}),
         r"config.json: action_repeat must be an integer >= 1, got 0"),
        (json.dumps({"args": {"algo": "ppo", "action_repeat": "3"}}),
         r"config.json: action_repeat must be an integer >= 1, got '3'"),
    ],
    ids=["not_json", "not_an_object", "unknown_algo", "repeat_0", "repeat_string"],
)
def test_a_bad_run_config_is_refused_naming_the_file(maze_model: Path, tmp_path: Path,
                                                     config: str, match: str) -> None:
    (tmp_path / "model.zip").write_bytes((maze_model / "model.zip").read_bytes())
    (tmp_path / "config.json").write_text(config)
    with pytest.raises(ValueError, match=match):
        SB3Agent.load(tmp_path)


def test_the_loader_says_model_files_are_trusted_input() -> None:
    assert "trusted input" in SB3Agent.load.__doc__
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    assert "trusted input" in readme
