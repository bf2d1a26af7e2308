"""Tests of the grid Markov filter (``active_loc.beliefs.grid``) and the maze depth sensor.

The reference is brute-force Bayes written here in plain Python: a dict over every pose
``(x, y, h)``, the motion applied outcome by outcome with the documented blocking rule, the
measurement multiplied in and normalized by hand. The filter must agree to 1e-12.
"""

from __future__ import annotations

import copy
import math
import pickle
from collections import defaultdict
from fractions import Fraction

import numpy as np
import pytest

from active_loc.beliefs.grid import GridBelief, MotionKernel
from active_loc.beliefs.mcl import landmark_log_likelihood
from active_loc.envs.maze_env import TURN_LEFT, TURN_RIGHT, MazeMotion
from active_loc.maps.maze import eller_maze, maze_to_grid
from active_loc.maps.occupancy import FREE, OCCUPIED, OccupancyGrid
from active_loc.sensors import RANGE_BEARING
from active_loc.sensors.depth import DepthSensor, depth_likelihood, depth_table
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
        expected = depth_likelihood(sensor.table, z)
        assert np.array_equal(sensor.likelihood(z), expected)
        assert np.array_equal(expected, ((sensor.table == z) & (z >= 1)).astype(float))
    assert sensor.measure((1, 1, 0)) == sensor.table[1, 1, 0]
    assert not sensor.table.flags.writeable and not sensor.likelihoods.flags.writeable
    twin = pickle.loads(pickle.dumps(sensor))
    assert not twin.likelihoods.flags.writeable
    with pytest.raises(ValueError, match="free"):
        depth_table(np.ones((3, 3)))
