"""GridMarkov-v0: Markov localization (the chapter's Algorithm 1) on generated grid maps with a
lidar: the env's filter against brute-force Bayes over every pose, global localization by a
passive robot, the state row and observation of a grid belief, planners, configuration."""

from __future__ import annotations

import dataclasses
import math
from collections import defaultdict

import gymnasium as gym
import numpy as np
import pytest
from scipy.integrate import quad

import active_loc  # noqa: F401  (registers the ids)
from active_loc.beliefs.grid import GridBelief
from active_loc.envs.observations import BELIEF_HEADER
from active_loc.envs.particle_core import HISTOGRAM_CELLS
from active_loc.maps import OccupancyGrid
from active_loc.maps.occupancy import FREE
from active_loc.sensors.lidar_lattice import (
    lattice_field_log_likelihood,
    off_map_log_probability,
    padded_table,
)
from tests.envs.wander import BEAMS, wander

ENV_ID = "ActiveLoc/GridMarkov-v0"
FORWARD, FORWARD_LEFT, TURN_LEFT, TURN_RIGHT = 1, 2, 4, 5


# --- brute force -----------------------------------------------------------------------------


def tent_weight(s: float, k: int, std: float) -> float:
    """The share of a cell's mass (uniform over the cell) that lands ``k`` cells away after a
    shift ``s`` plus N(0, std^2), by quadrature."""
    if std == 0.0:
        return max(0.0, 1.0 - abs(s - k))
    value, _ = quad(
        lambda n: max(0.0, 1.0 - abs(s - k + n)) * math.exp(-0.5 * (n / std) ** 2),
        -12.0 * std - 2.0, 12.0 * std + 2.0, points=[k - s - 1.0, k - s, k - s + 1.0],
        limit=200, epsabs=1e-14,
    )
    return value / (std * math.sqrt(2.0 * math.pi))


def blocked(free: np.ndarray, x: int, y: int, dx: int, dy: int) -> bool:
    """A translation is blocked when it is none, or when a cell of its path (cells at
    round-half-up of ``d i / n``, i = 1..n) is occupied or off the grid."""
    if (dx, dy) == (0, 0):
        return True
    n = max(abs(dx), abs(dy))
    for i in range(1, n + 1):
        cx = x + math.floor(dx * i / n + 0.5)
        cy = y + math.floor(dy * i / n + 0.5)
        if not (0 <= cx < free.shape[0] and 0 <= cy < free.shape[1] and free[cx, cy]):
            return True
    return False


def brute_predict(bel: dict, free: np.ndarray, n_h: int, v_cells: float, turn: float,
                  std: tuple[float, float, float]) -> dict:
    """The unicycle on the grid, pose by pose and outcome by outcome: in heading bin h the
    robot moves by v_cells (cos, sin)(2 pi h / H) and turns by ``turn`` bins, plus noise."""
    def axis(s: float, sd: float) -> dict:
        weights = {d: tent_weight(s, d, sd) for d in range(math.floor(s) - 3, math.floor(s) + 5)}
        return {d: w for d, w in weights.items() if w > 1e-15}

    turns = axis(turn, std[2])
    angles = [2.0 * math.pi * h / n_h for h in range(n_h)]
    moves = [(axis(v_cells * math.cos(a), std[0]), axis(v_cells * math.sin(a), std[1]))
             for a in angles]
    out: dict = defaultdict(float)
    for (x, y, h), p in bel.items():
        wx, wy = moves[h]
        for dx, px in wx.items():
            for dy, py in wy.items():
                stay = blocked(free, x, y, dx, dy)
                for dh, pt in turns.items():
                    th = (h + dh) % n_h
                    out[(x, y, th) if stay else (x + dx, y + dy, th)] += p * px * py * pt
    return dict(out)


