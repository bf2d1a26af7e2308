"""Dynamic environments: people the map does not hold occlude the lidar and block the robot;
the likelihood field's beam skipping keeps pose tracking on course among them."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import active_loc  # noqa: F401  (registers the ids)
from active_loc.envs.crowd import ROBOT_RADIUS, Crowd
from active_loc.maps import OccupancyGrid, rooms_map
from active_loc.sensors.lidar import (
    LidarSensor,
    likelihood_field_skip_log_likelihood,
    likelihood_field_table_log_likelihood,
    occlude_ranges,
)
from tests.envs.wander import wander

# --- occlusion and beam skipping -----------------------------------------------------------------


def test_a_disc_shortens_the_beams_that_meet_it():
    angles = np.array([0.0, math.pi / 2, math.asin(0.5 / 3.0) - 1e-9])
    ranges = np.full(3, 8.0)
    occlude_ranges(1.0, 1.0, 0.0, angles, np.array([[4.0, 1.0, 0.5]]), ranges)
    assert ranges[0] == pytest.approx(2.5)  # straight at the centre: 3 m less the radius
    assert ranges[1] == 8.0  # looking away
    # a tangent beam touches the disc at the tangent length
    assert ranges[2] == pytest.approx(math.sqrt(3.0**2 - 0.5**2), rel=1e-3)
    inside = np.full(3, 8.0)
    occlude_ranges(4.0, 1.1, 0.0, angles, np.array([[4.0, 1.0, 0.5]]), inside)
    assert np.all(inside == 0.0)
    nearer = np.full(3, 1.0)  # a wall at 1 m comes first
    occlude_ranges(1.0, 1.0, 0.0, angles, np.array([[4.0, 1.0, 0.5]]), nearer)
    assert np.all(nearer == 1.0)


@pytest.fixture(scope="module")
def corridor() -> OccupancyGrid:
    return OccupancyGrid.from_ascii(
        ["##########", "#........#", "#........#", "#........#", "##########"], 1.0
    )


def skip_scores(grid, lidar, z, poses, skip):
    _, res, ox, oy, c, s = grid.kernel_arrays()
    field = grid.distance_field()
    table = lidar.log_table(field)
    out = np.empty(len(poses))
    log_off = math.log(lidar.z_rand / lidar.max_range)
    skipped = likelihood_field_skip_log_likelihood(
        z, lidar.beam_angles, poses, table, field, log_off, res, ox, oy, c, s, lidar.max_range,
        *skip, out,
    )
    return out, skipped, table, log_off


def test_beam_skipping_leaves_out_the_beams_the_map_cannot_explain(corridor):
    lidar = LidarSensor(n_beams=4, fov=2 * math.pi, max_range=8.0, sigma_hit=0.3,
                        z_hit=0.9, z_short=0.0, z_max=0.05, z_rand=0.05)
    _, res, ox, oy, c, s = corridor.kernel_arrays()
    poses = np.array([[5.0, 2.5, 0.0], [5.05, 2.5, 0.0], [4.95, 2.45, 0.02]])
    z = lidar.expected_ranges(poses[:1], corridor.kernel_arrays())[0].copy()
    z[0] = 1.5  # something unmapped 1.5 m ahead, in the middle of the corridor
    out, skipped, table, log_off = skip_scores(corridor, lidar, z, poses, (0.5, 0.3, 0.9))
    assert skipped == 1
    # the same as the plain likelihood field over the other three beams
    keep = np.arange(1, 4)
    want = np.empty(3)
    likelihood_field_table_log_likelihood(
        z[keep], lidar.beam_angles[keep], poses, table, log_off, res, ox, oy, c, s,
        lidar.max_range, want,
    )
    np.testing.assert_allclose(out, want, rtol=0, atol=1e-12)


def test_when_most_beams_disagree_every_beam_is_used(corridor):
    lidar = LidarSensor(n_beams=4, fov=2 * math.pi, max_range=8.0, model="likelihood_field")
    _, res, ox, oy, c, s = corridor.kernel_arrays()
    poses = np.array([[5.0, 2.5, 0.0], [3.0, 2.0, 1.0]])
    z = np.full(4, 1.0)  # nothing mapped is 1 m away in any direction
    out, skipped, table, log_off = skip_scores(corridor, lidar, z, poses, (0.3, 0.5, 0.5))
    assert skipped == 0
    want = np.empty(2)
    likelihood_field_table_log_likelihood(
        z, lidar.beam_angles, poses, table, log_off, res, ox, oy, c, s, lidar.max_range, want
    )
    np.testing.assert_allclose(out, want, rtol=0, atol=1e-12)


# --- the crowd -----------------------------------------------------------------------------------


def test_people_walk_in_free_space_keep_clear_of_the_robot_and_block_it():
    grid = rooms_map(np.random.default_rng(1), size_m=(12.0, 12.0))
    rng = np.random.default_rng(2)
    robot = grid.sample_free(rng, 1)[0]
    crowd = Crowd.spawn(grid, 10, 0.8, 0.25, robot, rng)
    assert crowd.discs.shape == (10, 3)
    start = crowd.discs.copy()
    for _ in range(300):
        crowd.step(grid, 0.1, robot, rng)
        assert grid.is_free(crowd.discs[:, :2]).all()
        gaps = np.hypot(*(crowd.discs[:, :2] - robot).T)
        assert np.all(gaps >= 0.25 + ROBOT_RADIUS - 1e-9)
    assert np.all(np.hypot(*(crowd.discs[:, :2] - start[:, :2]).T) > 0.0)
    assert crowd.blocks(crowd.discs[0, :2] + [0.3, 0.0])
    assert not crowd.blocks(np.array([-100.0, -100.0]))


def test_the_dynamic_env_is_reproducible_and_renders_people():
    envs = [gym.make("ActiveLoc/GridMCLDynamic-v0", render_mode="rgb_array") for _ in range(2)]
    for env in envs:
        env.reset(seed=3)
    rng = np.random.default_rng(0)
    for _ in range(30):
        action = rng.uniform(-1, 1, 2).astype(np.float32)
        a, b = (env.step(action) for env in envs)
        assert np.array_equal(a[0], b[0]) and a[4] == b[4]
    crowd, twin = (env.unwrapped.core.episode(0).crowd for env in envs)
    assert crowd is not None and twin is not None and crowd.discs.shape == (10, 3)
    assert np.array_equal(crowd.discs, twin.discs)
    frame = envs[0].render()
    assert frame.shape == (600, 600, 3)


@pytest.mark.parametrize(
    "people", [(10, 1.0), (-1, 1.0, 0.2), (2, -1.0, 0.2), (2, 1.0, 0.0), (True, 1.0, 0.2),
               (2, math.nan, 0.2)],
)
def test_bad_dynamic_obstacles_are_named(people):
    with pytest.raises(ValueError, match="dynamic_obstacles"):
        gym.make("ActiveLoc/GridMCLDynamic-v0", dynamic_obstacles=people)


def test_dynamic_obstacles_need_a_grid_map():
    with pytest.raises(ValueError, match="dynamic_obstacles needs a grid map"):
        gym.make("ActiveLoc/LandmarkMCL-v0", dynamic_obstacles=(3, 1.0, 0.2))


@pytest.mark.parametrize("skip", [(0.0, 0.3, 0.9), (0.5, 1.5, 0.9), (0.5, 0.3), (0.5, 0.3, -1)])
def test_bad_beam_skip_settings_are_named(skip):
    with pytest.raises(ValueError, match="lidar_beam_skip"):
        gym.make("ActiveLoc/GridMCLDynamic-v0", lidar_beam_skip=skip)


# --- tracking among people -----------------------------------------------------------------------


def test_tracking_among_ten_people_stays_within_tolerance():
    """20 seeded episodes of 200 steps on generated offices with 10 people: after 30 steps to
    settle from the initial error, the position error stays under 0.5 m all the way in at least
    90% of them."""
    env = gym.make("ActiveLoc/GridMCLDynamic-v0", action_type="discrete",
                   terminate_when_localized=False)
    tracked, worst_errors = 0, []
    for seed in range(20):
        obs, info = env.reset(seed=seed)
        worst = 0.0
        for step in range(200):
            obs, _, _, _, info = env.step(wander(obs))
            if step >= 30:
                worst = max(worst, info["pose_error"])
        tracked += worst < 0.5
        worst_errors.append(worst)
    print(f"GridMCLDynamic-v0: tracked in {tracked}/20, worst error after settling: median "
          f"{np.median(worst_errors):.2f} m, max {np.max(worst_errors):.2f} m")
    assert tracked >= 18
