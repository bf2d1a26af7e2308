"""Bad command-line arguments of ``active-loc render``, ``evaluate`` and ``train``: one line
on stderr naming the argument and a non-zero exit, before any work; results written as
episodes finish."""

from __future__ import annotations

import csv
from pathlib import Path

import gymnasium as gym
import pytest

from active_loc.agents import make_agent
from active_loc.cli import main
from active_loc.evaluation import ResultsStream, evaluate

MAZE = ["--env", "ActiveLoc/Maze-v0", "--agent", "greedy"]


def one_error_line(capsys: pytest.CaptureFixture[str], command: str) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"active-loc {command}: error: "), err
    return err[0]


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["--env", "Bogus-v0"], "--env Bogus-v0"),
        (["--fps", "0"], "--fps must be >= 1, got 0"),
        (["--fps", "-5"], "--fps must be >= 1, got -5"),
        (["--out", "r.xyz"], "--out r.xyz: the file must end in .gif or .mp4"),
        (["--agent", "sb3:/no/such/model.zip"], "no saved model at /no/such/model.zip"),
        (["--seed", "-1"], "--seed must be >= 0, got -1"),
    ],
)
def test_render_refuses_bad_arguments_in_one_line(
    args: list[str], match: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = ["--out", str(tmp_path / "e.gif")] if "--out" not in args else []
    assert main(["render", *MAZE, *out, *args]) == 2
    assert match in one_error_line(capsys, "render")


EVALUATE = ["evaluate", "--env", "ActiveLoc/LandmarkEKF-v0", "--agents", "random",
            "--episodes", "2"]


def test_evaluate_refuses_an_unwritable_out_before_any_episode(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a_file = tmp_path / "a_file"
    a_file.write_text("")
    assert main([*EVALUATE, "--out", str(a_file)]) == 2
    assert "is a file, not a folder" in one_error_line(capsys, "evaluate")
    assert main([*EVALUATE, "--out", "/proc/no/such/place"]) == 2
    assert "cannot write results there" in one_error_line(capsys, "evaluate")


@pytest.mark.parametrize("steps", ["-1", "0", "1.5"])
def test_evaluate_refuses_a_step_limit_that_never_ends_an_episode(
    steps: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main([*EVALUATE, "--out", str(tmp_path),
                 "--env-kwargs", f'{{"max_episode_steps": {steps}}}']) == 2
    assert "max_episode_steps must be an integer >= 1" in one_error_line(capsys, "evaluate")


def test_an_interrupted_evaluation_keeps_the_episodes_it_finished(tmp_path: Path) -> None:
    env_id = "ActiveLoc/LandmarkEKF-v0"
    agent = make_agent("random", gym.make(env_id), 0)
    finished = []

    def add_then_interrupt(record: object) -> None:
        stream.add(record)
        finished.append(record)
        if len(finished) == 3:
            raise KeyboardInterrupt

    stream = ResultsStream(tmp_path)
    with pytest.raises(KeyboardInterrupt):
        evaluate(env_id, {}, {"random": agent}, 10, 0, progress=False,
                 on_record=add_then_interrupt)
    stream.close()
    with (tmp_path / "results.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [int(r["episode"]) for r in rows] == [0, 1, 2]


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["--seed", "-1"], "seed must be >= 0"),
        (["--device", "bogus"], "device 'bogus' is not a torch device"),
        (["--device", "cuda"], "torch sees no CUDA GPU"),
        (["--learning-rate", "inf"], "learning_rate must be a finite number > 0, got inf"),
        (["--out", "/proc/no/such/place"], "cannot write the run there"),
    ],
)
def test_train_refuses_bad_arguments_in_one_line(
    args: list[str], match: str, capsys: pytest.CaptureFixture[str]
) -> None:
    torch = pytest.importorskip("torch")
    if "cuda" in args and torch.cuda.is_available():
        pytest.skip("this machine has a GPU")
    with pytest.raises(SystemExit) as exit_info:
        main(["train", "--env", "ActiveLoc/Maze-v0", "--total-steps", "64", *args])
    assert exit_info.value.code == 2
    assert match in one_error_line(capsys, "train")


def test_evaluate_refuses_a_torch_thread_count_below_one(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main([*EVALUATE, "--out", str(tmp_path), "--torch-threads", "0"]) == 2
    assert "--torch-threads must be >= 1, got 0" in one_error_line(capsys, "evaluate")


@pytest.mark.parametrize("threads", [None, 2])
def test_evaluate_runs_sb3_agents_on_the_torch_threads_asked_for(
    threads: int | None, tmp_path: Path
) -> None:
    import torch
    from stable_baselines3 import PPO

    env = gym.make("ActiveLoc/LandmarkEKF-v0")
    PPO("MlpPolicy", env, n_steps=16, batch_size=16, seed=0, device="cpu").save(
        tmp_path / "model.zip")
    before = torch.get_num_threads()
    option = [] if threads is None else ["--torch-threads", str(threads)]
    try:
        torch.set_num_threads(3)
        assert main(["evaluate", "--env", "ActiveLoc/LandmarkEKF-v0", "--episodes", "1",
                     "--agents", f"sb3:{tmp_path / 'model.zip'}", "--out",
                     str(tmp_path / "eval"), *option]) == 0
        assert torch.get_num_threads() == (1 if threads is None else threads)
    finally:
        torch.set_num_threads(before)