def tiny_map() -> OccupancyGrid:
    """3 m x 2 m at 0.2 m: walls all round, a pillar and a wall stub (no symmetry). With
    0.5 m belief cells no cell centre lies on a map cell's border, where the lattice and the
    direct computation of a beam's end point could round to different sides."""
    return OccupancyGrid.from_ascii(
        ["###############",
         "#.............#",
         "#....##.......#",
         "#....##...#...#",
         "#.........#...#",
         "#.........#...#",
         "#.............#",
         "#.............#",
         "#.............#",
         "###############"],
        0.2,
    )  # fmt: skip


def test_episode_equals_brute_force_bayes_over_every_pose() -> None:
    """Every step of the env's filter (fractional motion with noise, blocked translations, a
    collision predicted with V = 0, the tempered lidar likelihood at every free cell pose) is
    exact Bayes computed pose by pose, with the motion weights integrated numerically and the
    likelihood field evaluated directly (not from the env's table or lattice)."""
    grid = tiny_map()
    cell, n_h, exponent = 0.5, 8, 0.5
    env = gym.make(
        ENV_ID, map=grid, grid_cell_size=cell, grid_headings=n_h, n_beams=12, fov=2 * np.pi,
        max_range=4.0, likelihood_exponent=exponent, terminate_when_localized=False,
        action_type="discrete",
    )
    core = env.unwrapped.core
    env.reset(seed=3)
    # a cell is free when the centre of a FREE map cell lies in it
    free = np.zeros((6, 4), dtype=bool)
    for iy, ix in zip(*np.nonzero(grid.values == FREE), strict=True):
        free[int((ix + 0.5) * 0.2 / cell), int((iy + 0.5) * 0.2 / cell)] = True
    assert np.array_equal(core.belief.free[0], free)
    poses = [(x, y, h) for x in range(6) for y in range(4) for h in range(n_h) if free[x, y]]
    bel = {pose: 1.0 / len(poses) for pose in poses}
    world = {
        (x, y, h): np.array([(x + 0.5) * cell, (y + 0.5) * cell,
                             (2 * np.pi * h / n_h + np.pi) % (2 * np.pi) - np.pi])
        for x, y, h in poses
    }
    config = env.unwrapped.config
    sx, sy, st = config.motion_noise_std
    noise = (sx / cell, sy / cell, st * n_h / (2 * np.pi))
    lidar, arrays, field = core.lidar, grid.kernel_arrays(), grid.distance_field()
    log_volume = math.log(cell * cell * 2 * np.pi / n_h)
    collisions = 0
    actions = [FORWARD] * 6 + [TURN_LEFT, FORWARD_LEFT, FORWARD, FORWARD, TURN_RIGHT]
    actions += [FORWARD] * 5
    for action in actions:
        _, _, _, _, info = env.step(action)
        v, omega = core.models.primitives[action]
        if info["collisions"] > collisions:
            collisions = info["collisions"]
            v = 0.0
        bel = brute_predict(bel, free, n_h, v * config.dt / cell,
                            omega * config.dt * n_h / (2 * np.pi), noise)
        z = core.ranges[0]
        ll = {pose: exponent * lidar.log_likelihood(z, world[pose][None], arrays, field)[0]
              for pose in bel}
        top = max(ll.values())
        post = {pose: p * math.exp(ll[pose] - top) for pose, p in bel.items()}
        total = sum(post.values())
        bel = {pose: p / total for pose, p in post.items()}
        prob = core.belief.prob[0]
        for pose in poses:
            assert abs(prob[pose] - bel.get(pose, 0.0)) <= 1e-9, pose
        assert prob[~free].sum() == 0.0
        entropy = -sum(p * math.log(p) for p in bel.values() if p > 0.0) + log_volume
        assert info["entropy"] == pytest.approx(entropy, abs=1e-8)
    assert collisions >= 1  # the run exercised the blocked prediction


