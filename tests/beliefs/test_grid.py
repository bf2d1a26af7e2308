"""Tests of the grid Markov filter (``active_loc.beliefs.grid``) and the maze depth sensor.

The reference is brute-force Bayes written here in plain Python: a dict over every pose
``(x, y, h)``, the motion applied outcome by outcome with the documented blocking rule, the
measurement multiplied in and normalized by hand. The filter must agree to 1e-12 (to 1e-8 with
fractional motion, whose weights the reference integrates numerically).
"""

from __future__ import annotations

import copy
import math
import pickle
from collections import defaultdict
from fractions import Fraction

import numpy as np
import pytest
from scipy.integrate import quad

from active_loc.beliefs.grid import (
    GridBelief,
    MotionKernel,
    coarse_free_mask,
    update_log_kernel,
    update_log_kernel_parallel,
)
from active_loc.beliefs.grid_motion import axis_weights, fractional_kernel
from active_loc.beliefs.mcl import landmark_log_likelihood
from active_loc.envs.maze_env import TURN_LEFT, TURN_RIGHT, MazeMotion
from active_loc.maps.maze import eller_maze, maze_to_grid
from active_loc.maps.occupancy import FREE, OCCUPIED, OccupancyGrid
from active_loc.sensors import RANGE_BEARING
from active_loc.sensors.depth import DepthSensor, depth_table, reading_likelihood
from active_loc.sensors.lidar import LidarSensor

# a tiny map, drawn with row y = 2 on top ('#' = occupied), indexed free[x, y]
TINY = ["..#.",
        ".#..",
        "...#"]  # fmt: skip


def parse(rows: list[str]) -> np.ndarray:
    """``free[x, y]`` from text rows, the first row being the top (largest y)."""
    grid = np.array([[c != "#" for c in row] for row in rows[::-1]])  # [y, x]
    return np.ascontiguousarray(grid.T)


# --- brute force -----------------------------------------------------------------------------


def path_cells(x: int, y: int, dx: int, dy: int) -> list[tuple[int, int]]:
    """The documented path of a translation: cells at floor(d i / n + 1/2), i = 1..n."""
    n = max(abs(dx), abs(dy))
    half = Fraction(1, 2)
    return [
        (x + math.floor(Fraction(dx * i, n) + half), y + math.floor(Fraction(dy * i, n) + half))
        for i in range(1, n + 1)
    ]


def brute_predict(
    bel: dict, free: np.ndarray, n_h: int, shift, turn: int, outcomes
) -> dict:
    nx, ny = free.shape
    out: dict = defaultdict(float)
    for (x, y, h), p in bel.items():
        for ox, oy, oh, w in outcomes:
            dx, dy = int(shift[h][0]) + ox, int(shift[h][1]) + oy
            th = (h + turn + oh) % n_h
            path = path_cells(x, y, dx, dy)
            ok = (dx, dy) != (0, 0) and all(
                0 <= cx < nx and 0 <= cy < ny and free[cx, cy] for cx, cy in path
            )
            target = (x + dx, y + dy, th) if ok else (x, y, th)
            out[target] += p * w
    return dict(out)


def brute_update(bel: dict, likelihood: np.ndarray) -> dict:
    post = {pose: p * float(likelihood[pose]) for pose, p in bel.items()}
    total = sum(post.values())
    return {pose: p / total for pose, p in post.items()}


def as_dict(prob: np.ndarray) -> dict:
    return {
        (x, y, h): float(prob[x, y, h])
        for x in range(prob.shape[0])
        for y in range(prob.shape[1])
        for h in range(prob.shape[2])
    }


def assert_matches(belief: GridBelief, bel: dict, b: int = 0) -> None:
    for (x, y, h), p in as_dict(belief.prob[b]).items():
        assert abs(p - bel.get((x, y, h), 0.0)) <= 1e-12, (x, y, h)


def walk_depth(free: np.ndarray, x: int, y: int, h: int) -> int:
    """Depth by walking, plain Python: cells from (x, y) counted as 1 until a wall."""
    step = [(1, 0), (0, 1), (-1, 0), (0, -1)][h]
    d = 0
    while 0 <= x < free.shape[0] and 0 <= y < free.shape[1] and free[x, y]:
        d += 1
        x, y = x + step[0], y + step[1]
    return d


# --- brute-force Bayes -----------------------------------------------------------------------


