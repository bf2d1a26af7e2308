"""The main job runs end to end: a subprocess smoke test of ``make demo``'s module."""

from __future__ import annotations

import subprocess
import sys


def test_demo_trains_and_compares_with_random_in_a_subprocess() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "active_loc.demo", "--timesteps", "1024", "--n-envs", "2",
         "--episodes", "2"],
        capture_output=True, text=True, timeout=600, check=False,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    lines = result.stdout.splitlines()
    assert any(line.startswith("PPO (trained)") for line in lines), result.stdout
    assert any(line.startswith("random") for line in lines), result.stdout
