"""Paired comparison: McNemar's and the sign test on hand-made outcomes, results.csv, the CLI."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

import active_loc  # noqa: F401
from active_loc.agents import RandomAgent, TextbookAgent
from active_loc.cli import main as cli_main
from active_loc.comparison import (
    EpisodeOutcome,
    comparison_markdown,
    outcomes_of,
    paired_comparison,
    read_outcomes,
)
from active_loc.evaluation import evaluate, summarize, write_results

TEXTBOOK = "ActiveLoc/Textbook-v0"


def _outcomes(agent: str, results: list[tuple[bool, int | None]]) -> list[EpisodeOutcome]:
    return [EpisodeOutcome(agent, 10 + i, ok, steps) for i, (ok, steps) in enumerate(results)]


def test_counts_and_exact_p_values_of_a_known_pairing() -> None:
    limit = 300
    base = _outcomes("passive", [(False, limit)] * 6 + [(True, 50), (True, 80), (False, limit)])
    agent = _outcomes("ppo", [(True, 40)] * 6 + [(True, 50), (False, limit), (False, limit)])
    comparison = paired_comparison(base + agent, "passive")
    assert comparison["baseline"] == "passive" and list(comparison["agents"]) == ["ppo"]
    c = comparison["agents"]["ppo"]
    assert c["episodes"] == 9
    assert (c["only_agent"], c["only_baseline"]) == (6, 1)
    # McNemar exact: P(|K - 3.5| >= 2.5) for K ~ Bin(7, 1/2) = 2 * (1 + 7) / 2**7
    assert c["mcnemar_p"] == pytest.approx(16 / 128)
    # sooner in the 6, later in the one only the wall follower localized; ties left out
    assert (c["sooner"], c["later"]) == (6, 1)
    assert c["sign_test_p"] == pytest.approx(16 / 128)
    assert c["restricted_mean_difference"] == pytest.approx((6 * (40 - 300) + 220) / 9)


def test_no_difference_gives_p_one_and_a_missing_limit_gives_no_steps() -> None:
    same = _outcomes("a", [(True, 5), (False, 20)]) + _outcomes("b", [(True, 5), (False, 20)])
    c = paired_comparison(same, "a")["agents"]["b"]
    assert (c["only_agent"], c["only_baseline"], c["mcnemar_p"]) == (0, 0, 1.0)
    assert (c["sooner"], c["later"], c["sign_test_p"]) == (0, 0, 1.0)
    assert c["restricted_mean_difference"] == 0.0
    unlimited = _outcomes("a", [(True, 5), (False, None)]) + _outcomes("b", [(True, 3)] * 2)
    c = paired_comparison(unlimited, "a")["agents"]["b"]
    assert c["restricted_mean_difference"] is None and (c["sooner"], c["later"]) == (0, 0)
    assert c["only_agent"] == 1


def test_only_the_episodes_both_ran_are_paired() -> None:
    base = _outcomes("a", [(False, 9)] * 4)  # seeds 10..13
    other = [EpisodeOutcome("b", seed, True, 1) for seed in (12, 13, 14)]
    c = paired_comparison(base + other, "a")["agents"]["b"]
    assert c["episodes"] == 2 and c["only_agent"] == 2


def test_bad_comparisons_name_what_is_wrong() -> None:
    a = _outcomes("a", [(True, 1)])
    with pytest.raises(ValueError, match="baseline 'z' is not among the agents"):
        paired_comparison(a, "z")
    with pytest.raises(ValueError, match="seed 10 twice"):
        paired_comparison(a + a, "a")
    with pytest.raises(ValueError, match="no episode seed"):
        paired_comparison([*a, EpisodeOutcome("b", 99, True, 1)], "a")


def test_results_csv_reads_back_as_the_records_outcomes(tmp_path: Path) -> None:
    records = evaluate(TEXTBOOK, {"max_episode_steps": 15},
                       {"textbook": TextbookAgent(), "random": RandomAgent(3)}, 4, 7,
                       progress=False)
    paths = write_results(records, summarize(records), tmp_path)
    outcomes = read_outcomes(paths["csv"])
    assert outcomes == outcomes_of(records)
    assert all(o.steps_to_localize_or_limit is not None for o in outcomes)
    markdown = comparison_markdown(paired_comparison(outcomes, "random"))
    assert "| `textbook` | 4 |" in markdown

    bad = tmp_path / "bad.csv"
    bad.write_text("agent,seed,success,steps_to_localize\na,1,yes,\n")
    with pytest.raises(ValueError, match="line 2: success must be True or False"):
        read_outcomes(bad)
    bad.write_text("agent,seed\na,1\n")
    with pytest.raises(ValueError, match=r"not a results\.csv"):
        read_outcomes(bad)


def test_evaluate_with_a_baseline_and_compare_write_the_same_table(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "eval"
    args = ["evaluate", "--env", TEXTBOOK, "--env-kwargs", '{"max_episode_steps": 12}',
            "--agents", "random,textbook", "--episodes", "3", "--seed", "2", "--out", str(out)]
    assert cli_main([*args, "--baseline", "textbook"]) == 0
    printed = capsys.readouterr().out
    data = json.loads((out / "summary.json").read_text())
    paired = data["paired"]
    assert paired["baseline"] == "textbook" and list(paired["agents"]) == ["random"]
    with (out / "results.csv").open(newline="") as f:
        success = {(r["agent"], r["seed"]): r["success"] == "True" for r in csv.DictReader(f)}
    only_random = sum(success["random", s] and not success["textbook", s] for s in "234")
    assert paired["agents"]["random"]["only_agent"] == only_random
    table = comparison_markdown(paired)
    assert table in (out / "summary.md").read_text() and table in printed

    assert cli_main(["compare", str(out / "results.csv"), "--baseline", "textbook"]) == 0
    assert table in capsys.readouterr().out

    assert cli_main([*args, "--baseline", "greedy"]) == 2
    assert "--baseline 'greedy' is not one of --agents" in capsys.readouterr().err
    assert cli_main(["compare", str(tmp_path / "missing.csv"), "--baseline", "a"]) == 2
    assert "active-loc compare: error:" in capsys.readouterr().err
