"""The examples run: ``examples/cleanrl_ppo.py`` trains a few updates and prints its summary."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("torch")
pytest.importorskip("tyro")

ROOT = Path(__file__).resolve().parents[1]
CLEANRL_PPO = ROOT / "examples" / "cleanrl_ppo.py"
SUMMARY = re.compile(
    r"^summary: steps (\d+) wall_time [\d.]+s SPS \d+ final_return (\S+) "
    r"final_success_rate (\S+) \(last (\d+) episodes\)$",
    re.MULTILINE,
)


def _run(tmp_path: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(CLEANRL_PPO), "--env-id", "ActiveLoc/LandmarkEKF-v0",
         "--total-timesteps", "2048", "--num-envs", "8", "--num-steps", "64",
         "--update-epochs", "2", "--log-every", "1", *extra],
        capture_output=True, text=True, timeout=300, check=False, cwd=tmp_path,
    )


@pytest.mark.parametrize("action_type", ["continuous", "discrete"])
def test_cleanrl_ppo_trains_and_prints_its_summary(tmp_path: Path, action_type: str) -> None:
    model = tmp_path / "ppo.pt"
    result = _run(tmp_path, "--action-type", action_type, "--save", str(model),
                  "--track-tb", "--log-dir", str(tmp_path / "tb"))
    assert result.returncode == 0, result.stderr[-3000:]
    match = SUMMARY.search(result.stdout)
    assert match is not None, result.stdout[-3000:]
    assert int(match.group(1)) == 2048  # 4 updates of 8 envs x 64 steps
    assert int(match.group(4)) > 0  # LandmarkEKF-v0 episodes end within 64 steps mostly
    assert 0.0 <= float(match.group(3)) <= 1.0
    assert len(re.findall(r"^update \d+/4 step", result.stdout, re.MULTILINE)) == 4
    assert model.stat().st_size > 0
    assert any((tmp_path / "tb").rglob("events.out.tfevents.*"))
