"""Monte Carlo localization filter cycles per second, as a ratio to CartPole-v1 env steps/s.

What is measured: one **cycle** is what :class:`active_loc.beliefs.mcl.MCLBelief` does per
time step: ``predict`` (motion sampling and the map prior), the per-particle log-likelihood of
the scan, and ``update`` (weighting and resampling when the ESS drops below half the count).
Every filter has a FIXED count of 1000 particles (no KLD sampling, no injection):

1. landmarks: the chapter's exercise (section 13.8, problem 1): landmarks (0, 0), (2, 8),
   (8, 2), (10, 10), relative-position measurements of all four with R = 0.25 I, dt = 0.1,
   Q = 0.1 dt^2 I, controls V = 1, omega = sin(k dt), true start (1, 1, 0), initial belief
   N(start + N(0, 0.1 I), I); 150 steps;
2. lidar, likelihood field: the 60-beam lidar of ``ActiveLoc/GridMCL-v0`` (270 degrees, 8 m)
   on a 200 x 200 grid (``rooms_map(rng, size_m=(20, 20), resolution=0.1)``), pose tracking;
3. lidar, beam model (ray casting per particle and beam), same map, truth and scans;
3t. the same beam model with the casts precomputed once for the map
   (:class:`active_loc.sensors.range_table.RangeTable`: a range per cell and 1-degree
   direction, and the model's log-probabilities over 1 cm range steps); the table's build
   time is printed, not counted in the cycles;
4. the filter of case 1 written the textbook way, here in this file
   (:func:`textbook_particle_filter_step`): plain Python loops over particles for the motion
   sampling, the weights (per particle and landmark, ``math`` scalars on Python floats) and a
   low-variance resampler. It draws exactly the noise MCLBelief draws (the same arrays, from a
   Generator with the same seed), so both filters run the same algorithm on the same numbers;
   before timing, both are run on the same truth and measurements and their RMSEs printed;
5. the same loop over particles as it is most often written (each particle a numpy vector,
   numpy for its motion and landmark likelihoods: :func:`numpy_loop_particle_filter_step`),
   same noise and resampler. Case 4 is the fastest pure-Python form; case 5 the common one.

How: truth, controls and measurements are simulated up front from seeded
``numpy.random.Generator`` s (nothing here touches a global RNG), so only the filter is timed.
A timing is one episode of cycles from the same initial particles with a freshly seeded
filter Generator, so every repeat does identical work; the first run is a warm-up (numba
kernels compiled or loaded from the cache, estimates recorded for the RMSE column) and each
figure is the best of at least ``--repeats`` timings, more until they add up to a second.
CartPole-v1 is measured in the same run with ``bench_steps.steps_per_second`` (random
actions pre-drawn, through ``gymnasium.make``). For context the env ids
``ActiveLoc/LandmarkMCL-v0``, ``ActiveLoc/GridMCL-v0`` and ``ActiveLoc/GridMCLDynamic-v0``
(KLD sampling, so the particle count is reported) are timed per step the same way.
Targets are printed next to the figures; this script measures and asserts nothing.

    python benchmarks/bench_mcl.py [--repeats 5] [--json out.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import platform
import shlex
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

import gymnasium as gym
import numba
import numpy as np
from bench_steps import random_actions, steps_per_second
from numpy.typing import NDArray

import active_loc
from active_loc.beliefs.mcl import FreeSpace, MCLBelief
from active_loc.envs.config import LocalizationConfig
from active_loc.envs.particle_core import build_lidar
from active_loc.maps.generators import rooms_map
from active_loc.maps.occupancy import OccupancyGrid
from active_loc.motion import UnicycleModel
from active_loc.scenarios import scenario_kwargs
from active_loc.sensors.landmarks import RelativePositionSensor
from active_loc.sensors.lidar import LidarSensor, cast_ray
from active_loc.sensors.range_table import RangeTable

N_PARTICLES = 1000
RESAMPLE_THRESHOLD = 0.5  # MCLBelief's default: resample when ESS < 0.5 K
TEXTBOOK_LANDMARKS = np.array([[0.0, 0.0], [2.0, 8.0], [8.0, 2.0], [10.0, 10.0]])
TEXTBOOK_BOX = (-2.0, -2.0, 14.0, 14.0)  # the free space of the env's textbook map (m)
TEXTBOOK_DT = 0.1
TEXTBOOK_STEPS = 150

# targets of the issue, printed next to the measurements (never asserted)
TARGET_LANDMARKS = 5000.0
TARGET_LIKELIHOOD_FIELD = 2000.0
TARGET_BEAM = 400.0
TARGET_SPEEDUP = 100.0
RANGE_BINS = 360  # directions of the precomputed range table (1 degree)


@dataclass
class Run:
    """One episode of filter cycles.

    Attributes:
        seconds: wall time of the cycle loop (s).
        cycles: cycles run.
        resampled: how many cycles resampled.
        estimates: ``(T, 3)`` pose estimates after each cycle, when recorded.
    """

    seconds: float
    cycles: int
    resampled: int
    estimates: NDArray[np.float64] | None = None


# --- case 1 and 4: the chapter's exercise --------------------------------------------------------


@dataclass(frozen=True)
class LandmarkProblem:
    """Truth, controls and measurements of the exercise, and the shared initial particles.

    Attributes:
        truth: ``(T, 3)`` true pose after each step.
        controls: ``(T, 2)`` (V m/s, omega rad/s) of each step.
        z: ``(T, 4, 2)`` relative-position measurements after each step (m).
        visible: ``(T, 4)`` all True (the exercise sees every landmark).
        initial: ``(K, 3)`` initial particles of both filters.
        motion: the unicycle model (dt, Q).
        sensor: the relative-position sensor (R).
        free_space: the box of the env's textbook map.
        filter_seed: seed of the Generator each filter run draws its noise from.
    """

    truth: NDArray[np.float64]
    controls: NDArray[np.float64]
    z: NDArray[np.float64]
    visible: NDArray[np.bool_]
    initial: NDArray[np.float64]
    motion: UnicycleModel
    sensor: RelativePositionSensor
    free_space: FreeSpace
    filter_seed: int


def textbook_problem(seed: int, steps: int = TEXTBOOK_STEPS) -> LandmarkProblem:
    """Simulate the exercise for ``steps`` steps from a Generator seeded with ``seed``."""
    rng = np.random.default_rng(seed)
    dt = TEXTBOOK_DT
    motion = UnicycleModel(dt, 0.1 * dt**2 * np.eye(3))
    sensor = RelativePositionSensor(0.25 * np.eye(2))
    k = np.arange(1, steps + 1)
    controls = np.stack([np.ones(steps), np.sin(k * dt)], axis=-1)
    pose = np.array([1.0, 1.0, 0.0])
    truth = np.empty((steps, 3))
    z = np.empty((steps, 4, 2))
    visible = np.empty((steps, 4), dtype=np.bool_)
    for t in range(steps):
        pose = motion.sample(pose, controls[t], rng)
        truth[t] = pose
        z[t], visible[t] = sensor.measure(pose, TEXTBOOK_LANDMARKS, rng)
    mean = np.array([1.0, 1.0, 0.0]) + math.sqrt(0.1) * rng.standard_normal(3)
    initial = mean + rng.standard_normal((N_PARTICLES, 3))  # covariance I
    initial[:, 2] = (initial[:, 2] + np.pi) % (2 * np.pi) - np.pi
    return LandmarkProblem(
        truth, controls, z, visible, initial, motion, sensor,
        FreeSpace.from_box(*TEXTBOOK_BOX), int(rng.integers(2**31)),
    )


def run_landmark_mcl(problem: LandmarkProblem, record: bool = False) -> Run:
    """Case 1: MCLBelief over the exercise, one cycle per step."""
    belief = MCLBelief(problem.free_space, problem.motion, N_PARTICLES,
                       resample_threshold=RESAMPLE_THRESHOLD)
    belief.set_particles(problem.initial)
    rng = np.random.default_rng(problem.filter_seed)
    steps = problem.controls.shape[0]
    estimates = np.empty((steps, 3)) if record else None
    resampled = 0
    start = time.perf_counter()
    for t in range(steps):
        belief.predict(problem.controls[t], rng)
        belief.update_landmarks(problem.z[t], problem.visible[t], TEXTBOOK_LANDMARKS,
                                problem.sensor, rng)
        resampled += belief.resampled
        if estimates is not None:
            estimates[t] = belief.mean()
    return Run(time.perf_counter() - start, steps, resampled, estimates)


@dataclass(frozen=True)
class TextbookModel:
    """The exercise's models as Python floats, for :func:`textbook_particle_filter_step`.

    Attributes:
        dt: time step (s).
        noise_root: rows of L with L L^T = Q (the same L as MCLBelief's motion model).
        r_inv: ``(a, b, c, d)``, the entries of R^-1 row by row.
        log_norm: ``-log(2 pi) - 0.5 log det R``.
        box: ``(x_min, y_min, x_max, y_max)`` (m), the free space.
        landmarks: landmark positions (m).
    """

    dt: float
    noise_root: tuple[tuple[float, float, float], ...]
    r_inv: tuple[float, float, float, float]
    log_norm: float
    box: tuple[float, float, float, float]
    landmarks: tuple[tuple[float, float], ...]

    @classmethod
    def of(cls, problem: LandmarkProblem) -> TextbookModel:
        """The models of ``problem``."""
        r = problem.sensor.noise_cov
        r_inv = np.linalg.inv(r)
        root = problem.motion.noise_root
        return cls(
            float(problem.motion.dt),
            tuple(tuple(float(v) for v in row) for row in root),  # type: ignore[misc]
            (float(r_inv[0, 0]), float(r_inv[0, 1]), float(r_inv[1, 0]), float(r_inv[1, 1])),
            -math.log(2.0 * math.pi) - 0.5 * math.log(float(np.linalg.det(r))),
            TEXTBOOK_BOX,
            tuple((float(x), float(y)) for x, y in TEXTBOOK_LANDMARKS),
        )


@dataclass
class TextbookParticles:
    """A particle set as Python lists: poses and normalized log-weights."""

    xs: list[float]
    ys: list[float]
    ths: list[float]
    log_w: list[float]


def textbook_initial(initial: NDArray[np.float64], model: TextbookModel) -> TextbookParticles:
    """Uniform weights over ``initial`` ``(K, 3)``, zero outside the box (as set_particles)."""
    k = initial.shape[0]
    xs, ys, ths = (initial[:, i].tolist() for i in range(3))
    x_min, y_min, x_max, y_max = model.box
    log_w = [
        -math.log(k) if (x_min <= x <= x_max and y_min <= y <= y_max) else -math.inf
        for x, y in zip(xs, ys, strict=True)
    ]
    top = max(log_w)
    lse = top + math.log(sum(math.exp(v - top) for v in log_w))
    return TextbookParticles(xs, ys, ths, [v - lse for v in log_w])


def textbook_particle_filter_step(
    p: TextbookParticles,
    control: tuple[float, float],
    z: list[list[float]],
    normals: list[list[float]],
    u: float,
    model: TextbookModel,
) -> tuple[TextbookParticles, bool]:
    """One MCL cycle the textbook way: Python loops over the particles, no numba, no vectors.

    Motion: ``x += V cos(theta) dt + (L n)_x`` (likewise y and theta, wrapped), and weight 0
    outside the box. Weights: ``log w += sum_j log N(z_j; R(theta)^T (m_j - p), R)``, per
    particle and landmark with ``math`` scalars, then normalized. Resampling when
    ESS < 0.5 K: the low-variance sampler of Thrun et al. (2005, table 4.4) with ``r = u / K``.

    Args:
        p: the particle set (its lists are updated in place unless it resamples).
        control: (V m/s, omega rad/s).
        z: ``4 x 2`` measurements (m) as nested lists.
        normals: ``K x 3`` standard normals (the motion noise MCLBelief draws).
        u: one uniform in [0, 1) (the first of the K + 1 that MCLBelief draws).
        model: the models as Python floats.

    Returns:
        The particle set after the cycle and whether it resampled.
    """
    xs, ys, ths, log_w = p.xs, p.ys, p.ths, p.log_w
    k = len(xs)
    v, om = control
    dt = model.dt
    (l00, l01, l02), (l10, l11, l12), (l20, l21, l22) = model.noise_root
    x_min, y_min, x_max, y_max = model.box
    two_pi = 2.0 * math.pi
    # --- motion sampling and the map prior
    for i in range(k):
        n0, n1, n2 = normals[i]
        th = ths[i]
        x = xs[i] + v * math.cos(th) * dt + l00 * n0 + l01 * n1 + l02 * n2
        y = ys[i] + v * math.sin(th) * dt + l10 * n0 + l11 * n1 + l12 * n2
        th = th + om * dt + l20 * n0 + l21 * n1 + l22 * n2
        if not -math.pi <= th < math.pi:
            th = (th + math.pi) % two_pi - math.pi
        xs[i], ys[i], ths[i] = x, y, th
        if not (x_min <= x <= x_max and y_min <= y <= y_max):
            log_w[i] = -math.inf
    # --- weights: per particle, per landmark
    a, b, c, d = model.r_inv
    log_norm = model.log_norm
    for i in range(k):
        x, y, th = xs[i], ys[i], ths[i]
        cs, sn = math.cos(th), math.sin(th)
        ll = 0.0
        for (mx, my), (z0, z1) in zip(model.landmarks, z, strict=True):
            dx = mx - x
            dy = my - y
            r0 = z0 - (cs * dx + sn * dy)
            r1 = z1 - (-sn * dx + cs * dy)
            ll += log_norm - 0.5 * (r0 * (a * r0 + b * r1) + r1 * (c * r0 + d * r1))
        log_w[i] += ll
    top = max(log_w)
    if top == -math.inf:
        raise RuntimeError("textbook filter: every weight is zero")
    w = [math.exp(lw - top) for lw in log_w]
    total = sum(w)
    w = [wi / total for wi in w]
    ess = 1.0 / sum(wi * wi for wi in w)
    if ess >= RESAMPLE_THRESHOLD * k:
        shift = top + math.log(total)
        return TextbookParticles(xs, ys, ths, [lw - shift for lw in log_w]), False
    # --- low-variance resampling (table 4.4)
    r = u / k
    cum = w[0]
    j = 0
    new_x: list[float] = []
    new_y: list[float] = []
    new_th: list[float] = []
    for m in range(k):
        target = r + m / k
        while target > cum and j < k - 1:
            j += 1
            cum += w[j]
        new_x.append(xs[j])
        new_y.append(ys[j])
        new_th.append(ths[j])
    return TextbookParticles(new_x, new_y, new_th, [-math.log(k)] * k), True


def textbook_mean(p: TextbookParticles) -> NDArray[np.float64]:
    """Weighted mean pose, heading circular (as MCLBelief.mean)."""
    w = np.exp(np.asarray(p.log_w))
    w /= w.sum()
    th = np.asarray(p.ths)
    return np.array([w @ np.asarray(p.xs), w @ np.asarray(p.ys),
                     math.atan2(w @ np.sin(th), w @ np.cos(th))])


def run_textbook(problem: LandmarkProblem, record: bool = False) -> Run:
    """Case 4: :func:`textbook_particle_filter_step` over the exercise, drawing from a Generator
    exactly what MCLBelief draws (3 K normals per predict, K + 1 uniforms per update)."""
    model = TextbookModel.of(problem)
    particles = textbook_initial(problem.initial, model)
    rng = np.random.default_rng(problem.filter_seed)
    steps = problem.controls.shape[0]
    controls = [(float(v), float(w)) for v, w in problem.controls]
    zs = problem.z.tolist()
    estimates = np.empty((steps, 3)) if record else None
    resampled = 0
    start = time.perf_counter()
    for t in range(steps):
        normals = rng.standard_normal((N_PARTICLES, 3)).tolist()
        u = float(rng.random(N_PARTICLES + 1)[0])
        particles, did = textbook_particle_filter_step(
            particles, controls[t], zs[t], normals, u, model
        )
        resampled += did
        if estimates is not None:
            estimates[t] = textbook_mean(particles)
    return Run(time.perf_counter() - start, steps, resampled, estimates)


def numpy_loop_particle_filter_step(
    particles: list[NDArray[np.float64]],
    log_w: NDArray[np.float64],
    control: NDArray[np.float64],
    z: NDArray[np.float64],
    normals: NDArray[np.float64],
    u: float,
    problem: LandmarkProblem,
) -> tuple[list[NDArray[np.float64]], NDArray[np.float64], bool]:
    """One MCL cycle as it is most often written in Python: a loop over particles, each a
    numpy 3-vector, with numpy for that particle's motion and its landmark likelihoods.

    The same algorithm, noise and resampler as :func:`textbook_particle_filter_step`.

    Args:
        particles: K poses ``(3,)`` (replaced, not changed in place).
        log_w: ``(K,)`` normalized log-weights (changed in place unless it resamples).
        control: ``(2,)`` (V m/s, omega rad/s).
        z: ``(4, 2)`` measurements (m).
        normals: ``(K, 3)`` standard normals (the motion noise MCLBelief draws).
        u: one uniform in [0, 1).
        problem: the exercise (models, landmarks).
    """
    k = len(particles)
    v, om = control
    dt = problem.motion.dt
    root = problem.motion.noise_root
    r_inv = np.linalg.inv(problem.sensor.noise_cov)
    log_norm = -math.log(2.0 * math.pi) - 0.5 * math.log(np.linalg.det(problem.sensor.noise_cov))
    low = np.array(TEXTBOOK_BOX[:2])
    high = np.array(TEXTBOOK_BOX[2:])
    moved = []
    for i in range(k):
        x = particles[i]
        step = np.array([v * np.cos(x[2]) * dt, v * np.sin(x[2]) * dt, om * dt])
        x = x + step + root @ normals[i]
        x[2] = (x[2] + np.pi) % (2.0 * np.pi) - np.pi
        moved.append(x)
        if np.any(x[:2] < low) or np.any(x[:2] > high):
            log_w[i] = -np.inf
            continue
        c, s = np.cos(x[2]), np.sin(x[2])
        expected = (TEXTBOOK_LANDMARKS - x[:2]) @ np.array([[c, -s], [s, c]])
        e = z - expected
        log_w[i] += np.sum(log_norm - 0.5 * np.einsum("ij,jk,ik->i", e, r_inv, e))
    w = np.exp(log_w - np.max(log_w))
    w /= w.sum()
    if 1.0 / np.sum(w * w) >= RESAMPLE_THRESHOLD * k:
        log_w[:] = np.log(w)
        return moved, log_w, False
    # low-variance resampling (table 4.4), the same loop as the textbook filter
    r = u / k
    cum = w[0]
    j = 0
    chosen = []
    for m in range(k):
        target = r + m / k
        while target > cum and j < k - 1:
            j += 1
            cum += w[j]
        chosen.append(moved[j].copy())
    return chosen, np.full(k, -math.log(k)), True


def run_numpy_loop(problem: LandmarkProblem, record: bool = False) -> Run:
    """Case 5: :func:`numpy_loop_particle_filter_step` over the exercise, with the noise draws
    of :func:`run_textbook`."""
    k = problem.initial.shape[0]
    particles = [row.copy() for row in problem.initial]
    inside = np.all((problem.initial[:, :2] >= TEXTBOOK_BOX[:2])
                    & (problem.initial[:, :2] <= TEXTBOOK_BOX[2:]), axis=1)
    log_w = np.where(inside, 0.0, -np.inf)
    log_w -= np.log(np.sum(inside))
    rng = np.random.default_rng(problem.filter_seed)
    steps = problem.controls.shape[0]
    estimates = np.empty((steps, 3)) if record else None
    resampled = 0
    start = time.perf_counter()
    for t in range(steps):
        normals = rng.standard_normal((k, 3))
        u = float(rng.random(k + 1)[0])
        particles, log_w, did = numpy_loop_particle_filter_step(
            particles, log_w, problem.controls[t], problem.z[t], normals, u, problem
        )
        resampled += did
        if estimates is not None:
            poses = np.array(particles)
            w = np.exp(log_w)
            estimates[t] = (w @ poses[:, 0], w @ poses[:, 1],
                            math.atan2(w @ np.sin(poses[:, 2]), w @ np.cos(poses[:, 2])))
    return Run(time.perf_counter() - start, steps, resampled, estimates)


# --- cases 2 and 3: lidar on a grid --------------------------------------------------------------


@dataclass(frozen=True)
class GridProblem:
    """A drive through a rooms map with its lidar scans, and the shared initial particles.

    Attributes:
        grid: the map (200 x 200 cells of 0.1 m).
        truth: ``(T, 3)`` true pose after each step.
        controls: ``(T, 2)`` the controls the filter is given (V = 0 on a blocked move, as the
            env does).
        scans: ``(T, M)`` simulated ranges (m).
        initial: ``(K, 3)`` initial particles (pose tracking).
        motion: the unicycle model.
        lidar: the filter's lidar model (likelihood field).
        filter_seed: seed of the Generator each filter run draws its noise from.
    """

    grid: OccupancyGrid
    truth: NDArray[np.float64]
    controls: NDArray[np.float64]
    scans: NDArray[np.float64]
    initial: NDArray[np.float64]
    motion: UnicycleModel
    lidar: LidarSensor
    filter_seed: int


def grid_problem(seed: int, steps: int = 150) -> GridProblem:
    """Simulate ``steps`` steps of a robot driving through a 20 m x 20 m rooms map with the
    lidar, motion noise and initial belief of ``ActiveLoc/GridMCL-v0``'s defaults (pose
    tracking: initial mean error and spread (0.5 m, 0.5 m, 0.3 rad))."""
    rng = np.random.default_rng(seed)
    cfg = LocalizationConfig(**{**scenario_kwargs("grid_global"), "n_particles": N_PARTICLES})
    lidar = build_lidar(cfg)
    true_lidar = build_lidar(cfg, simulated=True)
    motion = UnicycleModel(cfg.dt, np.diag(np.square(cfg.motion_noise_std)))
    grid = rooms_map(rng, size_m=(20.0, 20.0), resolution=0.1)
    arrays = grid.kernel_arrays()
    values, res, ox, oy, c, s = arrays
    field = grid.distance_field()
    # a start well clear of the walls
    candidates = grid.sample_free(rng, 1000)
    cells = grid.world_to_cell(candidates)
    clear = field[cells[:, 1], cells[:, 0]] >= 0.8
    xy = candidates[np.argmax(clear)]
    pose = np.array([xy[0], xy[1], rng.uniform(-np.pi, np.pi)])
    start = pose.copy()
    truth = np.empty((steps, 3))
    controls = np.empty((steps, 2))
    scans = np.empty((steps, lidar.n_beams))
    dt = cfg.dt
    for t in range(steps):
        # a simple driver: ahead if the way is clear, else turn on the spot
        ahead = cast_ray(values, res, ox, oy, c, s, pose[0], pose[1], pose[2], 1.5, True)
        v, om = (0.5, 0.4 * math.sin((t + 1) * dt)) if ahead >= 1.0 else (0.0, 1.2)
        noise = motion.noise_root @ rng.standard_normal(3)
        dx = v * math.cos(pose[2]) * dt + noise[0]
        dy = v * math.sin(pose[2]) * dt + noise[1]
        pose[2] = (pose[2] + om * dt + noise[2] + np.pi) % (2 * np.pi) - np.pi
        dist = math.hypot(dx, dy)
        blocked = False
        if dist > 0.0:
            run = cast_ray(values, res, ox, oy, c, s, pose[0], pose[1], math.atan2(dy, dx),
                           dist, True)
            target = np.array([pose[0] + dx, pose[1] + dy])
            blocked = run < dist or not bool(grid.is_free(target))
            if not blocked:
                pose[:2] = target
        truth[t] = pose
        controls[t] = (0.0 if blocked else v, om)
        scans[t] = true_lidar.measure(pose, arrays, rng)
    mean = start + rng.standard_normal(3) * np.asarray(cfg.initial_error_std)
    initial = mean + rng.standard_normal((N_PARTICLES, 3)) * np.asarray(cfg.initial_belief_std)
    initial[:, 2] = (initial[:, 2] + np.pi) % (2 * np.pi) - np.pi
    return GridProblem(grid, truth, controls, scans, initial, motion, lidar,
                       int(rng.integers(2**31)))


def run_grid_mcl(
    problem: GridProblem, lidar: LidarSensor, record: bool = False,
    ranges: RangeTable | None = None,
) -> Run:
    """Cases 2, 3 and 3t: MCLBelief through the drive, weighting with ``lidar``'s model, as the
    env's particle core does; with ``ranges``, the beam model from that precomputed table."""
    grid = problem.grid
    free = FreeSpace.from_grid(grid.values, grid.resolution, grid.origin)
    arrays = grid.kernel_arrays()
    field = grid.distance_field()
    # the env's fast path for the likelihood field: per-cell log-probabilities, once per map
    table = lidar.log_table(field) if lidar.model == "likelihood_field" else None
    belief = MCLBelief(free, problem.motion, N_PARTICLES, resample_threshold=RESAMPLE_THRESHOLD)
    belief.set_particles(problem.initial)
    rng = np.random.default_rng(problem.filter_seed)
    steps = problem.controls.shape[0]
    estimates = np.empty((steps, 3)) if record else None
    resampled = 0
    start = time.perf_counter()
    for t in range(steps):
        belief.predict(problem.controls[t], rng)
        if ranges is not None:
            log_lik = ranges.log_likelihood(problem.scans[t], belief.particles)
        elif table is not None:
            log_lik = lidar.field_log_likelihood(problem.scans[t], belief.particles, arrays, table)
        else:
            log_lik = lidar.log_likelihood(problem.scans[t], belief.particles, arrays, field)
        belief.update(log_lik, rng)
        resampled += belief.resampled
        if estimates is not None:
            estimates[t] = belief.mean()
    return Run(time.perf_counter() - start, steps, resampled, estimates)