@pytest.mark.parametrize("n_headings", [4, 8])
def test_noisy_prediction_and_correction_equal_brute_force_bayes(n_headings: int) -> None:
    free = parse(TINY)
    rng = np.random.default_rng(0)
    belief = GridBelief(free, n_headings)
    start = rng.random((1, *free.shape, n_headings)) * free[None, :, :, None]
    belief.set_prob(start)
    bel = {k: v for k, v in as_dict(start[0] / start.sum()).items() if free[k[0], k[1]]}
    assert_matches(belief, bel)

    kernel = MotionKernel(
        np.array([[0, 0, 0], [1, 0, 0], [0, -1, 1], [-1, 1, -1], [2, 1, 0], [0, 0, 3]]),
        np.array([0.5, 0.1, 0.1, 0.1, 0.1, 0.1]),
    )
    angles = 2 * np.pi * np.arange(n_headings) / n_headings
    forward = np.stack([np.round(np.cos(angles)), np.round(np.sin(angles))], 1).astype(int)
    commands = [(forward, 0), (2 * forward, 0), (np.zeros_like(forward), 1), (forward, -1)]
    for step in range(12):
        shift, turn = commands[step % len(commands)]
        noisy = step % 2 == 0
        outcomes = (
            list(zip(*kernel.offsets.T.tolist(), kernel.weights.tolist(), strict=True))
            if noisy
            else [(0, 0, 0, 1.0)]
        )
        belief.predict(shift, turn, kernel if noisy else None)
        bel = brute_predict(bel, free, n_headings, shift, turn, outcomes)
        assert_matches(belief, bel)
        assert belief.prob[0][~free].sum() == 0.0  # no mass in occupied cells
        likelihood = rng.random((*free.shape, n_headings))
        likelihood[rng.random(likelihood.shape) < 0.2] = 0.0
        belief.update(likelihood)
        bel = brute_update(bel, likelihood)
        assert_matches(belief, bel)


def test_maze_episode_equals_brute_force_bayes_over_every_pose() -> None:
    walls = eller_maze(7, np.random.default_rng(3))
    free = np.ascontiguousarray(~walls.T)
    sensor = DepthSensor.from_free(free)
    motion = MazeMotion()
    belief = GridBelief(free)
    poses = [(x, y, h) for x in range(7) for y in range(7) for h in range(4) if free[x, y]]
    bel = {pose: 1.0 / len(poses) for pose in poses}
    rng = np.random.default_rng(4)
    truth = poses[int(rng.integers(len(poses)))]

    def observe(bel: dict, truth: tuple) -> dict:
        z = walk_depth(free, *truth)
        post = {p: w for p, w in bel.items() if walk_depth(free, *p) == z}
        total = sum(post.values())
        belief.update(sensor.likelihood(z))
        return {p: w / total for p, w in post.items()}

    bel = observe(bel, truth)
    assert_matches(belief, bel)
    for action in rng.integers(3, size=40).tolist():
        def move(pose: tuple, action: int = action) -> tuple:
            x, y, h = pose
            if action == TURN_LEFT:
                return (x, y, (h + 1) % 4)
            if action == TURN_RIGHT:
                return (x, y, (h - 1) % 4)
            dx, dy = [(1, 0), (0, 1), (-1, 0), (0, -1)][h]
            return (x + dx, y + dy, h) if free[x + dx, y + dy] else pose

        predicted: dict = defaultdict(float)
        for pose, w in bel.items():
            predicted[move(pose)] += w
        truth = move(truth)
        motion.predict(belief, action)
        assert_matches(belief, dict(predicted))
        bel = observe(dict(predicted), truth)
        assert_matches(belief, bel)
        assert bel.get(truth, 0.0) > 0.0  # the exact filter never loses the truth


# --- the motion model ------------------------------------------------------------------------


def test_blocked_mass_stays_in_its_cell_and_still_turns() -> None:
    free = parse(["...",
                  ".#.",
                  "..."])  # fmt: skip
    belief = GridBelief(free)
    prob = np.zeros((1, 3, 3, 4))
    prob[0, 0, 1, 0] = 0.5  # west of the pillar, facing it (east)
    prob[0, 0, 0, 0] = 0.5  # bottom-left corner, facing east: free ahead
    belief.set_prob(prob)
    belief.predict(np.array([[1, 0], [0, 1], [-1, 0], [0, -1]]), turn=1)
    assert belief.prob[0, 0, 1, 1] == 0.5  # blocked: stayed, turned to north
    assert belief.prob[0, 1, 0, 1] == 0.5  # moved east, turned
    assert belief.prob.sum() == 1.0

    # the map's edge blocks like a wall; a turn alone is never blocked
    prob = np.zeros((1, 3, 3, 4))
    prob[0, 2, 2, 0] = 1.0
    belief.set_prob(prob)
    belief.predict(np.array([[1, 0], [0, 1], [-1, 0], [0, -1]]))
    assert belief.prob[0, 2, 2, 0] == 1.0
    belief.predict(np.zeros((4, 2), dtype=int), turn=-1)
    assert belief.prob[0, 2, 2, 3] == 1.0


def test_a_long_translation_is_blocked_by_any_cell_on_its_path() -> None:
    free = parse(["....",
                  "....",
                  ".#.."])  # fmt: skip
    belief = GridBelief(free, n_headings=1)
    one = np.zeros((1, 4, 3, 1))
    one[0, 0, 0, 0] = 1.0
    belief.set_prob(one)
    belief.predict(np.array([[3, 0]]))  # through (1, 0): blocked
    assert belief.prob[0, 0, 0, 0] == 1.0
    belief.predict(np.array([[2, 1]]))  # path (1, 1) then (2, 1): free
    assert belief.prob[0, 2, 1, 0] == 1.0
    belief.set_prob(one)
    belief.predict(np.array([[2, 0]]), kernel=MotionKernel(np.array([[0, 1, 0]]), np.ones(1)))
    assert belief.prob[0, 2, 1, 0] == 1.0


