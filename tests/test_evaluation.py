"""Evaluation: Wilson intervals, the metrics' definitions, the files, determinism and the CLI."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import active_loc  # noqa: F401
from active_loc.agents import RandomAgent, TextbookAgent
from active_loc.cli import main as cli_main
from active_loc.evaluation import (
    CSV_COLUMNS,
    SUMMARY_KEYS,
    EpisodeRecord,
    entropy_curves,
    evaluate,
    json_safe,
    nees,
    run_episode,
    success_curves,
    summarize,
    wilson_interval,
    write_results,
)
from active_loc.evaluation_plots import ENTROPY_PNG, SUCCESS_PNG, safe_name, write_plots

TEXTBOOK = "ActiveLoc/Textbook-v0"
SHORT = {"max_episode_steps": 20}
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _agents() -> dict[str, object]:
    return {"textbook": TextbookAgent(), "random": RandomAgent(7)}


def _closed_form(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    p = k / n
    centre = (p + z**2 / (2 * n)) / (1 + z**2 / n)
    half = z / (1 + z**2 / n) * math.sqrt(p * (1 - p) / n + z**2 / (4 * n**2))
    return centre - half, centre + half


# --- Wilson ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("k", "n", "expected"),
    [
        (0, 10, (0.0, 0.27753)),
        (10, 10, (0.72247, 1.0)),
        (5, 10, (0.23659, 0.76341)),
        (1, 1, (0.20654, 1.0)),
        (30, 100, (0.21895, 0.39585)),
    ],
)
def test_wilson_interval_known_values(k: int, n: int, expected: tuple[float, float]) -> None:
    lo, hi = wilson_interval(k, n)
    assert (lo, hi) == pytest.approx(expected, abs=5e-5)
    assert (lo, hi) == pytest.approx(_closed_form(k, n), abs=1e-12)


def test_wilson_interval_edges() -> None:
    lo, hi = wilson_interval(0, 10)
    assert lo == 0.0 and hi == pytest.approx(1.96**2 / (10 + 1.96**2))
    lo, hi = wilson_interval(10, 10)
    assert hi == 1.0 and lo == pytest.approx(10 / (10 + 1.96**2))
    assert all(math.isnan(v) for v in wilson_interval(0, 0))
    lo99, hi99 = wilson_interval(5, 10, z=2.576)
    assert lo99 < 0.23659 and hi99 > 0.76341
    with pytest.raises(ValueError, match="successes"):
        wilson_interval(11, 10)
    with pytest.raises(ValueError, match="successes"):
        wilson_interval(-1, 10)


# --- metric definitions on hand-made records -----------------------------------------------------


def _record(
    success: list[bool], localized: list[bool] | None = None, **kw: object
) -> EpisodeRecord:
    steps = len(success) - 1
    fields = {
        "agent": "a",
        "episode": 0,
        "seed": 100,
        "env_id": "X-v0",
        "belief": "ekf",
        "steps": steps,
        "terminated": False,
        "truncated": True,
        "entropy_trace": tuple(float(-t) for t in range(steps + 1)),
        "success_trace": tuple(success),
        "localized_trace": tuple(localized if localized is not None else success),
        "pose_error_trace": (1.0,) * (steps + 1),
        "heading_error_trace": (0.5,) * (steps + 1),
        "reward_trace": (0.5,) * steps,
        "collisions": 2,
        "path_length": 1.5,
        "nees": 3.0,
    }
    fields.update(kw)
    return EpisodeRecord(**fields)  # type: ignore[arg-type]


def test_record_metrics_follow_their_definitions() -> None:
    r = _record([False, False, True, False, True])
    assert r.steps_to_localize == 2  # the first step with is_success
    assert r.success and not r.false_convergence
    assert r.final_entropy == -4.0 and r.episode_return == 2.0
    assert _record([True, True]).steps_to_localize == 0  # already after reset
    never = _record([False, False, False], localized=[False, True, True])
    assert never.steps_to_localize is None and not never.success
    assert never.false_convergence  # confident at the end, not successful
    row = never.row()
    assert tuple(row) == CSV_COLUMNS
    assert row["return"] == 1.0 and row["steps_to_localize"] is None


def test_summarize_means_over_localized_episodes_only_and_null_without_any() -> None:
    records = [
        _record([False, True], episode=0, seed=100),
        _record([False, False, False, True], episode=1, seed=101),
        _record([False, False, False], episode=2, seed=102, localized=[False, False, True]),
        _record([False, False], agent="b", episode=0, seed=100),
        _record([False, False], agent="b", episode=1, seed=101),
        _record([False, False], agent="b", episode=2, seed=102),
    ]
    summary = summarize(records)
    assert summary["env"] == "X-v0" and summary["episodes"] == 3 and summary["seed"] == 100
    a, b = summary["agents"]["a"], summary["agents"]["b"]
    assert tuple(a) == SUMMARY_KEYS
    assert a["success_rate"] == pytest.approx(2 / 3)
    assert a["success_ci95"] == pytest.approx(list(_closed_form(2, 3)))
    assert a["steps_to_localize_mean"] == 2.0 and a["steps_to_localize_median"] == 2.0
    assert a["false_convergence_rate"] == pytest.approx(1 / 3)
    assert a["position_rmse"] == 1.0 and a["heading_rmse"] == 0.5
    assert a["collisions_mean"] == 2.0
    assert b["steps_to_localize_mean"] is None and b["steps_to_localize_median"] is None
    assert b["success_rate"] == 0.0
    # without a step limit an episode never localized has no value: no restricted mean
    assert a["steps_to_localize_restricted_mean"] is None
    assert b["steps_to_localize_restricted_mean"] is None
    with pytest.raises(ValueError, match="numbers of episodes"):
        summarize(records[:4])
    with pytest.raises(ValueError, match="different envs"):
        summarize([records[0], replace(records[1], env_id="Y-v0")])


def test_restricted_mean_counts_episodes_never_localized_at_the_step_limit() -> None:
    records = [
        _record([False, True], episode=0, seed=100, step_limit=10),  # 1
        _record([False, False, False, True], episode=1, seed=101, step_limit=10),  # 3
        _record([False, False], episode=2, seed=102, step_limit=10),  # never: 10
    ]
    assert [r.steps_to_localize_or_limit for r in records] == [1, 3, 10]
    assert records[2].row()["step_limit"] == 10
    a = summarize(records)["agents"]["a"]
    assert a["steps_to_localize_mean"] == 2.0  # the localized episodes only
    assert a["steps_to_localize_restricted_mean"] == pytest.approx(14 / 3)


def test_json_safe_turns_non_finite_numbers_into_null() -> None:
    value = {"a": math.nan, "b": [math.inf, 1.0, np.float64(-math.inf)], "c": np.int64(3),
             "d": (np.bool_(True), None)}
    assert json_safe(value) == {"a": None, "b": [None, 1.0, None], "c": 3, "d": [True, None]}


def test_nees_wraps_the_heading_and_rejects_singular_covariances() -> None:
    truth = np.array([1.0, 2.0, math.pi - 0.1])
    mean = np.array([0.0, 2.0, -math.pi + 0.1])
    assert nees(truth, mean, np.eye(3)) == pytest.approx(1.0 + 0.2**2)
    assert nees(truth, mean, np.diag([4.0, 1.0, 0.01])) == pytest.approx(0.25 + 4.0)
    assert math.isnan(nees(truth, mean, np.zeros((3, 3))))
    assert math.isnan(nees(truth, mean, np.diag([1.0, 1.0, 0.0])))
    assert math.isnan(nees(truth, mean, np.full((3, 3), np.nan)))


# --- running episodes ----------------------------------------------------------------------------


def test_run_episode_records_every_step_and_the_truths_path() -> None:
    env = gym.make(TEXTBOOK, **SHORT)
    record = run_episode(env, TextbookAgent(), 3, agent_name="textbook", episode=2)
    env.close()
    assert record.agent == "textbook" and record.episode == 2 and record.seed == 3
    assert record.base_seed == 1 and record.env_id == TEXTBOOK and record.belief == "ekf"
    assert record.steps == 20 and record.truncated and not record.terminated
    assert record.step_limit == 20  # the max_episode_steps given to gymnasium.make
    for trace in (record.entropy_trace, record.success_trace, record.localized_trace,
                  record.pose_error_trace, record.heading_error_trace):
        assert len(trace) == 21
    assert len(record.reward_trace) == 20
    # V = 1 m/s for 20 steps of 0.1 s, plus a little motion noise
    assert 1.8 < record.path_length < 2.6
    assert record.nees is not None and math.isfinite(record.nees) and record.nees >= 0.0
    assert record.entropy_trace[-1] < record.entropy_trace[0]


def test_maze_records_have_no_nees_and_paths_in_whole_cells() -> None:
    env = gym.make("ActiveLoc/Maze-v0")
    record = run_episode(env, RandomAgent(0), 4)
    env.close()
    assert record.belief == "grid" and record.nees is None
    assert record.step_limit == 15  # no TimeLimit: the env's own episode length (n = 7)
    assert record.row()["nees"] is None
    assert record.path_length == round(record.path_length) <= record.steps


def test_same_seeds_give_identical_results() -> None:
    first = evaluate(TEXTBOOK, SHORT, _agents(), 3, 11, progress=False)
    second = evaluate(TEXTBOOK, SHORT, _agents(), 3, 11, progress=False)
    assert first == second
    assert [r.seed for r in first] == [11, 12, 13] * 2
    other = evaluate(TEXTBOOK, SHORT, {"textbook": TextbookAgent()}, 3, 12, progress=False)
    assert other[0].entropy_trace == first[1].entropy_trace  # episode seed 12 either way
    assert other[0].entropy_trace != first[0].entropy_trace


def test_evaluate_rejects_bad_arguments() -> None:
    with pytest.raises(ValueError, match="episodes"):
        evaluate(TEXTBOOK, SHORT, _agents(), 0, 0, progress=False)
    with pytest.raises(ValueError, match="agent"):
        evaluate(TEXTBOOK, SHORT, {}, 1, 0, progress=False)


def test_small_evaluation_writes_csv_json_md_and_plots(tmp_path: Path) -> None:
    records = evaluate(TEXTBOOK, SHORT, _agents(), 3, 0, progress=False)
    summary = summarize(records)
    paths = write_results(records, summary, tmp_path / "eval")
    plots = write_plots(records, tmp_path / "eval")

    with paths["csv"].open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert tuple(rows[0]) == CSV_COLUMNS
    assert [(r["agent"], r["episode"]) for r in rows] == [
        (agent, str(i)) for agent in ("textbook", "random") for i in range(3)
    ]
    assert [r["seed"] for r in rows] == ["0", "1", "2"] * 2
    for row, record in zip(rows, records, strict=True):
        assert float(row["final_entropy"]) == record.final_entropy
        assert float(row["return"]) == record.episode_return
        assert row["success"] == str(record.success)

    data = json.loads(paths["json"].read_text())
    assert set(data) == {"env", "episodes", "seed", "agents"}
    assert data["env"] == TEXTBOOK and data["episodes"] == 3 and data["seed"] == 0
    assert list(data["agents"]) == ["textbook", "random"]
    for entry in data["agents"].values():
        assert tuple(entry) == SUMMARY_KEYS
        lo, hi = entry["success_ci95"]
        assert 0.0 <= lo <= entry["success_rate"] <= hi <= 1.0
        assert (lo, hi) == pytest.approx(
            wilson_interval(round(entry["success_rate"] * 3), 3)
        )

    md = paths["md"].read_text()
    assert "| `textbook` |" in md and "| `random` |" in md and "Wilson 95%" in md
    lo, hi = data["agents"]["textbook"]["success_ci95"]
    assert f"[{lo:.2f}, {hi:.2f}]" in md

    assert [p.name for p in plots] == [ENTROPY_PNG, SUCCESS_PNG]
    for p in plots:
        assert p.read_bytes()[:8] == PNG_SIGNATURE


def test_step_curves_hold_final_values_and_stay_in_their_bands() -> None:
    records = [
        _record([False, True], episode=0, seed=0),
        _record([False, False, False, True], episode=1, seed=1),
    ]
    entropy = entropy_curves(records)["a"]
    assert list(entropy.steps) == [0, 1, 2, 3]
    assert list(entropy.mean) == [0.0, -1.0, -1.5, -2.0]  # episode 0 holds -1 after its end
    assert np.all(entropy.lower <= entropy.mean) and np.all(entropy.mean <= entropy.upper)
    success = success_curves(records)["a"]
    assert list(success.mean) == [0.0, 0.5, 0.5, 1.0]
    assert np.all((success.lower >= 0) & (success.upper <= 1))
    assert success.lower[0] == 0.0 and success.upper[-1] == 1.0


def test_safe_name() -> None:
    assert safe_name("sb3:models/ppo.zip") == "sb3_models_ppo.zip"
    assert safe_name("greedy") == "greedy"


# --- the command ---------------------------------------------------------------------------------


def test_cli_evaluate_in_a_subprocess(tmp_path: Path) -> None:
    out = tmp_path / "eval"
    result = subprocess.run(
        [sys.executable, "-m", "active_loc.cli", "evaluate", "--env", TEXTBOOK,
         "--env-kwargs", json.dumps({"max_episode_steps": 10}), "--agents", "random,textbook",
         "--episodes", "2", "--seed", "5", "--out", str(out), "--gif"],
        capture_output=True, text=True, timeout=600, check=False, cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert "| `random` |" in result.stdout and "| `textbook` |" in result.stdout
    assert "episode" in result.stderr and "4/4" in result.stderr  # the progress bar
    data = json.loads((out / "summary.json").read_text())
    assert data["episodes"] == 2 and data["seed"] == 5 and list(data["agents"]) == [
        "random", "textbook"
    ]
    with (out / "results.csv").open(newline="") as f:
        assert len(list(csv.DictReader(f))) == 4
    for name in ("summary.md", ENTROPY_PNG, SUCCESS_PNG, "episode_random.gif",
                 "episode_textbook.gif"):
        assert (out / name).stat().st_size > 0


def test_cli_evaluate_takes_agent_parameters_and_names_the_rows_by_spec(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "eval"
    agents = "textbook,textbook[speed=0.5]"
    assert cli_main(["evaluate", "--env", TEXTBOOK, "--env-kwargs", '{"max_episode_steps": 20}',
                     "--agents", agents, "--episodes", "2", "--out", str(out),
                     "--baseline", "textbook"]) == 0
    capsys.readouterr()
    with (out / "results.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert [row["agent"] for row in rows] == ["textbook"] * 2 + ["textbook[speed=0.5]"] * 2
    half, full = (float(rows[i]["path_length"]) for i in (2, 0))
    assert half < 0.75 * full  # the parameter reached the agent: half the speed
    assert cli_main(["compare", str(out / "results.csv"), "--baseline", "textbook"]) == 0
    assert "textbook[speed=0.5]" in capsys.readouterr().out


def test_cli_evaluate_reports_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    base = ["evaluate", "--env", TEXTBOOK, "--episodes", "1", "--out", str(tmp_path / "eval")]
    for extra, message in [
        (["--agents", "nonsense"], "unknown agent"),
        (["--agents", "random", "--env-kwargs", "[1]"], "JSON object"),
        (["--agents", "random", "--env-kwargs", "{bad"], "not valid JSON"),
        (["--agents", "random,random"], "twice"),
        (["--agents", "random", "--env-kwargs", '{"fov": -1}'], "fov"),
        (["--agents", "random,textbook[sped=2]"], "no parameter 'sped'"),
    ]:
        assert cli_main(base + extra) == 2
        assert message in capsys.readouterr().err
    assert not (tmp_path / "eval").exists()