# --- measuring -----------------------------------------------------------------------------------


def best_of(
    run: Callable[[bool], Run], repeats: int, min_seconds: float = 1.0
) -> tuple[Run, Run]:
    """A recorded warm-up run, then the fastest of at least ``repeats`` timed runs, repeated
    until the timed runs add up to ``min_seconds`` (so short cases get more tries)."""
    warm = run(True)
    best = run(False)
    total = best.seconds
    count = 1
    while count < repeats or total < min_seconds:
        timed = run(False)
        total += timed.seconds
        count += 1
        if timed.seconds < best.seconds:
            best = timed
    return warm, best


def recorded(run: Run) -> NDArray[np.float64]:
    """The estimates of a recorded run."""
    if run.estimates is None:
        raise ValueError("this run did not record its estimates")
    return run.estimates


def rmse(estimates: NDArray[np.float64], truth: NDArray[np.float64]) -> tuple[float, float]:
    """Position RMSE (m) and heading RMSE (rad, wrapped residuals) over the steps."""
    pos = float(np.sqrt(np.mean(np.sum((estimates[:, :2] - truth[:, :2]) ** 2, axis=-1))))
    head = (estimates[:, 2] - truth[:, 2] + np.pi) % (2 * np.pi) - np.pi
    return pos, float(np.sqrt(np.mean(head**2)))