def test_noise_never_puts_mass_in_walls() -> None:
    walls = eller_maze(9, np.random.default_rng(0))
    free = np.ascontiguousarray(~walls.T)
    belief = GridBelief(free)
    kernel = MotionKernel(
        np.array([[0, 0, 0], [1, 1, 0], [-2, 0, 1], [0, 3, 2]]), np.array([0.4, 0.2, 0.2, 0.2])
    )
    for _ in range(10):
        belief.predict(np.array([[1, 0], [0, 1], [-1, 0], [0, -1]]), 1, kernel)
        assert belief.prob[0][~free].sum() == 0.0
        assert abs(belief.prob.sum() - 1.0) < 1e-12


def test_batch_members_are_independent_filters() -> None:
    mazes = [eller_maze(7, np.random.default_rng(s)) for s in (1, 2)]
    free = np.stack([np.ascontiguousarray(~w.T) for w in mazes])
    batch = GridBelief(free)
    singles = [GridBelief(f) for f in free]
    shifts = np.array([[[1, 0], [0, 1], [-1, 0], [0, -1]], [[0, 0]] * 4])
    batch.predict(shifts, np.array([0, 1]))
    singles[0].predict(shifts[0], 0)
    singles[1].predict(shifts[1], 1)
    sensors = [DepthSensor.from_free(f) for f in free]
    batch.update(np.stack([sensors[0].likelihood(2), sensors[1].likelihood(3)]))
    singles[0].update(sensors[0].likelihood(2))
    singles[1].update(sensors[1].likelihood(3))
    for b in range(2):
        assert np.array_equal(batch.prob[b], singles[b].prob[0])
    assert np.array_equal(batch.entropy(), [s.entropy()[0] for s in singles])


def test_per_member_unicycle_controls_equal_each_member_alone() -> None:
    """Members with their own (V, omega), one of them standing still, step exactly as
    one-member beliefs given the same control; so does a member copied in with set_member."""
    walls = eller_maze(9, np.random.default_rng(4))
    free = np.ascontiguousarray(~walls.T)
    batch = GridBelief(free, 16, batch_size=3)
    singles = [GridBelief(free, 16) for _ in range(3)]
    controls = [(0.9, 0.4), (0.0, 0.0), (0.5, -1.2)]
    for k in range(6):
        v, omega = np.array(controls).T * (-1) ** k
        batch.predict_unicycle(v, omega, 0.5, noise_std=(0.1, 0.1, 0.05))
        for single, vb, ob in zip(singles, v, omega, strict=True):
            single.predict_unicycle(float(vb), float(ob), 0.5, noise_std=(0.1, 0.1, 0.05))
    for b in range(3):
        assert np.array_equal(batch.prob[b], singles[b].prob[0])
    other = np.ascontiguousarray(~eller_maze(9, np.random.default_rng(5)).T)
    source = GridBelief(other, 16)
    source.predict_unicycle(0.7, 0.3, 0.5, noise_std=(0.1, 0.1, 0.05))
    batch.set_member(1, source)
    assert np.array_equal(batch.prob[1], source.prob[0])
    assert np.array_equal(batch.free[1], other) and np.array_equal(batch.free[0], free)
    assert np.array_equal(batch.clearance[1], source.clearance[0])
    batch.predict_unicycle(0.6, 0.2, 0.5, noise_std=(0.1, 0.1, 0.05))
    source.predict_unicycle(0.6, 0.2, 0.5, noise_std=(0.1, 0.1, 0.05))
    singles[0].predict_unicycle(0.6, 0.2, 0.5, noise_std=(0.1, 0.1, 0.05))
    assert np.array_equal(batch.prob[1], source.prob[0])
    assert np.array_equal(batch.prob[0], singles[0].prob[0])


def test_set_member_refuses_a_belief_on_other_cells() -> None:
    batch = GridBelief(np.ones((4, 5), dtype=bool), 8, batch_size=2)
    with pytest.raises(ValueError, match="one-member belief of shape"):
        batch.set_member(0, GridBelief(np.ones((5, 4), dtype=bool), 8))
    with pytest.raises(ValueError, match="one-member belief of shape"):
        batch.set_member(0, GridBelief(np.ones((4, 5), dtype=bool), 8, batch_size=2))
    with pytest.raises(ValueError, match="cells"):
        batch.set_member(0, GridBelief(np.ones((4, 5), dtype=bool), 8, cell_size=0.5))


# --- correction, collapse, statistics --------------------------------------------------------


def test_total_collapse_reinitializes_uniform_over_free_poses() -> None:
    free = parse(TINY)
    belief = GridBelief(free)
    lik = np.zeros((*free.shape, 4))
    lik[0, 0, 0] = 1.0
    assert belief.update(lik)[0] > 0.0
    assert belief.prob[0, 0, 0, 0] == 1.0
    lik = np.zeros((*free.shape, 4))
    lik[3, 2, 1] = 5.0  # only a pose the belief has ruled out
    evidence = belief.update(lik)
    assert evidence[0] == 0.0
    uniform = free[:, :, None] / (free.sum() * 4) * np.ones(4)
    assert np.array_equal(belief.prob[0], uniform)
    assert not np.isnan(belief.prob).any()
    assert np.isneginf(belief.update_log(np.full((*free.shape, 4), -np.inf)))[0]
    assert np.array_equal(belief.prob[0], uniform)


