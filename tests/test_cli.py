"""The ``active-loc`` command: the id list and episode rendering."""

from __future__ import annotations

from pathlib import Path

import pytest

from active_loc.cli import main


def test_envs_lists_every_id(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["envs"]) == 0
    listed = capsys.readouterr().out
    for env_id in ("ActiveLoc/Textbook-v0", "ActiveLoc/GridMarkov-v0", "ActiveLoc/Maze-v0"):
        assert env_id in listed


def test_render_writes_a_gif_of_a_named_agent(tmp_path: Path) -> None:
    out = tmp_path / "maze.gif"
    assert main(["render", "--env", "ActiveLoc/Maze-v0", "--agent", "greedy", "--out",
                 str(out)]) == 0
    assert out.stat().st_size > 1000


def test_render_refuses_an_agent_that_cannot_drive_the_env(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["render", "--env", "ActiveLoc/Maze-v0", "--agent", "wanderer", "--out",
                 str(tmp_path / "x.gif")]) == 2
    assert "unicycle" in capsys.readouterr().err
