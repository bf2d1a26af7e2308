"""The main job runs end to end: a subprocess smoke test of ``make demo``'s module."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path


def test_demo_trains_evaluates_and_writes_its_report(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    result = subprocess.run(
        [sys.executable, "-m", "active_loc.demo", "--timesteps", "1024", "--n-envs", "2",
         "--episodes", "2", "--out", str(out)],
        capture_output=True, text=True, timeout=600, check=False,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    summary = json.loads((out / "summary.json").read_text())
    assert list(summary["agents"]) == ["PPO", "random", "passive", "greedy", "horizon"]
    assert summary["episodes"] == 2
    for name in ("results.csv", "summary.md", "entropy_vs_step.png", "success_vs_step.png",
                 "train/model.zip", "train/config.json", "train/learning_curve.png"):
        assert (out / name).is_file(), name
    assert "| `PPO` |" in result.stdout
    assert summary["paired"]["baseline"] == "passive"
    assert list(summary["paired"]["agents"]) == ["PPO", "random", "greedy", "horizon"]
    assert "## Against `passive`, episode by episode" in result.stdout