def test_update_log_matches_update_and_survives_tiny_likelihoods() -> None:
    free = parse(TINY)
    rng = np.random.default_rng(1)
    ll = rng.normal(-1000.0, 3.0, (*free.shape, 4))  # exp() underflows to 0 without a shift
    a, b = GridBelief(free), GridBelief(free)
    log_evidence = a.update_log(ll)
    b.update(np.exp(ll - ll.max()))
    assert np.allclose(a.prob, b.prob, rtol=0, atol=1e-15)
    assert a.prob.max() < 1.0
    expected = np.log(np.sum(np.exp(ll - ll.max()) * free[:, :, None] / (free.sum() * 4)))
    assert log_evidence[0] == pytest.approx(expected + ll.max(), rel=1e-12)


def test_update_log_shifts_each_member_by_its_own_maximum_in_both_twins() -> None:
    free = parse(TINY)
    rng = np.random.default_rng(4)
    ll = rng.normal(0.0, 3.0, (3, *free.shape, 4)) + np.array([-900.0, 0.0, 700.0])[:, None,
                                                                                None, None]
    ll[1] = -np.inf  # a member no pose explains: re-initialized, log evidence -inf
    ll[2, 0, 0, 0] = -np.inf
    reference = GridBelief(free, batch_size=3)
    belief = reference.copy()
    tops = np.array([ll[0].max(), 0.0, ll[2].max()])
    evidence = reference.update(np.exp(ll - tops[:, None, None, None]))
    log_evidence = belief.update_log(ll)
    # the kernel's exp and NumPy's (SIMD, chosen by the CPU) may differ in the last bit
    np.testing.assert_allclose(belief.prob, reference.prob, rtol=1e-13, atol=0.0)
    np.testing.assert_allclose(log_evidence[[0, 2]], np.log(evidence[[0, 2]]) + tops[[0, 2]],
                               rtol=1e-13)
    assert np.isneginf(log_evidence[1])
    prob = {}
    for kernel in (update_log_kernel, update_log_kernel_parallel):
        state = GridBelief(free, batch_size=3).copy()
        out = np.empty(3), np.empty(3)
        assert kernel(state._prob, ll, state._free, np.empty_like(state._prob), *out)
        prob[kernel] = state._prob.copy()
    assert np.array_equal(prob[update_log_kernel], prob[update_log_kernel_parallel])
    assert np.array_equal(prob[update_log_kernel], belief.prob)


def test_entropy_is_histogram_entropy_plus_log_cell_volume() -> None:
    free = parse(TINY)
    n_free = int(free.sum())
    belief = GridBelief(free, n_headings=8, cell_size=0.5)
    log_volume = math.log(0.5 * 0.5 * 2 * math.pi / 8)
    assert belief.entropy()[0] == pytest.approx(math.log(n_free * 8) + log_volume, abs=1e-12)
    lik = np.zeros((*free.shape, 8))
    lik[0, 0, 3] = 1.0
    belief.update(lik)
    assert belief.entropy()[0] == pytest.approx(log_volume, abs=1e-15)
    maze = GridBelief(free)  # 1 m cells, 4 headings: the maze's log(pi / 2)
    lik = np.zeros((*free.shape, 4))
    lik[0, 0, 0] = lik[1, 0, 0] = 1.0
    maze.update(lik)
    assert maze.entropy()[0] == pytest.approx(math.log(2) + math.log(math.pi / 2), abs=1e-12)


def test_mode_max_and_summary_agree() -> None:
    free = parse(TINY)
    belief = GridBelief(free)
    lik = np.ones((*free.shape, 4))
    lik[2, 1, 3] = 7.0
    belief.update(lik)
    assert belief.mode().tolist() == [[2, 1, 3]]
    assert belief.max_prob()[0] == pytest.approx(7.0 / (free.sum() * 4 + 6))
    entropy, mode, top = belief.summary()
    assert np.array_equal(entropy, belief.entropy())
    assert np.array_equal(mode, belief.mode())
    assert np.array_equal(top, belief.max_prob())


