"""Paired comparison of agents that ran the same seeded episodes.

Every agent of an evaluation meets the same episodes (episode ``i`` is reset with seed
``S + i``), so two agents can be compared episode by episode, which separates a real
difference from the luck of the draw far better than two success rates side by side. For each
agent against a ``baseline``, over the episodes both ran (matched by their reset seed):

* **success**: ``only_agent`` (episodes the agent localized and the baseline did not),
  ``only_baseline`` (the other way round) and ``mcnemar_p``, McNemar's exact test: the
  two-sided binomial test of ``only_agent`` out of ``only_agent + only_baseline`` at 1/2
  (1.0 when no episode differs).
* **steps**: each episode's steps to localize, an episode never localized counting as its step
  limit (:attr:`active_loc.evaluation.EpisodeRecord.steps_to_localize_or_limit`). ``sooner``
  and ``later`` count the episodes where the agent's is smaller or larger than the baseline's,
  ``sign_test_p`` is the two-sided sign test on them (ties left out, 1.0 with none left), and
  ``restricted_mean_difference`` is the mean of agent minus baseline (negative: sooner; None,
  and the counts 0, when an episode has no step limit).

:func:`comparison_markdown` writes the result as a table; ``active-loc evaluate --baseline
NAME`` adds it to ``summary.json`` (key ``"paired"``) and ``summary.md``, and ``active-loc
compare`` computes it from ``results.csv`` files of earlier runs.
"""

from __future__ import annotations

import csv
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any


@dataclass(frozen=True)
class EpisodeOutcome:
    """What a paired comparison needs of one episode of one agent.

    Attributes:
        agent: the agent's name; seed: the episode's reset seed.
        success: localized at the end (``is_success``).
        steps_to_localize_or_limit: the first step with ``is_success``, or the env's step limit
            if there was none; None if neither exists.
    """

    agent: str
    seed: int
    success: bool
    steps_to_localize_or_limit: int | None


def outcomes_of(records: Iterable[Any]) -> list[EpisodeOutcome]:
    """The outcomes of :class:`active_loc.evaluation.EpisodeRecord` objects."""
    return [
        EpisodeOutcome(r.agent, r.seed, r.success, r.steps_to_localize_or_limit) for r in records
    ]


def _int_or_none(cell: str) -> int | None:
    return None if cell == "" else int(cell)


