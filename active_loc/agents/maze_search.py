"""The maze's shortest way to tell its hypotheses apart, for when no short plan is informative.

``Maze-v0``'s motion and depth sensor are deterministic, so every pose that the belief still
holds (a hypothesis) moves and reads in one way under an action sequence. Once the robot has
turned around and nothing within the planner's horizon would read differently under any
two hypotheses, the lookahead scores every action alike, and turning in place costs the
least: the robot spins to the end of the episode. The way out is to look further: a
breadth-first search over action sequences of the joint state (every hypothesis's pose at
once, deduplicated) finds the fewest steps after which two hypotheses read different
depths, and among the sequences that short, the one whose readings leave the least expected
entropy.
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from active_loc.envs.maze_core import SHIFTS, TURNS, maze_move

#: the most hypotheses the search follows (the most probable ones)
MAX_HYPOTHESES = 256
#: the most joint states the search expands before it gives up
MAX_STATES = 20000


@numba.njit(cache=True, nogil=True)
def move_hypotheses(
    free: NDArray, poses: NDArray, shift: NDArray, turn: int, table: NDArray, out: NDArray,
    readings: NDArray,
) -> None:
    """Every hypothesis ``poses`` ``(k, 3)`` (cell x, cell y, heading bin) moved by one maze
    action (``shift`` ``(4, 2)``, ``turn``) on the free mask ``(X, Y)`` into ``out``, and the
    depth it reads there into ``readings`` ``(k,)``."""
    for i in range(poses.shape[0]):
        x, y, h, _ = maze_move(free, poses[i, 0], poses[i, 1], poses[i, 2], shift, turn)
        out[i, 0] = x
        out[i, 1] = y
        out[i, 2] = h
        readings[i] = table[x, y, h]


def _expected_entropy(weights: NDArray[np.float64], readings: NDArray[np.int64]) -> float:
    """The expected entropy (nats, of the hypotheses' normalized weights ``(k,)``) after the
    readings ``(k,)`` split them."""
    total = 0.0
    for z in np.unique(readings):
        p = weights[readings == z]
        mass = p.sum()
        q = p / mass
        total -= mass * float(np.sum(q * np.log(q)))
    return total


def distinguishing_plan(view: Any, max_steps: int) -> list[int] | None:
    """The fewest maze actions (at most ``max_steps``) after which two of the belief's
    hypotheses read different depths, the least expected entropy among those; ``None`` when
    the belief holds a single pose, or no such sequence is found within ``max_steps`` steps
    and :data:`MAX_STATES` joint states.

    Args:
        view: a :class:`~active_loc.envs.maze_env.MazePlannerView`.
        max_steps: the longest sequence worth finding (the steps left in the episode).
    """
    prob = np.asarray(view.belief.prob)[0]  # (X, Y, 4)
    cells = np.argwhere(prob > 0.0)
    if cells.shape[0] < 2 or max_steps < 1:
        return None
    weights = prob[cells[:, 0], cells[:, 1], cells[:, 2]]
    if cells.shape[0] > MAX_HYPOTHESES:
        keep = np.argsort(-weights, kind="stable")[:MAX_HYPOTHESES]
        cells, weights = cells[keep], weights[keep]
    poses = np.ascontiguousarray(cells, dtype=np.int64)
    weights = weights / weights.sum()
    free = np.ascontiguousarray(np.asarray(view.belief.free)[0])
    table = view.sensor.table
    seen = {poses.tobytes()}
    layer: list[tuple[NDArray[np.int64], list[int]]] = [(poses, [])]
    readings = np.empty(poses.shape[0], dtype=np.int64)
    expanded = 0
    for _ in range(max_steps):
        best: tuple[float, list[int]] | None = None
        following = []
        for state, plan in layer:
            for action in range(3):
                moved = np.empty_like(state)
                move_hypotheses(free, state, SHIFTS[action], int(TURNS[action]), table, moved,
                                readings)
                expanded += 1
                if readings.min() != readings.max():  # the hypotheses read apart here
                    value = _expected_entropy(weights, readings)
                    if best is None or value < best[0] - 1e-12:
                        best = (value, [*plan, action])
                    continue
                key = moved.tobytes()
                if key not in seen:
                    seen.add(key)
                    following.append((moved, [*plan, action]))
        if best is not None:
            return best[1]
        if not following or expanded > MAX_STATES:
            return None
        layer = following
    return None