def test_copy_pickle_and_deepcopy_are_deep() -> None:
    belief = GridBelief(parse(TINY))
    for twin in (belief.copy(), pickle.loads(pickle.dumps(belief)), copy.deepcopy(belief)):
        assert np.array_equal(twin.prob, belief.prob)
        twin.predict(np.array([[1, 0], [0, 1], [-1, 0], [0, -1]]))
        twin.update(np.random.default_rng(0).random((4, 3, 4)))
        assert not np.array_equal(twin.prob, belief.prob)
        assert not twin.free.flags.writeable
    assert not belief.prob.flags.writeable


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda b: b.update(np.ones((3, 3, 4))), "likelihood"),
        (lambda b: b.update(-np.ones((4, 3, 4))), "likelihood"),
        (lambda b: b.update(np.full((4, 3, 4), np.nan)), "likelihood"),
        (lambda b: b.update_log(np.full((4, 3, 4), np.inf)), "log_likelihood"),
        (lambda b: b.update_log(np.full((4, 3, 4), np.nan)), "log_likelihood"),
        (lambda b: b.predict(np.zeros((3, 2), dtype=int)), "shift"),
        (lambda b: b.predict(np.zeros((4, 2))), "shift"),
        (lambda b: b.predict(np.zeros((4, 2), dtype=int), turn=np.zeros(2, dtype=int)), "turn"),
        (lambda b: b.set_prob(np.ones((1, 4, 3, 4))), "occupied"),
    ],
)
def test_bad_input_raises_value_error(call, match: str) -> None:
    belief = GridBelief(parse(TINY))
    before = belief.prob.copy()
    with pytest.raises(ValueError, match=match):
        call(belief)
    assert np.array_equal(belief.prob, before)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"free": np.zeros((3, 3), dtype=bool)}, "free"),
        ({"free": np.ones((3, 3))}, "free"),
        ({"free": np.ones((3, 3), dtype=bool), "n_headings": 0}, "n_headings"),
        ({"free": np.ones((3, 3), dtype=bool), "cell_size": -1.0}, "cell_size"),
        ({"free": np.ones((3, 3), dtype=bool), "batch_size": 0}, "batch_size"),
    ],
)
def test_bad_configuration_names_the_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        GridBelief(**kwargs)


def test_motion_kernel_validation() -> None:
    with pytest.raises(ValueError, match="weights"):
        MotionKernel(np.zeros((2, 3), dtype=int), np.array([0.5, 0.6]))
    with pytest.raises(ValueError, match="offsets"):
        MotionKernel(np.zeros((2, 3)), np.array([0.5, 0.5]))
    with pytest.raises(ValueError, match="offsets"):
        MotionKernel(np.zeros((2, 2), dtype=int), np.array([0.5, 0.5]))


# --- any sensor model ------------------------------------------------------------------------


def small_room() -> OccupancyGrid:
    """A 6 m x 4 m room at 0.5 m cells with an L-shaped block: no symmetry."""
    values = np.full((8, 12), FREE, dtype=np.int8)
    values[0, :] = values[-1, :] = values[:, 0] = values[:, -1] = OCCUPIED
    values[2:4, 3:5] = OCCUPIED
    values[2, 5:7] = OCCUPIED
    return OccupancyGrid(values, 0.5, origin=(1.0, -2.0, 0.0))


def test_cell_poses_are_the_grid_cell_centres_and_heading_bins() -> None:
    grid = small_room()
    belief = GridBelief.from_grid(grid, n_headings=8)
    poses = belief.cell_poses()
    assert poses.shape == (12, 8, 8, 3)
    assert np.array_equal(poses[3, 5, 0, :2], grid.cell_to_world([3, 5]))
    assert poses[0, 0, 2, 2] == pytest.approx(np.pi / 2)
    assert poses[0, 0, 4, 2] == pytest.approx(-np.pi)  # wrapped to [-pi, pi)
    assert np.array_equal(belief.free[0], grid.values.T == FREE)


def test_lidar_correction_through_cell_poses_finds_the_true_pose() -> None:
    grid = small_room()
    belief = GridBelief.from_grid(grid, n_headings=8)
    lidar = LidarSensor(n_beams=24, max_range=8.0, sigma_hit=0.1)
    poses = belief.cell_poses()
    truth = poses[8, 5, 3]
    z = lidar.expected_ranges(truth[None], grid.kernel_arrays())[0]
    ll = lidar.log_likelihood(z, poses.reshape(-1, 3), grid.kernel_arrays(), grid.distance_field())
    belief.update_log(ll.reshape(poses.shape[:3]))
    assert belief.mode().tolist() == [[8, 5, 3]]
    assert belief.max_prob()[0] > 0.5


def test_landmark_correction_through_cell_poses_finds_the_true_pose() -> None:
    grid = small_room()
    belief = GridBelief.from_grid(grid, n_headings=8)
    landmarks = np.array([[2.0, -1.0], [6.0, 1.0], [4.5, 0.8]])
    poses = belief.cell_poses()
    x, y, th = poses[4, 5, 6]
    d = landmarks - [x, y]
    bearing = (np.arctan2(d[:, 1], d[:, 0]) - th + np.pi) % (2 * np.pi) - np.pi
    z = np.column_stack([np.hypot(d[:, 0], d[:, 1]), bearing])
    ll = landmark_log_likelihood(
        poses.reshape(-1, 3), z, np.ones(3, dtype=bool), landmarks, RANGE_BEARING,
        np.diag([0.1**2, 0.05**2]),
    )
    belief.update_log(ll.reshape(poses.shape[:3]))
    assert belief.mode().tolist() == [[4, 5, 6]]
    assert belief.max_prob()[0] > 0.99


# --- the maze depth sensor -------------------------------------------------------------------