def read_outcomes(path: str | Path) -> list[EpisodeOutcome]:
    """The outcomes in a ``results.csv`` written by ``active-loc evaluate``.

    Raises:
        ValueError: the file lacks a column the comparison needs, or a cell is malformed.
    """
    needed = {"agent", "seed", "success", "steps_to_localize"}
    outcomes = []
    with Path(path).open(newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        missing = needed - set(reader.fieldnames or ())
        if missing:
            raise ValueError(f"{path} is not a results.csv: no column {sorted(missing)}")
        for line, row in enumerate(reader, start=2):
            try:
                if row["success"] not in ("True", "False"):
                    raise ValueError(f"success must be True or False, got {row['success']!r}")
                steps = _int_or_none(row["steps_to_localize"])
                # results.csv files written before the step_limit column have no limit
                limit = _int_or_none(row.get("step_limit") or "")
                outcomes.append(EpisodeOutcome(
                    row["agent"], int(row["seed"]), row["success"] == "True",
                    limit if steps is None else steps,
                ))
            except ValueError as error:
                raise ValueError(f"{path}, line {line}: {error}") from None
    return outcomes


def _by_agent(outcomes: Iterable[EpisodeOutcome]) -> dict[str, dict[int, EpisodeOutcome]]:
    """agent -> seed -> outcome, in first-seen order; an agent with a seed twice is an error."""
    agents: dict[str, dict[int, EpisodeOutcome]] = {}
    for outcome in outcomes:
        episodes = agents.setdefault(outcome.agent, {})
        if outcome.seed in episodes:
            raise ValueError(f"agent {outcome.agent!r} has episode seed {outcome.seed} twice")
        episodes[outcome.seed] = outcome
    return agents


def _two_sided_binomial_p(k: int, n: int) -> float:
    """P-value of ``k`` successes in ``n`` fair trials, two-sided; 1.0 for ``n = 0``."""
    if n == 0:
        return 1.0
    from scipy import stats

    return float(stats.binomtest(k, n, 0.5).pvalue)


def _paired(agent: Mapping[int, EpisodeOutcome], baseline: Mapping[int, EpisodeOutcome],
            seeds: Sequence[int]) -> dict[str, Any]:
    only_agent = sum(agent[s].success and not baseline[s].success for s in seeds)
    only_baseline = sum(baseline[s].success and not agent[s].success for s in seeds)
    steps = [(agent[s].steps_to_localize_or_limit, baseline[s].steps_to_localize_or_limit)
             for s in seeds]
    timed = [(a, b) for a, b in steps if a is not None and b is not None]
    if len(timed) < len(steps):  # an episode without a step limit: no comparison of steps
        timed = []
    sooner = sum(a < b for a, b in timed)
    later = sum(a > b for a, b in timed)
    return {
        "episodes": len(seeds),
        "only_agent": only_agent,
        "only_baseline": only_baseline,
        "mcnemar_p": _two_sided_binomial_p(only_agent, only_agent + only_baseline),
        "sooner": sooner,
        "later": later,
        "sign_test_p": _two_sided_binomial_p(sooner, sooner + later),
        "restricted_mean_difference": (
            sum(a - b for a, b in timed) / len(timed) if timed else None
        ),
    }


def paired_comparison(outcomes: Iterable[EpisodeOutcome], baseline: str) -> dict[str, Any]:
    """Every other agent against ``baseline`` on the episodes both ran (see the module
    docstring for the keys).

    Returns:
        ``{"baseline": baseline, "agents": {name: {"episodes", "only_agent", "only_baseline",
        "mcnemar_p", "sooner", "later", "sign_test_p", "restricted_mean_difference"}}}``, the
        agents in the order they first appear.

    Raises:
        ValueError: ``baseline`` is not among the agents, an agent has an episode seed twice,
            or an agent shares no episode with the baseline.
    """
    agents = _by_agent(outcomes)
    if baseline not in agents:
        raise ValueError(f"baseline {baseline!r} is not among the agents {list(agents)}")
    reference = agents[baseline]
    result: dict[str, Any] = {}
    for name, episodes in agents.items():
        if name == baseline:
            continue
        seeds = [seed for seed in episodes if seed in reference]
        if not seeds:
            raise ValueError(f"agent {name!r} ran no episode seed that {baseline!r} ran")
        result[name] = _paired(episodes, reference, seeds)
    return {"baseline": baseline, "agents": result}


def _p(value: float) -> str:
    return f"{value:.2g}" if value < 0.01 else f"{value:.2f}"


def comparison_markdown(comparison: Mapping[str, Any]) -> str:
    """``comparison`` (as :func:`paired_comparison` returns it) as a Markdown table."""
    baseline = comparison["baseline"]
    lines = [
        f"## Against `{baseline}`, episode by episode",
        "",
        f"| agent | episodes | only it localized / only `{baseline}` | McNemar p | sooner / "
        "later | sign test p | restricted mean difference (steps) |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, c in comparison["agents"].items():
        difference = c["restricted_mean_difference"]
        lines.append(
            f"| `{name}` | {c['episodes']} | {c['only_agent']} / {c['only_baseline']} | "
            f"{_p(c['mcnemar_p'])} | {c['sooner']} / {c['later']} | {_p(c['sign_test_p'])} | "
            f"{'n/a' if difference is None else f'{difference:+.1f}'} |"
        )
    lines += [
        "",
        "Paired by episode seed. McNemar's exact test on the episodes where exactly one of the "
        "two localized; sooner / later: episodes where the agent's steps to localize (an "
        "episode never localized counting as the step limit) are fewer / more than the "
        f"baseline's, with the sign test; the difference is the agent's mean minus `{baseline}`'s "
        "(negative: sooner).",
        "",
    ]
    return "\n".join(lines)
