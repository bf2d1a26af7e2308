"""The shipped policies of pretrained/: small, loadable by name, and localizing most of the
first test episodes (a floor well below the rate in pretrained/README.md, so that a model that
no longer loads into its env, or plays the wrong one, fails)."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import pytest

import active_loc  # noqa: F401  (registers the ids)
from active_loc.agents.registry import make_agent
from active_loc.evaluation import run_episode

PRETRAINED = Path(__file__).resolve().parents[1] / "pretrained"
MODELS = sorted(path.parent.name for path in PRETRAINED.glob("*/model.zip"))
#: each model's check: the env kwargs of its test set, the episodes, the fewest successes
CHECKS = {
    "maze7-flat-ppo": ({"size": 7, "observation": "flat", "test_set": 1000}, 40, 37),
    "maze15-pooled-ppo": ({"size": 15, "test_set": 1000}, 40, 28),
}


def test_every_shipped_policy_has_its_run_config_and_all_fit_in_10_mb() -> None:
    assert MODELS, "no pretrained/<name>/model.zip"
    assert set(MODELS) == set(CHECKS)
    for name in MODELS:
        config = json.loads((PRETRAINED / name / "config.json").read_text())
        assert config["args"]["env"].startswith("ActiveLoc/")
        assert isinstance(config["resolved"]["env_kwargs"], dict)
        assert name in (PRETRAINED / "README.md").read_text()
    total = sum(path.stat().st_size for path in PRETRAINED.rglob("*") if path.is_file())
    assert total <= 10 * 2**20


@pytest.mark.parametrize("name", MODELS)
def test_a_shipped_policy_loads_by_name_and_localizes(name: str) -> None:
    config = json.loads((PRETRAINED / name / "config.json").read_text())
    env_kwargs, episodes, fewest = CHECKS[name]
    env = gym.make(config["args"]["env"], **env_kwargs)
    agent = make_agent(f"sb3:{PRETRAINED / name / 'model.zip'}", env, seed=0)
    successes = sum(run_episode(env, agent, seed).success for seed in range(episodes))
    assert successes >= fewest