def test_depth_on_a_hand_made_map() -> None:
    free = parse(["#######",
                  "#...#.#",
                  "#.#...#",
                  "#######"])  # fmt: skip
    table = depth_table(free)
    # cell (1, 2) (top-left free cell): east 3 cells to the wall, north 1 (wall above)
    assert table[1, 2].tolist() == [3, 1, 1, 2]  # east, north, west, south
    assert table[5, 1].tolist() == [1, 2, 3, 1]  # bottom row (y = 1), x = 5
    assert table[3, 1].tolist() == [3, 2, 1, 1]
    assert table[0, 0].tolist() == [0, 0, 0, 0]  # a wall
    for x in range(7):
        for y in range(4):
            for h in range(4):
                assert table[x, y, h] == walk_depth(free, x, y, h)


def test_the_grid_edge_counts_as_a_wall() -> None:
    table = depth_table(np.ones((3, 2), dtype=bool))
    assert table[0, 0].tolist() == [3, 2, 1, 1]


def test_depth_sensor_likelihoods_are_indicators_of_the_table() -> None:
    walls = eller_maze(9, np.random.default_rng(5))
    sensor = DepthSensor.from_grid(maze_to_grid(walls))
    assert np.array_equal(sensor.table, depth_table(np.ascontiguousarray(~walls.T)))
    for z in range(0, sensor.max_depth + 3):
        expected = np.empty(sensor.table.shape)
        reading_likelihood(sensor.table, z, expected)
        assert np.array_equal(sensor.likelihood(z), expected)
        assert np.array_equal(expected, ((sensor.table == z) & (z >= 1)).astype(float))
    assert sensor.measure((1, 1, 0)) == sensor.table[1, 1, 0]
    assert not sensor.table.flags.writeable and not sensor.likelihoods.flags.writeable
    twin = pickle.loads(pickle.dumps(sensor))
    assert not twin.likelihoods.flags.writeable
    with pytest.raises(ValueError, match="free"):
        depth_table(np.ones((3, 3)))


# --- fractional motion (per-heading kernels) -------------------------------------------------


def tent_weight(s: float, k: int, std: float) -> float:
    """The share of a cell's mass, uniform over the cell, that lands ``k`` cells away after a
    shift ``s`` plus N(0, std^2): the shifted cell's overlap with cell k, by quadrature."""
    if std == 0.0:
        return max(0.0, 1.0 - abs(s - k))
    kinks = [k - s - 1.0, k - s, k - s + 1.0]
    value, _ = quad(
        lambda n: max(0.0, 1.0 - abs(s - k + n)) * math.exp(-0.5 * (n / std) ** 2),
        -12.0 * std - 2.0, 12.0 * std + 2.0, points=kinks, limit=200, epsabs=1e-14,
    )
    return value / (std * math.sqrt(2.0 * math.pi))


def brute_fractional_predict(
    bel: dict, free: np.ndarray, n_h: int, shift: np.ndarray, turn: float, std: tuple
) -> dict:
    """One fractional prediction over every pose and outcome, weights by quadrature."""
    nx, ny = free.shape
    turns = {d: tent_weight(turn, d, std[2]) for d in range(math.floor(turn) - 3,
                                                           math.floor(turn) + 5)}
    axis = {}
    for h in range(n_h):
        for a in range(2):
            s = float(shift[h][a])
            axis[h, a] = {d: tent_weight(s, d, std[a])
                          for d in range(math.floor(s) - 3, math.floor(s) + 5)}
    out: dict = defaultdict(float)
    for (x, y, h), p in bel.items():
        for dx, wx in axis[h, 0].items():
            for dy, wy in axis[h, 1].items():
                for dh, wt in turns.items():
                    w = wx * wy * wt
                    if w < 1e-15:
                        continue
                    path = path_cells(x, y, dx, dy)
                    ok = (dx, dy) != (0, 0) and all(
                        0 <= cx < nx and 0 <= cy < ny and free[cx, cy] for cx, cy in path
                    )
                    th = (h + dh) % n_h
                    out[(x + dx, y + dy, th) if ok else (x, y, th)] += p * w
    return dict(out)


def assert_close(belief: GridBelief, bel: dict, atol: float) -> None:
    for (x, y, h), p in as_dict(belief.prob[0]).items():
        assert abs(p - bel.get((x, y, h), 0.0)) <= atol, (x, y, h)


@pytest.mark.parametrize(
    ("s", "std"), [(0.3, 0.08), (-1.7, 0.3), (0.0, 0.0), (2.5, 0.0), (0.05, 0.08), (0.0, 0.5)]
)
def test_axis_weights_are_the_overlap_of_a_shifted_noisy_cell(s: float, std: float) -> None:
    first, weights = axis_weights([s], std)
    assert weights.sum() == pytest.approx(1.0, abs=1e-12)
    for j, w in enumerate(weights[0]):
        assert w == pytest.approx(tent_weight(s, int(first[0]) + j, std), abs=1e-8)
    # the mean displacement is the shift itself: no drift from the discretization
    displacement = float(np.dot(weights[0], first[0] + np.arange(weights.shape[1])))
    assert displacement == pytest.approx(s, abs=1e-8)


