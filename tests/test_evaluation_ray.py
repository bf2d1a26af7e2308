"""``active-loc evaluate --ray``: the episodes as Ray tasks give the serial run's files.

The Ray tests are skipped when ray is not installed (``pip install "active-loc[ray]"``); the
per-episode reseeding they rely on, and the message without ray, are tested either way.
"""

from __future__ import annotations

import importlib.util
import json
import sys
from collections.abc import Iterator
from dataclasses import asdict
from pathlib import Path
from typing import Any

import gymnasium as gym
import pytest
from gymnasium.utils import seeding

import active_loc  # noqa: F401
from active_loc.agents import make_agent
from active_loc.cli import main as cli_main
from active_loc.evaluation import agent_rng, evaluate, evaluate_ray, reseed_agent

ENV = "ActiveLoc/LandmarkEKF-v0"
SHORT = {"max_episode_steps": 40}
AGENTS = ("random", "greedy[n_hypotheses=2]")  # a spec with parameters, rebuilt by each task


def _agents(seed: int = 0) -> dict[str, Any]:
    env = gym.make(ENV, **SHORT)
    try:
        return {spec: make_agent(spec, env, seed) for spec in AGENTS}
    finally:
        env.close()


def _without_ids(record: Any) -> dict[str, Any]:
    fields = asdict(record)
    del fields["episode"]
    return fields


# --- per-episode seeding (no ray needed) -------------------------------------------------------


def test_an_episode_does_not_depend_on_the_episodes_before_it() -> None:
    four = evaluate(ENV, SHORT, _agents(), 4, 10, progress=False)
    # episode 2 of the run from seed 10 is episode 0 of a run from seed 12, whatever the
    # agents' own seeds and whatever they drew in episodes 0 and 1
    one = evaluate(ENV, SHORT, _agents(seed=99), 1, 12, progress=False)
    assert [_without_ids(r) for r in one] == [_without_ids(four[2]), _without_ids(four[6])]
    assert [r.episode for r in one] == [0, 0] and four[2].episode == 2


def test_reseed_agent_gives_a_stream_apart_from_the_envs() -> None:
    agent = _agents()["random"]
    reseed_agent(agent, 5)
    first = agent.rng.random(3)
    assert (agent_rng(5).random(3) == first).all()
    env_rng, _ = seeding.np_random(5)  # what env.reset(seed=5) draws from
    assert not (env_rng.random(3) == first).any()
    reseed_agent(object(), 5)  # an agent without rng or reset(): nothing to do


def test_evaluate_ray_without_ray_says_what_to_install(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    with pytest.raises(ImportError, match=r'pip install "active-loc\[ray\]"'):
        evaluate_ray(ENV, SHORT, {"random": "random"}, 1, 0, progress=False)
    real_find_spec = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec",
        lambda name, *a: None if name == "ray" else real_find_spec(name, *a),
    )
    out = tmp_path / "eval"
    code = cli_main(["evaluate", "--env", ENV, "--agents", "random", "--episodes", "1",
                     "--out", str(out), "--ray"])
    assert code == 2
    assert 'pip install "active-loc[ray]"' in capsys.readouterr().err
    assert not out.exists()


# --- with ray ----------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def local_ray() -> Iterator[Any]:
    ray = pytest.importorskip("ray")
    if ray.is_initialized():
        ray.shutdown()
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        yield ray
    finally:
        ray.shutdown()


def test_cli_evaluate_with_ray_writes_the_serial_files(
    local_ray: Any, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = ["evaluate", "--env", ENV, "--env-kwargs", json.dumps(SHORT), "--agents",
            ",".join(AGENTS), "--episodes", "4", "--seed", "3"]
    assert cli_main([*base, "--out", str(tmp_path / "serial")]) == 0
    assert cli_main([*base, "--out", str(tmp_path / "ray"), "--ray"]) == 0
    assert local_ray.is_initialized()  # the CLI used the Ray it found and left it running
    capsys.readouterr()
    for name in ("results.csv", "summary.json", "summary.md"):
        serial = (tmp_path / "serial" / name).read_text()
        assert (tmp_path / "ray" / name).read_text() == serial, name
    rows = (tmp_path / "ray" / "results.csv").read_text().splitlines()
    assert len(rows) == 1 + 2 * 4
    summary = json.loads((tmp_path / "ray" / "summary.json").read_text())
    assert list(summary["agents"]) == list(AGENTS) and summary["seed"] == 3


def test_evaluate_ray_chunks_give_the_serial_records(local_ray: Any) -> None:
    serial = evaluate(ENV, SHORT, _agents(), 5, 0, progress=False)
    for chunk_size in (2, 5):  # an uneven split; one task per agent
        records = evaluate_ray(ENV, SHORT, {name: name for name in AGENTS}, 5, 0,
                               progress=False, chunk_size=chunk_size)
        assert records == serial
