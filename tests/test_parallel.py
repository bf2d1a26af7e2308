"""The kernels' parallel and serial twins (``active_loc.parallel``) give the same episodes."""

from __future__ import annotations

import multiprocessing
import threading
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import active_loc  # noqa: F401  (registers the ids)
from active_loc import parallel

SMALL = {"n_particles": 3000, "min_particles": 300}
IDS = ["ActiveLoc/LandmarkMCL-v0", "ActiveLoc/GridMCL-v0", "ActiveLoc/GridMarkov-v0"]


def trace(env_id: str, steps: int = 25) -> list[np.ndarray]:
    env = gym.make(env_id, **({} if "Markov" in env_id else SMALL))
    obs, _ = env.reset(seed=11)
    out = [obs]
    rng = np.random.default_rng(11)
    for _ in range(steps):
        obs, reward, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 2))
        out += [obs, np.array([reward])]
        if terminated or truncated:
            out.append(env.reset()[0])
    return out


@pytest.mark.parametrize("env_id", IDS)
def test_serial_and_parallel_twins_give_the_same_episode(env_id):
    parallel_run = trace(env_id)
    result: dict[str, Any] = {}

    def serial() -> None:
        parallel.set_thread_count(1)  # this thread runs the serial twins
        result["trace"] = trace(env_id)

    thread = threading.Thread(target=serial)
    thread.start()
    thread.join()
    for a, b in zip(parallel_run, result["trace"], strict=True):
        np.testing.assert_array_equal(a, b)


def _child(connection: Any) -> None:
    connection.send(trace("ActiveLoc/GridMCL-v0"))


@pytest.mark.skipif("fork" not in multiprocessing.get_all_start_methods(), reason="no fork")
def test_a_child_forked_after_a_parallel_kernel_steps_on_the_serial_twins():
    """GNU OpenMP kills a forked child that launches a parallel kernel once its parent has:
    the child takes the serial twins, with the same results."""
    parent = trace("ActiveLoc/GridMCL-v0")  # launches the parallel twins here
    context = multiprocessing.get_context("fork")
    receiver, sender = context.Pipe(duplex=False)
    child = context.Process(target=_child, args=(sender,))
    child.start()
    sender.close()
    assert receiver.poll(180)
    child_trace = receiver.recv()
    child.join(60)
    assert child.exitcode == 0
    for a, b in zip(parent, child_trace, strict=True):
        np.testing.assert_array_equal(a, b)


def test_thread_count_holds_inside_its_block_only():
    seen: dict[str, Any] = {}

    def body() -> None:
        with parallel.thread_count(1):
            seen["inside"] = parallel.use_parallel()
        seen["after"] = parallel.use_parallel()
        with parallel.thread_count(None):
            seen["none"] = parallel.use_parallel()

    thread = threading.Thread(target=body)
    thread.start()
    thread.join()
    forbidden = parallel.prange_forbidden()
    assert seen == {"inside": False, "after": not forbidden, "none": not forbidden}
