"""``python train.py`` end to end (a subprocess smoke test), DQN and SAC runs, argument
errors, and ``SB3Agent`` on saved models."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import active_loc  # noqa: F401  (registers the env ids)
from active_loc.agents.sb3 import SB3Agent
from active_loc.train import TrainArgs, TrainConfigError, main, train

ROOT = Path(__file__).resolve().parents[1]

#: tiny runs: no progress bar, small networks, an evaluation and a checkpoint within budget
TINY = {"n_envs": 2, "eval_freq": 64, "eval_episodes": 2, "checkpoint_freq": 64,
        "progress_bar": False, "net_arch": (16,)}


@pytest.fixture(scope="module")
def maze_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    out = tmp_path_factory.mktemp("maze") / "run"
    command = [
        sys.executable, "train.py", "--env", "ActiveLoc/Maze-v0", "--total-steps", "256",
        "--n-envs", "2", "--n-steps", "64", "--eval-freq", "128", "--eval-episodes", "3",
        "--checkpoint-freq", "128", "--out", str(out),
    ]
    result = subprocess.run(
        command, cwd=ROOT, capture_output=True, text=True, timeout=600, check=False
    )
    assert result.returncode == 0, result.stderr[-3000:]
    return out, result.stdout


def test_train_py_smoke_run_writes_the_output_folder(maze_run: tuple[Path, str]) -> None:
    out, stdout = maze_run
    for name in ("model.zip", "config.json", "learning_curve.png", "eval/evaluations.npz",
                 "eval/best_model.zip", "eval/0.monitor.csv", "monitor/0.monitor.csv"):
        assert (out / name).is_file(), name
    assert list((out / "checkpoints").glob("model_*_steps.zip"))
    assert list((out / "tb").glob("*/events.out.tfevents.*"))
    config = json.loads((out / "config.json").read_text())
    assert config["args"]["env"] == "ActiveLoc/Maze-v0"
    assert config["args"]["total_steps"] == 256
    assert config["resolved"]["policy"] == "CnnPolicy"
    assert config["resolved"]["policy_kwargs"]["features_extractor_class"].endswith("SmallCNN")
    assert config["resolved"]["info_keywords"][:2] == ["is_success", "entropy"]
    assert "stable-baselines3" in config["versions"]
    assert config["result"]["timesteps"] >= 256
    assert config["result"]["eval"]["evaluations"] == 2
    split = config["result"]["env_time"]  # the training envs' share of the wall time
    assert 0.0 < split["env_s"] < split["total_s"]
    # env_s is rounded to 0.01 s
    assert split["env_share"] == pytest.approx(split["env_s"] / split["total_s"],
                                               abs=0.01 / split["total_s"])
    # custom metrics reach the Monitor CSVs
    header = (out / "monitor" / "0.monitor.csv").read_text().splitlines()[1].split(",")
    assert {"is_success", "entropy", "pose_error", "collisions"} <= set(header)
    with np.load(out / "eval" / "evaluations.npz") as data:
        assert data["successes"].shape == (2, 3)
    assert "model: " in stdout and "last success rate" in stdout


def test_smoke_run_logs_success_rate_and_info_keys_to_tensorboard(
    maze_run: tuple[Path, str],
) -> None:
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    events = next((maze_run[0] / "tb").glob("*/events.out.tfevents.*"))
    accumulator = EventAccumulator(str(events))
    accumulator.Reload()
    tags = set(accumulator.Tags()["scalars"])
    expected = {"eval/success_rate", "eval/entropy", "rollout/success_rate", "rollout/entropy",
                "rollout/pose_error"}
    assert expected <= tags


def test_sb3_agent_acts_with_the_saved_maze_model(maze_run: tuple[Path, str]) -> None:
    agent = SB3Agent.load(maze_run[0])  # the run folder; config.json names PPO
    assert type(agent.model).__name__ == "PPO"
    env = gym.make("ActiveLoc/Maze-v0")
    obs, _ = env.reset(seed=3)
    for _ in range(5):
        action = agent.act(obs, env.unwrapped.planner_view())
        assert isinstance(action, int) and env.action_space.contains(action)
        obs, *_ = env.step(action)
    env.close()
    # a checkpoint finds the config one folder up; the same weights act the same
    checkpoint = sorted((maze_run[0] / "checkpoints").glob("*.zip"))[-1]
    assert type(SB3Agent.load(checkpoint).model).__name__ == "PPO"


def test_dqn_run_on_a_discrete_localization_id(tmp_path: Path) -> None:
    args = TrainArgs(env="ActiveLoc/LandmarkEKF-v0", algo="dqn", total_steps=128,
                     learning_starts=32, batch_size=16, out=tmp_path, **TINY)
    out = train(args)
    config = json.loads((out / "config.json").read_text())
    assert config["resolved"]["env_kwargs"] == {"action_type": "discrete"}
    assert config["resolved"]["policy"] == "MlpPolicy"
    agent = SB3Agent.load(out / "model.zip")
    env = gym.make("ActiveLoc/LandmarkEKF-v0", action_type="discrete")
    obs, _ = env.reset(seed=0)
    action = agent.act(obs, env.unwrapped.planner_view())
    assert isinstance(action, int) and env.action_space.contains(action)
    env.close()


def test_sac_run_on_continuous_landmark_ekf(tmp_path: Path) -> None:
    args = TrainArgs(env="ActiveLoc/LandmarkEKF-v0", algo="sac", total_steps=128,
                     learning_starts=32, batch_size=16, buffer_size=1000, out=tmp_path,
                     **TINY)
    out = train(args)
    assert (out / "model.zip").is_file() and (out / "learning_curve.png").is_file()
    agent = SB3Agent.load(out)
    assert type(agent.model).__name__ == "SAC"
    env = gym.make("ActiveLoc/LandmarkEKF-v0")  # continuous by default
    obs, _ = env.reset(seed=0)
    action = agent.act(obs, env.unwrapped.planner_view())
    assert action.shape == (2,) and env.action_space.contains(action)
    env.close()


def test_ppo_run_with_the_native_vec_env(tmp_path: Path) -> None:
    args = TrainArgs(env="ActiveLoc/LandmarkEKF-v0", algo="ppo", total_steps=256, n_steps=64,
                     vec_env="native", out=tmp_path, **TINY)
    out = train(args)
    assert (out / "model.zip").is_file() and (out / "config.json").is_file()
    config = json.loads((out / "config.json").read_text())
    assert config["args"]["vec_env"] == "native"
    assert config["result"]["timesteps"] >= 256
    assert config["result"]["eval"]["evaluations"] >= 1
    # one VecMonitor CSV for both training envs, with the info keywords
    header = (out / "monitor" / "0.monitor.csv").read_text().splitlines()[1].split(",")
    assert {"is_success", "entropy", "pose_error"} <= set(header)
    assert (out / "eval" / "0.monitor.csv").is_file()
    assert type(SB3Agent.load(out).model).__name__ == "PPO"


def test_dqn_with_continuous_actions_is_a_clear_error(tmp_path: Path) -> None:
    args = TrainArgs(env="ActiveLoc/LandmarkEKF-v0", algo="dqn", out=tmp_path,
                     env_kwargs='{"action_type": "continuous"}')
    with pytest.raises(TrainConfigError, match=r"DQN \(dqn\) needs a Discrete action space.*Box"):
        train(args)
    assert not (tmp_path / "config.json").exists()


def test_sac_on_the_discrete_maze_is_a_clear_error_on_the_command_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["--env", "ActiveLoc/Maze-v0", "--algo", "sac", "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    message = capsys.readouterr().err
    assert "SAC (sac) needs a Box action space" in message
    assert "Discrete(3)" in message and "discrete actions only" in message


@pytest.mark.parametrize(
    ("overrides", "match"),
    [
        ({"algo": "dqn", "n_steps": 64}, "DQN has no hyperparameter 'n_steps'"),
        ({"env_kwargs": "[1, 2]"}, "env_kwargs must be a JSON object"),
        ({"env_kwargs": '{"size": 8}'}, "size must be one of"),
        ({"env": "ActiveLoc/Nope-v0"}, "unknown env id"),
        ({"env": "ActiveLoc/LandmarkEKF-v0", "policy": "cnn"}, "policy 'cnn' needs an image"),
        ({"total_steps": 0}, "total_steps must be >= 1"),
        ({"action_repeat": 0}, "action_repeat must be >= 1"),
        ({"env": "ActiveLoc/LandmarkEKF-v0", "action_repeat": 2, "vec_env": "native"},
         "vec_env native cannot hold actions"),
    ],
)
def test_bad_arguments_raise_clear_errors(
    tmp_path: Path, overrides: dict[str, object], match: str
) -> None:
    with pytest.raises(TrainConfigError, match=match):
        train(TrainArgs(out=tmp_path, **overrides))  # type: ignore[arg-type]


def test_sb3_agent_carries_the_lstm_state_and_resets_it_on_a_new_episode() -> None:
    from sb3_contrib import RecurrentPPO

    env = gym.make("ActiveLoc/LandmarkEKF-v0")
    model = RecurrentPPO("MlpLstmPolicy", env, n_steps=8, batch_size=8, seed=0, device="cpu",
                         policy_kwargs={"lstm_hidden_size": 8, "net_arch": [8]})
    agent = SB3Agent(model, deterministic=True)
    assert agent.recurrent
    obs, _ = env.reset(seed=1)
    first = agent.act(obs, env.unwrapped.planner_view())
    assert first.shape == (2,) and env.action_space.contains(first)
    state_after_first = [s.copy() for s in agent._state]
    obs, *_ = env.step(first)
    agent.act(obs, env.unwrapped.planner_view())
    assert any(not np.array_equal(a, b) for a, b in zip(state_after_first, agent._state,
                                                         strict=True))
    obs, _ = env.reset(seed=1)  # view.step == 0: a new episode, the state starts afresh
    again = agent.act(obs, env.unwrapped.planner_view())
    np.testing.assert_array_equal(again, first)
    for a, b in zip(state_after_first, agent._state, strict=True):
        np.testing.assert_array_equal(a, b)
    env.close()


def test_active_loc_train_forwards_to_the_training_cli(capsys: pytest.CaptureFixture[str]) -> None:
    from active_loc.cli import main as cli_main

    with pytest.raises(SystemExit) as exit_info:
        cli_main(["train", "--help"])
    assert exit_info.value.code == 0
    text = capsys.readouterr().out
    assert "active-loc train" in text and "--total-steps" in text and "--algo" in text


def test_pooled_belief_cnn_takes_any_maze_size_and_the_belief_up_to_scale() -> None:
    import gymnasium as gym
    import torch

    from active_loc.policies import PooledBeliefCNN

    torch.manual_seed(0)
    extractor = PooledBeliefCNN(gym.spaces.Box(0.0, 1.0, (5, 7, 7)), features_dim=16)
    rng = np.random.default_rng(0)
    for n in (7, 15, 21):
        obs = torch.as_tensor(rng.random((3, 5, n, n)), dtype=torch.float32)
        features = extractor(obs)
        assert features.shape == (3, 16)
        scaled = obs.clone()
        scaled[:, :4] *= 1e-3  # the same belief shape, 1000 times less mass per pose
        assert torch.allclose(extractor(scaled), features, atol=1e-5)
    with pytest.raises(ValueError, match="belief_channels"):
        PooledBeliefCNN(gym.spaces.Box(0.0, 1.0, (5, 7, 7)), belief_channels=6)


def test_belief_image_extractor_reads_the_image_and_the_vector() -> None:
    import torch

    from active_loc.policies import BeliefImageExtractor

    torch.manual_seed(0)
    space = gym.make("ActiveLoc/GridMCL-v0", observation="image", image_size=16).observation_space
    extractor = BeliefImageExtractor(space, features_dim=24, channels=(8, 16), vector_dim=8)
    assert extractor.features_dim == 32
    rng = np.random.default_rng(0)
    obs = {key: torch.as_tensor(rng.random((3, *sub.shape)), dtype=torch.float32)
           for key, sub in space.spaces.items()}
    features = extractor(obs)
    assert features.shape == (3, 32)
    scaled = {**obs, "image": obs["image"].clone()}
    scaled["image"][:, :-1] *= 1e-3  # the same belief, spread 1000 times thinner
    assert torch.allclose(extractor(scaled), features, atol=1e-5)
    moved = {**obs, "vector": obs["vector"] + 1.0}
    assert not torch.allclose(extractor(moved), features)  # the vector is read too
    with pytest.raises(ValueError, match="'image' Box"):
        BeliefImageExtractor(gym.spaces.Box(0.0, 1.0, (5, 7, 7)))


def test_ppo_run_on_the_belief_image(tmp_path: Path) -> None:
    args = TrainArgs(env="ActiveLoc/GridMCL-v0", algo="ppo", total_steps=128, n_steps=64,
                     vec_env="native", out=tmp_path, cnn_channels=(4, 8), features_dim=16,
                     env_kwargs=json.dumps({"observation": "image", "image_size": 12,
                                            "action_type": "discrete"}), **TINY)
    out = train(args)
    config = json.loads((out / "config.json").read_text())
    assert config["resolved"]["policy"] == "MultiInputPolicy"
    assert "BeliefImageExtractor" in config["resolved"]["policy_kwargs"]["features_extractor_class"]
    agent = SB3Agent.load(out)
    env = gym.make("ActiveLoc/GridMCL-v0", observation="image", image_size=12,
                   action_type="discrete")
    obs, _ = env.reset(seed=0)
    assert env.action_space.contains(agent.act(obs, env.unwrapped.planner_view()))


def test_auto_vec_env_is_native_where_it_is_faster() -> None:
    from active_loc.train import resolve_vec_env

    assert resolve_vec_env("auto", "ActiveLoc/LandmarkEKF-v0", {}, 64) == "native"
    assert resolve_vec_env("auto", "ActiveLoc/LandmarkEKF-v0", {}, 8) == "native"
    assert resolve_vec_env("auto", "ActiveLoc/LandmarkEKF-v0", {}, 4) == "dummy"
    assert resolve_vec_env("auto", "ActiveLoc/Textbook-v0", {"action_type": "discrete"}) == "native"
    threads = "native" if (os.cpu_count() or 1) >= 2 else "dummy"  # MCL: 2 cores
    assert resolve_vec_env("auto", "ActiveLoc/GridMCL-v0", {}) == threads
    assert resolve_vec_env("auto", "ActiveLoc/LandmarkMCL-v0", {}, 2) == threads
    assert resolve_vec_env("auto", "ActiveLoc/GridMarkov-v0", {}, 2) == "native"  # batched
    assert resolve_vec_env("auto", "ActiveLoc/GridMCL-v0", {}, 1) == "dummy"
    assert resolve_vec_env("auto", "ActiveLoc/LandmarkEKFUnknown-v0", {}) == "dummy"
    assert resolve_vec_env("auto", "ActiveLoc/Maze-v0", {"size": 7}) == "dummy"
    assert resolve_vec_env("auto", "CartPole-v1", {}) == "dummy"
    assert resolve_vec_env("subproc", "ActiveLoc/LandmarkEKF-v0", {}) == "subproc"


def test_auto_vec_env_with_held_actions_uses_processes_for_the_threads() -> None:
    from active_loc.train import resolve_vec_env

    processes = "subproc" if (os.cpu_count() or 1) >= 2 else "dummy"
    assert resolve_vec_env("auto", "ActiveLoc/GridMCL-v0", {}, 8, action_repeat=5) == processes
    assert resolve_vec_env("auto", "ActiveLoc/LandmarkEKF-v0", {}, 64, action_repeat=5) == "dummy"
    assert resolve_vec_env("auto", "ActiveLoc/Maze-v0", {"size": 7}, 8, action_repeat=2) == "dummy"
    assert resolve_vec_env("auto", "ActiveLoc/GridMarkov-v0", {}, 8, action_repeat=2) == "dummy"
    assert resolve_vec_env("dummy", "ActiveLoc/GridMCL-v0", {}, 8, action_repeat=5) == "dummy"


def test_a_run_with_action_repeat_holds_actions_in_training_and_in_the_agent(
    tmp_path: Path,
) -> None:
    args = TrainArgs(env="ActiveLoc/LandmarkEKF-v0", env_kwargs='{"action_type": "discrete"}',
                     algo="ppo", total_steps=128, n_steps=32, action_repeat=3, out=tmp_path,
                     **TINY)
    out = train(args)
    config = json.loads((out / "config.json").read_text())
    assert config["args"]["action_repeat"] == 3
    assert config["resolved"]["vec_env"] == "dummy"
    # the Monitor sits under the repeat, so it counts env steps: an episode longer than the
    # 64 decisions each training env took and the 67 an evaluation episode can take
    lengths = [
        int(row.split(",")[1]) for folder in ("monitor", "eval") for csv in (out / folder).glob(
            "*.monitor.csv") for row in csv.read_text().splitlines()[2:]
    ]
    assert max(lengths) > 67

    agent = SB3Agent.load(out)
    assert agent.action_repeat == 3
    asked = []
    predict = agent.model.predict
    agent.model.predict = lambda obs, **kw: (asked.append(1), predict(obs, **kw))[1]
    env = gym.make("ActiveLoc/LandmarkEKF-v0", action_type="discrete")
    obs, _ = env.reset(seed=0)
    actions = []
    for _ in range(7):
        actions.append(agent.act(obs, env.unwrapped.planner_view()))
        obs, *_ = env.step(actions[-1])
    assert len(asked) == 3  # at steps 0, 3 and 6
    assert actions[0] == actions[1] == actions[2] and actions[3] == actions[4] == actions[5]
    obs, _ = env.reset(seed=1)  # a new episode asks at once
    agent.act(obs, env.unwrapped.planner_view())
    assert len(asked) == 4
    env.close()
    assert SB3Agent(agent.model).action_repeat == 1
    with pytest.raises(ValueError, match="action_repeat must be an integer >= 1"):
        SB3Agent(agent.model, action_repeat=0)


def test_a_sampling_sb3_agent_draws_from_the_policy_with_its_own_generator(
    tmp_path: Path,
) -> None:
    import torch
    from stable_baselines3 import PPO

    from active_loc.agents.registry import make_agent
    from active_loc.evaluation import run_episodes

    env = gym.make("ActiveLoc/LandmarkEKF-v0", action_type="discrete")
    model = PPO("MlpPolicy", env, n_steps=16, batch_size=16, seed=0, device="cpu",
                policy_kwargs={"net_arch": [8]})
    obs, _ = env.reset(seed=0)
    view = env.unwrapped.planner_view()
    with torch.no_grad():
        obs_tensor, _ = model.policy.obs_to_tensor(obs)
        probs = model.policy.get_distribution(obs_tensor).distribution.probs[0].numpy()
    first = SB3Agent(model, deterministic=False, seed=7)
    draws = [first.act(obs, view) for _ in range(4000)]
    again = SB3Agent(model, deterministic=False, seed=7)
    assert [again.act(obs, view) for _ in range(4000)] == draws  # its seed replays it
    frequencies = np.bincount(draws, minlength=probs.size) / len(draws)
    np.testing.assert_allclose(frequencies, probs, atol=0.03)
    assert len(set(draws)) == probs.size  # an untrained policy spreads over every action

    # through the evaluation, which reseeds the agent each episode: the records replay
    model.save(tmp_path / "model.zip")
    agent = make_agent(f"sb3-sample:{tmp_path / 'model.zip'}", env, seed=0)
    assert not agent.deterministic and agent._own_sampling
    runs = [run_episodes(env, agent, "s", range(2), 5) for _ in range(2)]
    assert [r.row() for r in runs[0]] == [r.row() for r in runs[1]]
    env.close()

    box_env = gym.make("ActiveLoc/LandmarkEKF-v0")  # continuous actions
    box_model = PPO("MlpPolicy", box_env, n_steps=16, batch_size=16, seed=0, device="cpu",
                    policy_kwargs={"net_arch": [8]})
    obs, _ = box_env.reset(seed=0)
    box_agent = SB3Agent(box_model, deterministic=False, seed=1)
    actions = np.array([box_agent.act(obs, None) for _ in range(2000)])
    assert actions.shape == (2000, 2) and actions.dtype == np.float32
    assert np.all(actions >= -1.0) and np.all(actions <= 1.0) and actions.std(axis=0).min() > 0.3
    box_env.close()