def test_per_heading_prediction_equals_brute_force_bayes() -> None:
    free = parse(TINY)
    n_h = 4
    rng = np.random.default_rng(1)
    belief = GridBelief(free, n_h)
    start = rng.random((1, *free.shape, n_h)) * free[None, :, :, None]
    belief.set_prob(start)
    bel = {k: v for k, v in as_dict(start[0] / start.sum()).items() if free[k[0], k[1]]}
    for _ in range(6):
        offsets = rng.integers(-2, 3, size=(n_h, 5, 3))
        weights = rng.random((n_h, 5))
        weights[:, -1] = 0.0  # padding outcomes
        weights /= weights.sum(axis=1, keepdims=True)
        belief.predict_per_heading(offsets, weights)
        out: dict = defaultdict(float)
        for (x, y, h), p in bel.items():
            for (dx, dy, dh), w in zip(offsets[h].tolist(), weights[h].tolist(), strict=True):
                step = brute_predict({(x, y, h): p}, free, n_h, [[dx, dy]] * n_h, dh,
                                     [(0, 0, 0, w)])
                for pose, q in step.items():
                    out[pose] += q
        bel = dict(out)
        assert_matches(belief, bel)
        likelihood = rng.random((*free.shape, n_h))
        belief.update(likelihood)
        bel = brute_update(bel, likelihood)
        assert_matches(belief, bel)


def test_fractional_prediction_equals_brute_force_bayes() -> None:
    free = parse(["....#",
                  ".#...",
                  "...#.",
                  "....."])  # fmt: skip
    n_h = 8
    rng = np.random.default_rng(2)
    belief = GridBelief(free, n_h)
    bel = {k: v for k, v in as_dict(belief.prob[0]).items() if free[k[0], k[1]]}
    angles = 2 * np.pi * np.arange(n_h) / n_h
    std = (0.15, 0.1, 0.2)
    for step, (speed, turn) in enumerate([(0.6, 0.3), (1.4, -1.2), (0.0, 0.5), (2.2, 0.0)]):
        shift = speed * np.column_stack([np.cos(angles), np.sin(angles)])
        noise = std if step % 2 == 0 else (0.0, 0.0, 0.0)
        belief.predict_fractional(shift, turn, noise)
        bel = brute_fractional_predict(bel, free, n_h, shift, turn, noise)
        assert_close(belief, bel, 1e-8)
        assert belief.prob[0][~free].sum() == 0.0
        assert belief.prob.sum() == pytest.approx(1.0, abs=1e-12)
        likelihood = rng.random((*free.shape, n_h))
        belief.update(likelihood)
        bel = brute_update(bel, likelihood)
        assert_close(belief, bel, 1e-8)


def test_fractional_prediction_is_the_product_kernel_applied_in_two_factors() -> None:
    walls = eller_maze(9, np.random.default_rng(1))
    free = np.ascontiguousarray(~walls.T)
    one, two = GridBelief(free, 16), GridBelief(free, 16)
    rng = np.random.default_rng(3)
    start = rng.random((1, *free.shape, 16)) * free[None, :, :, None]
    one.set_prob(start)
    two.set_prob(start)
    for _ in range(5):
        shift = rng.normal(0.0, 1.2, (16, 2))
        turn = float(rng.normal(0.0, 2.0))
        noise = (0.1, 0.2, 0.3)
        one.predict_fractional(shift, turn, noise)
        two.predict_per_heading(*(a[0] for a in fractional_kernel(shift[None], [turn], noise)))
        assert np.allclose(one.prob, two.prob, rtol=0.0, atol=1e-15)


def test_integer_motion_without_noise_equals_predict() -> None:
    free = parse(TINY)
    one, two = GridBelief(free, 4), GridBelief(free, 4)
    start = np.random.default_rng(4).random((1, 4, 3, 4)) * free[None, :, :, None]
    one.set_prob(start)
    two.set_prob(start)
    shift = np.array([[1, 0], [0, 1], [-2, 0], [0, -1]])
    for turn in (0, 1, -1, 3):
        one.predict_fractional(shift.astype(float), float(turn))
        two.predict(shift, turn)
        assert np.allclose(one.prob, two.prob, rtol=0.0, atol=1e-15)


def test_unicycle_prediction_moves_the_mean_by_v_dt_and_keeps_walls_empty() -> None:
    free = np.ones((40, 40), dtype=bool)
    belief = GridBelief(free, 36, cell_size=0.25)
    prob = np.zeros((1, 40, 40, 36))
    prob[0, 20, 20, 3] = 1.0  # heading 30 degrees
    belief.set_prob(prob)
    before = belief.moments(within_cell=False)[0][0]
    belief.predict_unicycle(0.8, 0.0, 0.2, noise_std=(0.02, 0.02, 0.01))
    after = belief.moments(within_cell=False)[0][0]
    step = 0.8 * 0.2 * np.array([np.cos(np.pi / 6), np.sin(np.pi / 6)])
    assert np.allclose(after[:2] - before[:2], step, atol=1e-9)
    assert after[2] == pytest.approx(np.pi / 6, abs=1e-9)
    # in a maze, mass never enters a wall and the total stays 1
    walls = eller_maze(9, np.random.default_rng(6))
    maze = GridBelief(np.ascontiguousarray(~walls.T), 16)
    for k in range(20):
        maze.predict_unicycle(0.9, 0.4 * (-1) ** k, 0.5, noise_std=(0.1, 0.1, 0.05))
        assert maze.prob[0][walls.T].sum() == 0.0
        assert maze.prob.sum() == pytest.approx(1.0, abs=1e-12)


