"""DAgger from a planner (``active_loc.imitation``) and train.py's ``--imitate`` warm start."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3 import PPO

import active_loc  # noqa: F401  (registers the env ids)
from active_loc.agents.registry import make_agent
from active_loc.imitation import discounted_returns, fit, rollout
from active_loc.train import IMITATION_LOG, TrainArgs, TrainConfigError, train

#: a small maze whose flat observation an MLP reads
MAZE = {"size": 7, "observation": "flat", "episode_length": 15}


def _maze() -> gym.Env:
    return gym.make("ActiveLoc/Maze-v0", **MAZE)


def _refuse(constant: str) -> None:
    raise AssertionError(f"config.json holds {constant}, which is not JSON")


def test_discounted_returns_restart_after_each_episode_end() -> None:
    rewards = np.array([1.0, 1.0, 1.0, 2.0, 4.0])
    ends = np.array([False, False, True, False, False])
    out = discounted_returns(rewards, ends, 0.5)
    np.testing.assert_allclose(out, [1.75, 1.5, 1.0, 4.0, 4.0])


def test_a_planner_rollout_labels_every_state_with_the_action_it_executed() -> None:
    env = _maze()
    planner = make_agent("horizon", env, seed=0)
    run = rollout(env, planner, None, 40, seed=3, gamma=0.99)
    assert run.observations.shape == (40, *env.observation_space.shape)
    assert run.labels.shape == (40,) and run.agreement is None
    assert run.episodes == 3  # 15 steps an episode: 40 steps begin three
    # the same seed, the same planner: the same rollout
    again = rollout(_maze(), make_agent("horizon", _maze(), seed=0), None, 40, 3, 0.99)
    np.testing.assert_array_equal(again.labels, run.labels)
    np.testing.assert_array_equal(again.observations, run.observations)


def test_a_policy_rollout_counts_how_often_it_agrees_with_the_planner() -> None:
    env = _maze()
    planner = make_agent("horizon", env, seed=0)
    run = rollout(env, planner, lambda obs: 1, 30, seed=0, gamma=0.99)
    assert run.agreement == pytest.approx(float(np.mean(run.labels == 1)))


def test_the_fit_makes_the_policy_take_the_planners_actions() -> None:
    torch.manual_seed(0)
    env = _maze()
    run = rollout(env, make_agent("horizon", env, seed=0), None, 300, seed=0, gamma=0.99)
    model = PPO("MlpPolicy", env, policy_kwargs={"net_arch": [64, 64]}, seed=0)
    policy = model.policy

    def agreement() -> float:
        actions, _ = policy.predict(run.observations, deterministic=True)
        return float(np.mean(actions == run.labels))

    def value_error() -> float:
        with torch.no_grad():
            values = policy.predict_values(torch.as_tensor(run.observations))
        return float(np.mean((values.numpy().ravel() - run.returns) ** 2))

    before, error_before = agreement(), value_error()
    nll, mse = fit(policy, run.observations, run.labels, run.returns, epochs=100,
                   learning_rate=1e-3, seed=0)
    assert agreement() >= 0.85 > before  # the planner's actions, not chance's third
    assert value_error() < 0.5 * error_before
    assert nll < 0.5 * np.log(3.0) and mse == pytest.approx(value_error(), rel=0.5)


def test_train_with_imitate_logs_each_round_and_records_them(tmp_path: Path) -> None:
    args = TrainArgs(env="ActiveLoc/Maze-v0", env_kwargs=json.dumps(MAZE), total_steps=128,
                     n_envs=2, n_steps=64, eval_freq=0, checkpoint_freq=0,
                     progress_bar=False, net_arch=(16,), imitate="horizon",
                     imitate_rounds=2, imitate_steps=40, imitate_epochs=2, out=tmp_path)
    out = train(args)
    with (out / IMITATION_LOG).open() as stream:
        rows = list(csv.DictReader(stream))
    assert [row["driver"] for row in rows] == ["planner", "policy"]
    assert [int(row["labels_total"]) for row in rows] == [40, 80]
    assert 0.0 <= float(rows[1]["agreement"]) <= 1.0
    assert rows[0]["agreement"] == ""  # the planner drove
    # strict JSON (no NaN), as other tools read it
    config = json.loads((out / "config.json").read_text(), parse_constant=_refuse)
    assert [row["round"] for row in config["result"]["imitation"]] == [0, 1]
    assert config["result"]["imitation"][0]["agreement"] is None


@pytest.mark.parametrize(("overrides", "message"), [
    ({"algo": "dqn"}, "imitate needs an actor-critic policy"),
    ({"action_repeat": 2, "vec_env": "dummy"}, "cannot run with action_repeat 2"),
    ({"imitate": "nonsense"}, "imitate 'nonsense'"),
    ({"imitate_rounds": 0}, "imitate_rounds must be >= 1"),
    ({"imitate_learning_rate": float("nan")}, "imitate_learning_rate must be"),
])
def test_bad_imitation_arguments_are_refused_by_name(
    tmp_path: Path, overrides: dict, message: str
) -> None:
    settings = {"env": "ActiveLoc/Maze-v0", "env_kwargs": json.dumps(MAZE),
                "imitate": "horizon", "out": tmp_path / "run", "progress_bar": False,
                **overrides}
    with pytest.raises(TrainConfigError, match=message):
        train(TrainArgs(**settings))  # type: ignore[arg-type]
    assert not (tmp_path / "run" / IMITATION_LOG).exists()
