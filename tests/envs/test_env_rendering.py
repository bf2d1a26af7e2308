"""Rendering through the env: frame shape, RecordVideo, human mode on a headless machine."""

from __future__ import annotations

import itertools

import gymnasium as gym
import matplotlib
import numpy as np
import pytest
from gymnasium.wrappers import RecordVideo

import active_loc

ENV_IDS = [env_id for env_id, _, _ in active_loc.ENV_IDS]


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_rgb_frames_keep_one_shape_across_steps_and_episodes(env_id: str) -> None:
    env = gym.make(env_id, render_mode="rgb_array")
    frames = []
    for seed in (0, 1):
        env.reset(seed=seed)
        frames.append(env.render())
        for _ in range(5):
            env.step(env.action_space.sample())
            frames.append(env.render())
    shapes = {frame.shape for frame in frames}
    assert len(shapes) == 1
    (shape,) = shapes
    assert shape[2] == 3 and all(frame.dtype == np.uint8 for frame in frames)
    # the robot moves, so consecutive frames differ
    assert any(not np.array_equal(a, b) for a, b in itertools.pairwise(frames))
    env.close()


def test_render_without_mode_warns_and_returns_none() -> None:
    env = gym.make("ActiveLoc/Textbook-v0")
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.unwrapped.render() is None


def test_record_video_writes_an_mp4(tmp_path) -> None:
    pytest.importorskip("moviepy")
    env = RecordVideo(
        gym.make("ActiveLoc/Textbook-v0", render_mode="rgb_array"),
        video_folder=str(tmp_path / "videos"),
        episode_trigger=lambda episode: True,
        disable_logger=True,
    )
    env.reset(seed=0)
    for _ in range(20):
        env.step(np.zeros(2, dtype=np.float32))
    env.close()
    videos = list((tmp_path / "videos").glob("*.mp4"))
    assert videos and videos[0].stat().st_size > 1000


def test_human_mode_runs_headless() -> None:
    matplotlib.use("Agg")
    env = gym.make("ActiveLoc/LandmarkEKF-v0", render_mode="human")
    env.reset(seed=0)
    for _ in range(3):
        env.step(env.action_space.sample())
    env.close()
    assert env.metadata["render_fps"] > 0