def test_moments_are_the_weighted_cell_poses_plus_the_cells_own_spread() -> None:
    grid = small_room()
    belief = GridBelief.from_grid(grid, n_headings=8)
    rng = np.random.default_rng(7)
    belief.set_prob(rng.random((1, 12, 8, 8)) ** 4 * belief.free[:, :, :, None])
    mean, cov = belief.moments(within_cell=False)
    w = belief.prob[0].reshape(-1)
    poses = belief.cell_poses().reshape(-1, 3)
    heading = np.arctan2(w @ np.sin(poses[:, 2]), w @ np.cos(poses[:, 2]))
    assert np.allclose(mean[0], [w @ poses[:, 0], w @ poses[:, 1], heading], atol=1e-12)
    assert np.allclose(mean[0], belief.mean[0], atol=1e-12)
    residual = poses - mean[0]
    residual[:, 2] = (residual[:, 2] + np.pi) % (2 * np.pi) - np.pi
    assert np.allclose(cov[0], (residual * w[:, None]).T @ residual, atol=1e-12)
    _, full = belief.moments()
    spread = np.diag([0.25, 0.25, (2 * np.pi / 8) ** 2]) / 12.0
    assert np.allclose(full[0] - cov[0], spread, atol=1e-15)


def test_coarse_cells_are_free_where_a_free_map_cell_lies() -> None:
    values = np.full((10, 10), FREE, dtype=np.int8)  # 1 m x 1 m at 0.1 m
    values[:, 5] = OCCUPIED  # a wall one map cell thick
    values[0:4, 0:4] = OCCUPIED
    grid = OccupancyGrid(values, 0.1, origin=(2.0, 3.0, 0.0))
    free = coarse_free_mask(grid, 0.25)  # 4 x 4 cells (the last one past the map)
    assert free.shape == (4, 4)
    expected = np.zeros((4, 4), dtype=bool)
    for iy in range(10):
        for ix in range(10):
            if values[iy, ix] == FREE:
                expected[int((ix + 0.5) * 0.4), int((iy + 0.5) * 0.4)] = True
    assert np.array_equal(free, expected)
    assert not free[0, 0] and free[2, 0]  # the block; the wall's cell also holds free space
    belief = GridBelief.from_grid(grid, n_headings=4, cell_size=0.25)
    assert belief.shape == (1, 4, 4, 4) and belief.cell_size == 0.25
    assert np.array_equal(belief.free[0], free)
    # any free point of the map lies in a free cell
    points = grid.sample_free(np.random.default_rng(0), 500)
    cells = np.floor((points - [2.0, 3.0]) / 0.25).astype(int)
    assert free[cells[:, 0], cells[:, 1]].all()
    with pytest.raises(ValueError, match="cell_size"):
        coarse_free_mask(grid, 0.0)


def test_gaussian_initialization_peaks_at_the_mean_and_skips_walls() -> None:
    grid = small_room()
    belief = GridBelief.from_grid(grid, n_headings=8)
    mean = belief.cell_poses()[8, 5, 3]
    belief.initialize_gaussian(mean, np.diag([0.3, 0.3, 0.2]) ** 2)
    assert belief.mode().tolist() == [[8, 5, 3]]
    assert belief.prob[0][~belief.free[0]].sum() == 0.0
    assert belief.prob.sum() == pytest.approx(1.0)
    with pytest.raises(ValueError, match="cov"):
        belief.initialize_gaussian(mean, -np.eye(3))


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda b: b.predict_per_heading(np.zeros((3, 1, 3), dtype=int), np.ones((3, 1))),
         "offsets"),
        (lambda b: b.predict_per_heading(np.zeros((4, 1, 3)), np.ones((4, 1))), "offsets"),
        (lambda b: b.predict_per_heading(np.zeros((4, 2, 3), dtype=int), np.ones((4, 2))),
         "sum to 1"),
        (lambda b: b.predict_per_heading(np.zeros((4, 1, 3), dtype=int), np.ones((4, 2))),
         "weights"),
        (lambda b: b.predict_fractional(np.zeros((3, 2))), "shift"),
        (lambda b: b.predict_fractional(np.full((4, 2), np.nan)), "finite"),
        (lambda b: b.predict_fractional(np.zeros((4, 2)), noise_std=(0.1, -0.1, 0.0)),
         "noise_std"),
    ],
)
def test_bad_fractional_input_raises_value_error(call, match: str) -> None:
    belief = GridBelief(parse(TINY))
    before = belief.prob.copy()
    with pytest.raises(ValueError, match=match):
        call(belief)
    assert np.array_equal(belief.prob, before)
