"""Scans of identical-looking landmarks: misses, Poisson clutter over the field of view, a
random order, and a fixed number of random draws per scan."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import poisson

from active_loc.sensors.detections import (
    CLUTTER,
    CLUTTER_TAIL,
    DetectionModel,
    max_clutter_count,
)
from active_loc.sensors.landmarks import RangeBearingSensor, RelativePositionSensor

FOV = math.pi / 2
RANGE = 6.0
SENSOR = RangeBearingSensor.from_std(0.1, 0.035, FOV, RANGE)
LANDMARKS = np.array([[3.0, 0.0], [4.0, 1.5], [2.0, -1.0], [-3.0, 0.0], [20.0, 0.0]])
POSE = np.zeros(3)
IN_VIEW = np.array([True, True, True, False, False])


def test_without_misses_and_clutter_a_scan_is_the_landmarks_in_view_in_random_order() -> None:
    rng = np.random.default_rng(0)
    model = DetectionModel(clutter_range=RANGE)
    expected = SENSOR.expected(POSE, LANDMARKS)
    first = []
    for _ in range(600):
        z, truth = model.scan(SENSOR, POSE, LANDMARKS, rng)
        assert sorted(truth.tolist()) == [0, 1, 2]
        # each detection is its landmark's measurement plus noise of the sensor's size
        residual = SENSOR.residual(z, expected[truth])
        assert np.all(np.abs(residual) < 6 * np.sqrt(np.diag(SENSOR.noise_cov)))
        first.append(int(truth[0]))
    # the order carries no identity: each landmark comes first about a third of the time
    counts = np.bincount(first, minlength=3)
    assert np.all(np.abs(counts / 600 - 1 / 3) < 0.06), counts


def test_misses_drop_each_landmark_with_the_given_probability() -> None:
    rng = np.random.default_rng(1)
    model = DetectionModel(miss_probability=0.3, clutter_range=RANGE)
    seen = np.zeros(len(LANDMARKS))
    scans = 2000
    for _ in range(scans):
        _, truth = model.scan(SENSOR, POSE, LANDMARKS, rng)
        seen[truth] += 1
    rate = seen / scans
    # binomial std of 2000 draws at p = 0.7 is about 0.01
    np.testing.assert_allclose(rate[IN_VIEW], 0.7, atol=0.04)
    assert np.all(rate[~IN_VIEW] == 0.0)


@pytest.mark.parametrize("sensor", [SENSOR, RelativePositionSensor(0.25 * np.eye(2), FOV, RANGE)])
def test_clutter_is_poisson_and_uniform_over_the_field_of_view(sensor) -> None:
    rng = np.random.default_rng(2)
    model = DetectionModel(clutter_rate=2.0, clutter_range=RANGE)
    empty = np.empty((0, 2))
    counts, points = [], []
    for _ in range(4000):
        z, truth = model.scan(sensor, POSE, empty, rng)
        assert np.all(truth == CLUTTER)
        counts.append(len(z))
        points.append(z)
    counts_arr = np.array(counts)
    assert abs(counts_arr.mean() - 2.0) < 0.1 and abs(counts_arr.var() - 2.0) < 0.25
    assert abs(np.mean(counts_arr == 0) - math.exp(-2.0)) < 0.02
    z = np.concatenate(points)
    if sensor.kind == SENSOR.kind:
        r, bearing = z[:, 0], z[:, 1]
    else:
        r, bearing = np.hypot(z[:, 0], z[:, 1]), np.arctan2(z[:, 1], z[:, 0])
    assert np.all(r <= RANGE) and np.all(np.abs(bearing) <= FOV / 2)
    # uniform over the area: half of the points within R / sqrt(2), bearings uniform
    assert abs(np.mean(r <= RANGE / math.sqrt(2)) - 0.5) < 0.02
    assert abs(np.mean(bearing > 0) - 0.5) < 0.02


def test_every_scan_consumes_the_same_draws_whatever_the_scene() -> None:
    model = DetectionModel(miss_probability=0.2, clutter_rate=1.5, clutter_range=RANGE)
    states = set()
    for pose in (np.zeros(3), np.array([0.0, 0.0, math.pi]), np.array([50.0, 50.0, 0.0])):
        rng = np.random.default_rng(3)
        for _ in range(5):
            model.scan(SENSOR, pose, LANDMARKS, rng)
        states.add(str(rng.bit_generator.state))
    assert len(states) == 1
    # and the draws are what DetectionModel.draws says
    rng, ref = np.random.default_rng(4), np.random.default_rng(4)
    model.scan(SENSOR, POSE, LANDMARKS, rng)
    n_uniforms, n_normals = model.draws(len(LANDMARKS))
    ref.random(n_uniforms)
    ref.standard_normal(n_normals)
    assert rng.bit_generator.state == ref.bit_generator.state


@pytest.mark.parametrize("rate", [0.1, 1.0, 5.0, 50.0])
def test_the_clutter_count_is_truncated_where_the_poisson_tail_is_negligible(rate) -> None:
    k = max_clutter_count(rate)
    assert poisson.sf(k, rate) < CLUTTER_TAIL * 1.001
    assert poisson.sf(k - 1, rate) >= CLUTTER_TAIL * 0.999
    assert max_clutter_count(0.0) == 0


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"miss_probability": 1.0}, "miss_probability"),
        ({"miss_probability": -0.1}, "miss_probability"),
        ({"clutter_rate": -1.0}, "clutter_rate"),
        ({"clutter_rate": 51.0}, "clutter_rate"),
        ({"clutter_rate": float("nan")}, "clutter_rate"),
        ({"clutter_range": math.inf}, "clutter_range"),
        ({"clutter_range": 0.0}, "clutter_range"),
    ],
)
def test_bad_detection_models_raise_naming_the_field(kwargs, field) -> None:
    with pytest.raises(ValueError, match=field):
        DetectionModel(**kwargs)
