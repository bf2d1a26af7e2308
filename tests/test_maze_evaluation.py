"""Evaluating on maze files: ``active-loc evaluate --env ActiveLoc/Maze-v0 --env-kwargs
'{"test_set": PATH}'`` end to end, and the ``maze_index`` of every episode's record."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import active_loc  # noqa: F401  (registers the ids)
from active_loc.agents import make_agent
from active_loc.cli import main
from active_loc.evaluation import CSV_COLUMNS, evaluate, run_episode
from active_loc.maps.maze import maze_test_set


def paper_file(path: Path, count: int = 3) -> Path:
    """``count`` 7 x 7 mazes in the layout of the paper's test data."""
    maze_test_set(7, count, seed=21).save_anl(path)
    return path


def rows_of(out: Path) -> list[dict[str, str]]:
    with (out / "results.csv").open(newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def test_the_cli_evaluates_on_a_paper_file_and_names_each_episodes_maze(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = paper_file(tmp_path / "m7_n3.npy")
    out = tmp_path / "eval"
    status = main(["evaluate", "--env", "ActiveLoc/Maze-v0", "--env-kwargs",
                   json.dumps({"test_set": str(path)}), "--agents", "random,greedy",
                   "--episodes", "4", "--seed", "0", "--out", str(out)])
    assert status == 0
    rows = rows_of(out)
    assert tuple(rows[0]) == CSV_COLUMNS
    # each agent replays entries 0, 1, 2, then cycles to 0
    assert [(r["agent"], r["maze_index"]) for r in rows] == [
        (agent, index) for agent in ("random", "greedy") for index in ("0", "1", "2", "0")
    ]
    assert all(r["step_limit"] == "15" and r["belief"] == "grid" for r in rows)
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["env"] == "ActiveLoc/Maze-v0" and summary["episodes"] == 4
    assert "wrote" in capsys.readouterr().out


def test_the_cli_refuses_a_bad_maze_file_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.npy"
    rows = maze_test_set(7, 2, seed=0).to_anl()
    rows[1, -1] = 5.0  # an orientation out of 0..3
    np.save(bad, rows)
    status = main(["evaluate", "--env", "ActiveLoc/Maze-v0", "--env-kwargs",
                   json.dumps({"test_set": str(bad)}), "--agents", "random", "--episodes", "2",
                   "--out", str(tmp_path / "eval")])
    assert status == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0] and "maze 1" in err[0]
    assert "orientation not in 0..3" in err[0]


def test_records_name_the_maze_and_leave_it_empty_elsewhere(tmp_path: Path) -> None:
    path = paper_file(tmp_path / "m7_n3.npy")
    maze = gym.make("ActiveLoc/Maze-v0", test_set=str(path), maze_index=2)
    agent = make_agent("random", maze, 0)
    assert [run_episode(maze, agent, s).maze_index for s in (0, 1)] == [2, 2]
    record = run_episode(maze, agent, 0)
    assert record.row()["maze_index"] == 2

    random_mazes = gym.make("ActiveLoc/Maze-v0")
    assert run_episode(random_mazes, agent, 0).maze_index is None
    other = gym.make("ActiveLoc/Textbook-v0")
    textbook = run_episode(other, make_agent("random", other, 0), 0)
    assert textbook.maze_index is None and textbook.row()["maze_index"] is None


def test_written_rows_hold_the_maze_index_or_an_empty_cell(tmp_path: Path) -> None:
    from active_loc.evaluation import summarize, write_results

    path = paper_file(tmp_path / "m7_n2.npy", count=2)
    env = gym.make("ActiveLoc/Maze-v0")
    agent = make_agent("random", env, 0)
    for kwargs, expected in (({"test_set": str(path)}, ["0", "1", "0"]),
                             ({}, ["", "", ""])):
        records = evaluate("ActiveLoc/Maze-v0", kwargs, {"random": agent}, 3, 5,
                           progress=False)
        out = tmp_path / f"out{len(kwargs)}"
        write_results(records, summarize(records), out)
        assert [r["maze_index"] for r in rows_of(out)] == expected


def test_a_chunk_of_episodes_replays_the_mazes_of_the_serial_run(tmp_path: Path) -> None:
    """evaluate_ray's tasks play chunks of episodes in fresh envs: episode i replays entry
    i mod the set's length whatever ran before it, as in the serial run."""
    from active_loc.evaluation import run_episodes

    kwargs = {"test_set": str(paper_file(tmp_path / "m7_n3.npy"))}
    serial = evaluate("ActiveLoc/Maze-v0", kwargs, {"random": make_agent(
        "random", gym.make("ActiveLoc/Maze-v0", **kwargs), 0)}, 6, 0, progress=False)
    env = gym.make("ActiveLoc/Maze-v0", **kwargs)
    chunk = run_episodes(env, make_agent("random", env, 0), "random", [4, 5], 0)
    assert [r.maze_index for r in serial] == [0, 1, 2, 0, 1, 2]
    assert [r.maze_index for r in chunk] == [1, 2]
    assert [r.row() for r in chunk] == [r.row() for r in serial[4:]]