def env_steps_per_second(
    env_id: str, steps: int, repeats: int
) -> tuple[float, NDArray[np.int64], int]:
    """Best-of-``repeats`` steps per second of ``gymnasium.make(env_id)`` with random actions
    drawn up front, resets in the timed loop (as ``bench_steps``); plus the particle count
    after each step and the number of episode ends, from an untimed first pass over the same
    seed and actions (which also warms up)."""
    env = gym.make(env_id)
    actions = random_actions(env.action_space, steps)
    core = env.unwrapped.core  # type: ignore[attr-defined]

    counts = np.empty(steps, dtype=np.int64)
    episodes = 0
    env.reset(seed=1)
    for i, action in enumerate(actions):
        _, _, terminated, truncated, _ = env.step(action)
        counts[i] = core.belief.n_active
        if terminated or truncated:
            episodes += 1
            env.reset()
    best = math.inf
    for _ in range(repeats):
        env.reset(seed=1)
        start = time.perf_counter()
        for action in actions:
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset()
        best = min(best, time.perf_counter() - start)
    env.close()
    return steps / best, counts, episodes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timings per figure (best of)")
    parser.add_argument("--textbook-repeats", type=int, default=3,
                        help="timings of the slow textbook baseline")
    parser.add_argument("--cartpole-steps", type=int, default=50_000)
    parser.add_argument("--env-steps", type=int, default=600,
                        help="steps per timing of the ActiveLoc env ids")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", default=None, help="also write the figures to this file")
    args = parser.parse_args()

    machine = platform.processor() or platform.machine()
    print(f"machine: {machine}, {os.cpu_count()} cpus, {platform.system()} {platform.release()}")
    print(f"python {platform.python_version()}, numpy {np.__version__}, numba {numba.__version__}, "
          f"gymnasium {gym.__version__}, active_loc {active_loc.__version__}")
    print(f"command: {shlex.join(sys.orig_argv)}")
    print(f"{N_PARTICLES} particles (fixed, no KLD); each figure the best of >= {args.repeats} "
          f"timings ({args.textbook_repeats} for the textbook baseline) and >= 1 s of them; "
          f"seed {args.seed}\n")

    cartpole = steps_per_second("CartPole-v1", args.cartpole_steps, args.repeats)

    # like for like: the same truth, measurements and noise through both landmark filters
    exercise = textbook_problem(args.seed)
    warm_ours, best_ours = best_of(lambda rec: run_landmark_mcl(exercise, rec), args.repeats)
    warm_text, best_text = best_of(lambda rec: run_textbook(exercise, rec),
                                   args.textbook_repeats)
    warm_np, best_np = best_of(lambda rec: run_numpy_loop(exercise, rec),
                               args.textbook_repeats)
    est_ours, est_text = recorded(warm_ours), recorded(warm_text)
    ours_rmse = rmse(est_ours, exercise.truth)
    text_rmse = rmse(est_text, exercise.truth)
    gap = np.abs(est_ours - est_text)
    gap[:, 2] = np.abs((est_ours[:, 2] - est_text[:, 2] + np.pi) % (2 * np.pi) - np.pi)
    print(f"like for like on the exercise ({exercise.truth.shape[0]} steps, same truth, "
          f"measurements and Generator noise):")
    print(f"  MCLBelief: position RMSE {ours_rmse[0]:.4f} m, heading RMSE {ours_rmse[1]:.4f} "
          f"rad, resampled {warm_ours.resampled} of {warm_ours.cycles} cycles")
    print(f"  textbook:  position RMSE {text_rmse[0]:.4f} m, heading RMSE {text_rmse[1]:.4f} "
          f"rad, resampled {warm_text.resampled} of {warm_text.cycles} cycles")
    print(f"  largest estimate difference: {max(gap[:, 0].max(), gap[:, 1].max()):.2e} m, "
          f"{gap[:, 2].max():.2e} rad\n")

    drive = grid_problem(args.seed)
    field_lidar = drive.lidar
    beam_lidar = dataclasses.replace(drive.lidar, model="beam")
    warm_lf, best_lf = best_of(lambda rec: run_grid_mcl(drive, field_lidar, rec), args.repeats)
    warm_bm, best_bm = best_of(lambda rec: run_grid_mcl(drive, beam_lidar, rec), args.repeats)
    RangeTable.build(beam_lidar, drive.grid.kernel_arrays(), n_angles=8)  # compile
    start = time.perf_counter()
    ranges = RangeTable.build(beam_lidar, drive.grid.kernel_arrays(), n_angles=RANGE_BINS)
    build_seconds = time.perf_counter() - start
    warm_bt, best_bt = best_of(lambda rec: run_grid_mcl(drive, beam_lidar, rec, ranges),
                               args.repeats)

    ny, nx = drive.grid.shape
    print(f"grid cases: rooms_map {ny}x{nx} cells of {drive.grid.resolution:g} m, lidar "
          f"{field_lidar.n_beams} beams over {math.degrees(field_lidar.fov):.0f} deg, "
          f"{field_lidar.max_range:g} m, sigma_hit {field_lidar.sigma_hit:g} m; "
          f"{drive.truth.shape[0]} steps of pose tracking; the range table of case 3t: "
          f"{RANGE_BINS} directions, {ranges.ranges.nbytes / 1e6:.1f} MB, built once in "
          f"{build_seconds:.2f} s\n")
    rows: list[tuple[str, Run, Run, float, float]] = [
        ("1 MCL landmarks, the exercise", warm_ours, best_ours, TARGET_LANDMARKS, ours_rmse[0]),
        ("2 MCL lidar, likelihood field", warm_lf, best_lf, TARGET_LIKELIHOOD_FIELD,
         rmse(recorded(warm_lf), drive.truth)[0]),
        ("3 MCL lidar, beam model with ray casting", warm_bm, best_bm, TARGET_BEAM,
         rmse(recorded(warm_bm), drive.truth)[0]),
        ("3t MCL lidar, beam model, precomputed casts", warm_bt, best_bt, TARGET_BEAM,
         rmse(recorded(warm_bt), drive.truth)[0]),
        ("4 filter 1 the textbook way (Python floats)", warm_text, best_text, math.nan,
         text_rmse[0]),
        ("5 filter 1 as a Python loop of numpy", warm_np, best_np, math.nan,
         rmse(recorded(warm_np), exercise.truth)[0]),
    ]
    results: dict[str, dict[str, float | None]] = {
        "CartPole-v1": {"steps_per_second": cartpole, "ratio_to_cartpole": 1.0}
    }
    header = (f"{'case':<44} {'cycles/s':>9} {'x CartPole':>10} {'target':>7} {'met':>4} "
              f"{'resampled':>9} {'RMSE m':>7}")
    print(header)
    print(f"{'CartPole-v1 env steps/s (reference)':<44} {cartpole:>9.0f} {1.0:>10.3f}")
    for label, warm, best, target, pos_rmse in rows:
        rate = best.cycles / best.seconds
        met = "-" if math.isnan(target) else ("yes" if rate >= target else "no")
        target_txt = "-" if math.isnan(target) else f"{target:.0f}"
        print(f"{label:<44} {rate:>9.0f} {rate / cartpole:>10.3f} {target_txt:>7} {met:>4} "
              f"{f'{warm.resampled}/{warm.cycles}':>9} {pos_rmse:>7.3f}")
        results[label] = {"cycles_per_second": rate, "ratio_to_cartpole": rate / cartpole,
                          "target": None if math.isnan(target) else target,
                          "resampled_fraction": warm.resampled / warm.cycles}
    ours_cycle = best_ours.seconds / best_ours.cycles
    for name, baseline in (("textbook (Python floats)", best_text),
                           ("Python loop of numpy", best_np)):
        speedup = baseline.seconds / baseline.cycles / ours_cycle
        print(f"\nMCLBelief / {name} on the exercise: {speedup:.0f}x "
              f"(target >= {TARGET_SPEEDUP:.0f}x: {'yes' if speedup >= TARGET_SPEEDUP else 'no'})",
              end="")
        results[f"speedup_ours_over_{name}"] = {"ratio": speedup, "target": TARGET_SPEEDUP}
    print()

    print(f"\nfor context, whole env steps through gymnasium.make ({args.env_steps} steps per "
          f"timing, random actions, resets timed):")
    print(f"{'env':<44} {'steps/s':>9} {'x CartPole':>10} {'ms/step':>8}  particles")
    for env_id in ("ActiveLoc/LandmarkMCL-v0", "ActiveLoc/GridMCL-v0",
                   "ActiveLoc/GridMCLDynamic-v0"):
        rate, counts, episodes = env_steps_per_second(env_id, args.env_steps, args.repeats)
        if counts.min() == counts.max():
            particles = f"{counts[0]} fixed"
        else:
            particles = (f"mean {counts.mean():.0f}, median {np.median(counts):.0f}, "
                         f"min {counts.min()}, max {counts.max()} (KLD)")
        print(f"{env_id:<44} {rate:>9.0f} {rate / cartpole:>10.3f} {1000.0 / rate:>8.3f}  "
              f"{particles}; {episodes} episode end(s)")
        results[env_id] = {"steps_per_second": rate, "ratio_to_cartpole": rate / cartpole,
                           "mean_particles": float(counts.mean())}
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)


if __name__ == "__main__":
    main()
