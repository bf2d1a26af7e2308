"""The precomputed beam model: its table holds exactly what ray casting gives at cell centres,
its scores are the beam model's on quantized ranges, and it stays close to the exact model."""

from __future__ import annotations

import math

import numpy as np
import pytest

from active_loc.maps import OccupancyGrid, rooms_map
from active_loc.sensors.lidar import LidarSensor, beam_probability, cast_ray
from active_loc.sensors.range_table import RANGE_QUANTUM, RangeTable

LIDAR = LidarSensor(n_beams=24, fov=1.5 * math.pi, max_range=6.0, model="beam")


@pytest.fixture(scope="module")
def room() -> OccupancyGrid:
    return rooms_map(np.random.default_rng(3), size_m=(8.0, 8.0), resolution=0.1)


@pytest.fixture(scope="module")
def table(room: OccupancyGrid) -> RangeTable:
    return RangeTable.build(LIDAR, room.kernel_arrays(), n_angles=72)


def cell_centre(grid: OccupancyGrid, ix: int, iy: int) -> tuple[float, float]:
    ox, oy, _ = grid.origin
    return ox + (ix + 0.5) * grid.resolution, oy + (iy + 0.5) * grid.resolution


def test_the_table_holds_the_casts_from_cell_centres(room, table):
    values, res, ox, oy, c, s = room.kernel_arrays()
    rng = np.random.default_rng(0)
    free = np.argwhere(values == 0)
    for iy, ix in free[rng.choice(len(free), 200, replace=False)]:
        x, y = cell_centre(room, ix, iy)
        for a in rng.choice(table.n_angles, 5, replace=False):
            angle = -math.pi + 2 * math.pi * a / table.n_angles
            exact = cast_ray(values, res, ox, oy, c, s, x, y, angle, LIDAR.max_range, True)
            assert abs(table.ranges[iy, ix, a] * RANGE_QUANTUM - exact) <= 0.5 * RANGE_QUANTUM
    assert np.all(table.ranges[values == 100] == 0)
    assert table.ranges.max() * RANGE_QUANTUM <= LIDAR.max_range + 1e-9


def test_the_log_prob_table_is_the_beam_model(table):
    rng = np.random.default_rng(1)
    for i, j in rng.integers(0, table.log_probs.shape[0], (300, 2)):
        p = beam_probability(i * RANGE_QUANTUM, j * RANGE_QUANTUM, LIDAR.max_range, LIDAR.z_hit,
                             LIDAR.z_short, LIDAR.z_max, LIDAR.z_rand, LIDAR.sigma_hit,
                             LIDAR.lambda_short)
        assert table.log_probs[i, j] == pytest.approx(math.log(p), rel=1e-12, abs=1e-12)


def test_scores_are_the_beam_model_on_the_looked_up_ranges(room, table):
    """At a cell centre with a heading on a bin, every beam falls on a bin (72 bins, 24
    beams 11.7 degrees apart would not; use beams on the bin lattice)."""
    values, res, ox, oy, c, s = room.kernel_arrays()
    lidar = LidarSensor(n_beams=8, fov=2 * math.pi, max_range=6.0, model="beam")
    tab = RangeTable(lidar, table.grid_arrays, table.ranges, table.log_probs, RANGE_QUANTUM)
    rng = np.random.default_rng(2)
    free = np.argwhere(values == 0)
    poses = []
    for iy, ix in free[rng.choice(len(free), 50, replace=False)]:
        x, y = cell_centre(room, ix, iy)
        poses.append((x, y, -math.pi + 2 * math.pi * rng.integers(72) / 72))
    poses = np.array(poses)
    z = rng.uniform(0.0, 7.0, lidar.n_beams)
    z[0] = np.inf
    got = tab.log_likelihood(z, poses)
    zq = np.rint(np.minimum(z, lidar.max_range) / RANGE_QUANTUM) * RANGE_QUANTUM
    for pose, score in zip(poses, got, strict=True):
        want = 0.0
        for zm, angle in zip(zq, lidar.beam_angles, strict=True):
            r = cast_ray(values, res, ox, oy, c, s, pose[0], pose[1], pose[2] + angle,
                         lidar.max_range, True)
            want += math.log(beam_probability(
                zm, round(r / RANGE_QUANTUM) * RANGE_QUANTUM, lidar.max_range, lidar.z_hit,
                lidar.z_short, lidar.z_max, lidar.z_rand, lidar.sigma_hit, lidar.lambda_short))
        assert score == pytest.approx(want, abs=1e-9)


def test_scores_stay_close_to_the_exact_beam_model(room, table):
    """Off-centre poses and off-bin headings: the quantization moves a scan's score by a
    small fraction of how much scores differ between poses."""
    rng = np.random.default_rng(4)
    truth = room.sample_free(rng, 1)[0]
    pose = np.array([truth[0], truth[1], 0.3])
    z = LIDAR.expected_ranges(pose[None], room.kernel_arrays())[0]
    poses = np.column_stack([room.sample_free(rng, 300), rng.uniform(-np.pi, np.pi, 300)])
    poses = np.vstack([pose + np.array([0.02, -0.03, 0.01]), poses])
    exact = LIDAR.log_likelihood(z, poses, room.kernel_arrays())
    fast = table.log_likelihood(z, poses)
    assert np.all(np.isfinite(fast))
    assert np.corrcoef(exact, fast)[0, 1] > 0.97
    # the pose next to the truth scores best under both
    assert np.argmax(fast) == np.argmax(exact) == 0


def test_poses_off_the_map_score_finite(table):
    poses = np.array([[-5.0, -5.0, 0.0], [100.0, 2.0, 1.0]])
    out = table.log_likelihood(np.full(LIDAR.n_beams, 3.0), poses)
    assert np.all(np.isfinite(out))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"n_angles": 2}, "n_angles"), ({"n_angles": 36.0}, "n_angles"),
     ({"quantum": 0.0}, "quantum"), ({"quantum": 10.0}, "quantum"),
     ({"quantum": 1e-5}, "uint16")],
)
def test_bad_table_settings_name_the_setting(room, kwargs, match):
    with pytest.raises(ValueError, match=match):
        RangeTable.build(LIDAR, room.kernel_arrays(), **kwargs)