def test_the_lattice_likelihood_equals_the_sensor_at_every_cell_pose() -> None:
    """The env scores the likelihood field on the lattice of cells; the numbers are the
    lidar's at each cell pose (a yawed map included)."""
    rng = np.random.default_rng(0)
    env = gym.make(ENV_ID)
    env.reset(seed=5)
    core = env.unwrapped.core
    base = core.maps[0]
    for yaw in (0.0, 0.4):
        grid = OccupancyGrid(base.values, base.resolution, origin=(-1.0, 2.0, yaw))
        belief = GridBelief.from_grid(grid, n_headings=36, cell_size=0.25)
        lidar = core.lidar
        table = lidar.log_table(grid.distance_field())
        # the robot 4 m along and 2.5 m across the yawed map from its origin
        c, s = np.cos(yaw), np.sin(yaw)
        robot = np.array([-1.0 + 4.0 * c - 2.5 * s, 2.0 + 4.0 * s + 2.5 * c, yaw + 1.0])
        z = lidar.measure(robot, grid.kernel_arrays(), rng)
        _, nx, ny, nh = belief.shape
        ratio = 0.25 / grid.resolution
        lattice = lattice_field_log_likelihood(
            lidar, z, 2 * np.pi * np.arange(nh) / nh, (np.arange(nx) + 0.5) * ratio,
            (np.arange(ny) + 0.5) * ratio, belief.free[0], grid.resolution,
            padded_table(table, off_map_log_probability(lidar)),
        )
        poses = belief.cell_poses()[belief.free[0]].reshape(-1, 3)
        direct = lidar.field_log_likelihood(z, poses, grid.kernel_arrays(), table)
        assert np.all(np.isneginf(lattice[~belief.free[0]]))
        close = np.isclose(lattice[belief.free[0]].reshape(-1), direct, rtol=0.0, atol=1e-9)
        # an end point exactly on a map cell's border may round to the other side
        assert close.mean() > 0.999


# --- the env ---------------------------------------------------------------------------------


def test_passive_wanderer_localizes_globally() -> None:
    """The wall-avoiding wanderer (it reads the scan, never the belief) on 50 seeded generated
    office maps, belief uniform over the free cell poses at the start: the episode ends on
    confidence, and the confident belief is right in at least 45 of them."""
    env = gym.make(ENV_ID, action_type="discrete")
    successes, lengths = 0, []
    for seed in range(50):
        obs, info = env.reset(seed=seed)
        terminated = truncated = False
        while not (terminated or truncated):
            obs, _, terminated, truncated, info = env.step(wander(obs))
        successes += info["is_success"]
        lengths.append(env.unwrapped.core.episode(0).t)
    print(f"GridMarkov-v0 passive wanderer: {successes}/50 localized, mean episode "
          f"{np.mean(lengths):.1f} steps")
    assert successes >= 45


def test_state_row_and_observation_come_from_the_histogram() -> None:
    env = gym.make(ENV_ID, terminate_when_localized=False)
    obs, info = env.reset(seed=1)
    core = env.unwrapped.core
    belief = core.belief
    assert isinstance(belief, GridBelief) and belief.shape[3] == 36
    uniform_entropy = math.log(belief.free.sum() * 36) + belief.log_cell_volume
    assert info["entropy"] == pytest.approx(uniform_entropy)
    rng = np.random.default_rng(0)
    for _ in range(15):
        obs, _, _, _, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        mean, cov = belief.moments()
        row = core.rows[0]
        assert np.array_equal(row["mean"], mean[0])
        assert np.array_equal(row["cov"], cov[0])
        assert info["entropy"] == belief.entropy()[0]
        # the 8 x 8 histogram is the x-y marginal pooled over the map
        marginal = belief.marginal_xy()[0]
        centres = belief.cell_poses()[:, :, 0, :2]
        x_min, y_min, x_max, y_max = core.maps[0].bounds
        ix = np.clip(((centres[..., 0] - x_min) / (x_max - x_min) * 8).astype(int), 0, 7)
        iy = np.clip(((centres[..., 1] - y_min) / (y_max - y_min) * 8).astype(int), 0, 7)
        pooled = np.zeros((8, 8))
        np.add.at(pooled, (iy, ix), marginal)
        cells = HISTOGRAM_CELLS * HISTOGRAM_CELLS
        assert np.allclose(obs[BELIEF_HEADER : BELIEF_HEADER + cells], pooled.ravel(), atol=1e-6)
        assert np.allclose(obs[-BEAMS:], np.clip(core.ranges[0] / 8.0, 0, 1), atol=1e-6)
        assert belief.prob[0][~belief.free[0]].sum() == 0.0


def test_gaussian_initial_belief_tracks_the_robot() -> None:
    env = gym.make(ENV_ID, initial_belief="gaussian", action_type="discrete",
                   terminate_when_localized=False)
    errors = []
    for seed in range(3):
        obs, info = env.reset(seed=seed)
        for _ in range(30):
            obs, _, _, _, info = env.step(wander(obs))
        errors.append(info["pose_error"])
    assert max(errors) < 0.3


def test_planner_view_simulates_a_grid_step_on_a_copy() -> None:
    env = gym.make(ENV_ID, action_type="discrete")
    env.reset(seed=2)
    for _ in range(3):
        env.step(FORWARD)
    view = env.unwrapped.planner_view()
    assert isinstance(view.belief, GridBelief)
    assert view.belief is not env.unwrapped.core.belief
    before = env.unwrapped.core.belief.prob.copy()
    out, z, visible = view.simulate(FORWARD, view.belief, np.random.default_rng(0))
    assert isinstance(out, GridBelief) and out is not view.belief
    assert z.shape == (BEAMS,) and visible.all()
    assert np.array_equal(env.unwrapped.core.belief.prob, before)  # the env is untouched
    assert out.prob.sum() == pytest.approx(1.0)
    assert out.entropy()[0] < view.belief.entropy()[0]  # a scan is informative
    assert view.likelihood_exponent == env.unwrapped.config.likelihood_exponent


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"sensor": "range_bearing", "map": "random"}, "sensor"),
        ({"grid_cell_size": 0.0}, "grid_cell_size"),
        ({"grid_cell_size": float("nan")}, "grid_cell_size"),
        ({"grid_headings": 0}, "grid_headings"),
        ({"grid_headings": 8.5}, "grid_headings"),
    ],
)
def test_bad_grid_configuration_names_the_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        gym.make(ENV_ID, **kwargs)


def test_the_heat_map_of_the_belief_is_rendered() -> None:
    pytest.importorskip("matplotlib")
    env = gym.make(ENV_ID, render_mode="rgb_array", action_type="discrete",
                   terminate_when_localized=False)
    obs, _ = env.reset(seed=0)
    env.render()
    renderer = env.unwrapped._renderer

    def heat_pixels() -> int:
        """Pixels of the map area that the heat map changes."""
        frame = env.unwrapped._frame()
        assert frame.belief_map is not None and frame.particles is None
        assert frame.belief_map.shape == env.unwrapped.core.belief.shape[1:3]
        with_heat = renderer.render_rgb(frame)
        without = renderer.render_rgb(dataclasses.replace(frame, belief_map=None))
        x0, y0, x1, y1 = renderer._scene.ax.bbox.extents
        height = with_heat.shape[0]
        rows = slice(int(height - y1) + 1, int(height - y0) - 1)
        cols = slice(int(x0) + 1, int(x1) - 1)
        return int(np.count_nonzero(np.any(with_heat[rows, cols] != without[rows, cols], -1)))

    spread = heat_pixels()  # uniform: the whole free space
    for _ in range(150):
        obs, _, _, _, info = env.step(wander(obs))
        if info["localized"]:
            break
    assert info["localized"]
    assert spread > 5 * heat_pixels() > 0  # localized: a small patch
    env.close()
