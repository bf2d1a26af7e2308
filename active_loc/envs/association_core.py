"""The simulator of landmark localization with identical-looking landmarks (Algorithm 3).

``belief="ekf"`` with ``known_correspondences=False``. The step order is the landmark
core's, with a scan that carries no identities and an EKF that infers them:

    controls -> true motion (noise, blocked at walls)
             -> scan from the true pose: detections in random order, with misses and clutter
                (:mod:`active_loc.sensors.detections`)
             -> EKF predict; ML data association under the predicted belief with a chi-square
                gate, stacked update with the matched detections
                (:mod:`active_loc.beliefs.association`)
             -> metrics (entropy, errors, association) and the observation row

It is :class:`~active_loc.envs.landmark_core.LandmarkCore` (same ``state`` row layout, maps,
reset, belief views, pickling) with its own fused step kernel. Per step it draws, with the
member's Generator and in blocks of ``NOISE_BLOCK`` steps, the landmark core's normals
(motion, then measurement noise of every landmark slot) and a fixed number of uniforms (miss,
clutter and ordering draws), so every step consumes the same draws whatever the scene.

Observation: the landmark core's layout (``11 + 6 max_landmarks``), where a slot's landmark
part is landmark j of the known map relative to the belief mean, and its measurement part is
the j-th detection of the scan by increasing distance (not landmark j's measurement: the
scan carries no identities). Detections beyond ``max_landmarks`` are not in the observation
(the filter uses all of them).

Metrics: ``n_visible`` counts the landmarks truly detected this step (clutter excluded), and
:attr:`AssociationCore.association` holds this step's association figures against the true
correspondences, at the ``A_*`` offsets: the accuracy is the fraction of detections assigned
correctly, a landmark's detection to that landmark and a false detection to "unmatched";
1.0 on a step without detections (nothing was assigned wrongly).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numba
import numpy as np
from numpy.typing import NDArray

from active_loc.beliefs.association import associate_and_update, gate_threshold
from active_loc.beliefs.ekf import ekf_predict
from active_loc.envs.config import LocalizationConfig
from active_loc.envs.landmark_core import (
    B_COUNT,
    B_WALLS,
    NEED_NOISE,
    NOISE_BLOCK,
    P_DT,
    P_FOV,
    P_KIND,
    P_Q,
    P_QROOT,
    P_R,
    P_RANGE,
    P_RROOT,
    S_COLLIDED,
    S_N_VISIBLE,
    S_NIS,
    W_LANDMARK,
    W_VISIBLE,
    W_Z,
    X_BOX,
    X_COV,
    X_MEAN,
    X_NOISE_CURSOR,
    X_POSE,
    X_STATS,
    LandmarkCore,
    _decode,
    finish_batch,
)
from active_loc.motion import move_within_bounds_scalar
from active_loc.sensors.detections import (
    DetectionModel,
    detection_draws,
    simulate_detections,
    sort_order,
)
from active_loc.sensors.landmarks import RANGE_BEARING

# layout of the detection parameters handed to the step kernel
D_MISS, D_RATE, D_RANGE, D_MAX_CLUTTER, D_GATE = range(5)
N_DETECTION_PARAMS = 5

# layout of a member's row of association figures (this step)
(
    A_ACCURACY,  # fraction of detections assigned correctly (1.0 without detections)
    A_DETECTIONS,  # detections in the scan
    A_LANDMARK_DETECTIONS,  # of which true landmarks
    A_LANDMARKS_CORRECT,  # ... assigned to their own landmark
    A_CLUTTER,  # of which false detections
    A_CLUTTER_REJECTED,  # ... left unmatched by the gate
    A_MATCHED,  # detections that entered the update
) = range(7)
N_ASSOCIATION = 7


@numba.njit(cache=True, nogil=True)
def _score_association(
    n: int, count: int, truth: NDArray, index: NDArray, out: NDArray
) -> None:
    """This step's association figures (``A_*``) against the true correspondences."""
    correct = 0
    landmarks = 0
    landmarks_correct = 0
    clutter = 0
    rejected = 0
    matched = 0
    for i in range(n):
        if index[i] < count:
            matched += 1
        if truth[i] < 0:
            clutter += 1
            if index[i] >= count:
                rejected += 1
                correct += 1
        else:
            landmarks += 1
            if index[i] == truth[i]:
                landmarks_correct += 1
                correct += 1
    out[A_ACCURACY] = correct / n if n > 0 else 1.0
    out[A_DETECTIONS] = n
    out[A_LANDMARK_DETECTIONS] = landmarks
    out[A_LANDMARKS_CORRECT] = landmarks_correct
    out[A_CLUTTER] = clutter
    out[A_CLUTTER_REJECTED] = rejected
    out[A_MATCHED] = matched


@numba.njit(cache=True, nogil=True)
def _write_detection_slots(kind: int, z: NDArray, n: int, world: NDArray) -> None:
    """The observation's measurement slots: the detections ``z[:n]`` by increasing distance,
    as many as there are slots, into the measurement columns of ``world`` ``(N, WORLD_SIZE)``."""
    dist = np.empty(n)
    for i in range(n):
        # range-bearing: the range; relative position: its norm (both are distances)
        dist[i] = z[i, 0] if kind == RANGE_BEARING else np.hypot(z[i, 0], z[i, 1])
    order = np.empty(n, dtype=np.int64)
    sort_order(dist, n, order)
    for s in range(world.shape[0]):
        if s < n:
            world[s, W_Z] = z[order[s], 0]
            world[s, W_Z + 1] = z[order[s], 1]
            world[s, W_VISIBLE] = 1.0
        else:
            world[s, W_Z] = 0.0
            world[s, W_Z + 1] = 0.0
            world[s, W_VISIBLE] = 0.0


@numba.njit(cache=True, nogil=True)
def association_step_batch(
    actions: NDArray,
    params: NDArray,
    detection_params: NDArray,
    noise: NDArray,
    state: NDArray,
    world: NDArray,
    z: NDArray,
    truth: NDArray,
    index: NDArray,
    d2: NDArray,
    detected: NDArray,
    association: NDArray,
    obs: NDArray,
) -> int:
    """One step of the whole batch with identical-looking landmarks.

    Args:
        actions: ``(B, 2)``, as in :func:`active_loc.envs.landmark_core.step_batch`.
        params: the landmark core's packed parameters; detection_params: the ``D_*`` vector.
        noise: ``(B, NOISE_BLOCK, 3 + 2 N + U)``: per step, 3 + 2 N standard normals (motion,
            then measurement noise, as the landmark core's) and U uniforms in [0, 1)
            (``detection_draws``); consumed row by row at the cursor ``state[:, X_NOISE_CURSOR]``.
        state: ``(B, STATE_SIZE)``, world: ``(B, N, WORLD_SIZE)``: updated in place.
        z: ``(B, M, 2)`` out, the scan (M = N + max clutter); truth, index: ``(B, M)`` int out,
            the true and the inferred correspondences (``count`` = unmatched); d2: ``(B, M)``
            out, the Mahalanobis distances; detected: ``(B, N)`` bool out; association:
            ``(B, N_ASSOCIATION)`` out; obs: ``(B, D)`` float32 out.

    Returns:
        -1 on success; the index of a member whose action is not finite; or ``NEED_NOISE``
        when a member's noise block is used up. In the last two cases nothing has changed.
    """
    for b in range(actions.shape[0]):
        if not (np.isfinite(actions[b, 0]) and np.isfinite(actions[b, 1])):
            return b
        if state[b, X_NOISE_CURSOR] >= noise.shape[1]:
            return NEED_NOISE
    r = params[P_R : P_R + 4].reshape(2, 2)
    q = params[P_Q : P_Q + 9].reshape(3, 3)
    kind = int(params[P_KIND])
    dt = params[P_DT]
    qr = P_QROOT
    rr = P_RROOT
    noise_root = (params[rr], params[rr + 2], params[rr + 3])
    max_clutter = int(detection_params[D_MAX_CLUTTER])
    n_normals = 3 + 2 * world.shape[1]
    for b in range(actions.shape[0]):
        v, omega = _decode(actions[b], params)
        row = int(state[b, X_NOISE_CURSOR])
        state[b, X_NOISE_CURSOR] = row + 1
        normals = noise[b, row, :n_normals]
        # true motion with noise L_Q e
        n0, n1, n2 = normals[0], normals[1], normals[2]
        e_x = params[qr] * n0 + params[qr + 1] * n1 + params[qr + 2] * n2
        e_y = params[qr + 3] * n0 + params[qr + 4] * n1 + params[qr + 5] * n2
        e_t = params[qr + 6] * n0 + params[qr + 7] * n1 + params[qr + 8] * n2
        pose = state[b, X_POSE : X_POSE + 3]
        box = state[b, X_BOX : X_BOX + 6]
        collided = move_within_bounds_scalar(
            pose, v, omega, dt, e_x, e_y, e_t, box[:4], box[B_WALLS] > 0.5
        )
        # the scan: detections without identities
        count = int(box[B_COUNT])
        landmarks = world[b, :, W_LANDMARK : W_LANDMARK + 2]
        n = simulate_detections(
            kind, pose, landmarks, count, params[P_FOV], params[P_RANGE], noise_root,
            detection_params[D_MISS], detection_params[D_RATE], detection_params[D_RANGE],
            max_clutter, noise[b, row, n_normals:], normals[3:], z[b], truth[b], detected[b],
        )
        # Algorithm 3: predict, associate under the predicted belief, update with the matches
        mean = state[b, X_MEAN : X_MEAN + 3]
        cov = state[b, X_COV : X_COV + 9].reshape(3, 3)
        ekf_predict(mean, cov, 0.0 if collided else v, omega, dt, q)
        state[b, X_STATS + S_NIS] = associate_and_update(
            mean, cov, z[b], n, landmarks, count, kind, r, detection_params[D_GATE], index[b],
            d2[b],
        )
        state[b, X_STATS + S_COLLIDED] = 1.0 if collided else 0.0
        _score_association(n, count, truth[b], index[b], association[b])
        _write_detection_slots(kind, z[b], n, world[b])
        finish_batch(params, state[b : b + 1], world[b : b + 1], obs[b : b + 1])
        state[b, X_STATS + S_N_VISIBLE] = association[b, A_LANDMARK_DETECTIONS]
    return -1


class AssociationCore(LandmarkCore):
    """B landmark-localization episodes with identical-looking landmarks, misses and clutter,
    and an EKF with maximum-likelihood data association (Algorithm 3).

    Args:
        config: the task; ``belief="ekf"``, ``known_correspondences=False``.
        batch_size: B.

    Besides the landmark core's arrays it keeps the last scan (:attr:`z` ``(B, M, 2)`` with
    :attr:`n_detections`, :attr:`truth`, :attr:`index`, :attr:`d2`), which landmarks were
    detected (:attr:`visible`) and the association figures (:attr:`association`).
    """

    def __init__(self, config: LocalizationConfig, batch_size: int = 1) -> None:
        if config.belief != "ekf" or config.known_correspondences:
            raise ValueError(
                "AssociationCore runs belief='ekf' with known_correspondences=False, got "
                f"belief={config.belief!r}, known_correspondences={config.known_correspondences}"
            )
        # Algorithm 3 runs the numba EKF kernels whatever the backend (filterpy's update takes
        # known correspondences)
        super().__init__(dataclasses.replace(config, ekf_backend="numba"), batch_size)
        n = config.max_landmarks
        scale = self.models.scale
        # clutter spreads over the sensor's range, or a map-sized disc when it is unlimited
        clutter_range = config.max_range if math.isfinite(config.max_range) else scale
        self.detection = DetectionModel(config.miss_probability, config.clutter_rate,
                                        clutter_range)
        max_clutter = self.detection.max_clutter
        n_uniforms, n_normals = detection_draws(n, max_clutter)
        self._n_normals = 3 + n_normals  # motion, then the scan
        self.detection_params = np.zeros(N_DETECTION_PARAMS)
        self.detection_params[D_MISS] = config.miss_probability
        self.detection_params[D_RATE] = config.clutter_rate
        self.detection_params[D_RANGE] = clutter_range
        self.detection_params[D_MAX_CLUTTER] = max_clutter
        self.detection_params[D_GATE] = gate_threshold(config.association_gate)
        rows = n + max_clutter
        # per step the landmark core's normals, then the detection uniforms
        self.noise = np.zeros((batch_size, NOISE_BLOCK, self._n_normals + n_uniforms))
        self._scan = np.zeros((batch_size, rows, 2))
        self.truth = np.full((batch_size, rows), -1, dtype=np.int64)
        self.index = np.zeros((batch_size, rows), dtype=np.int64)
        self.d2 = np.zeros((batch_size, rows))
        self.detected = np.zeros((batch_size, n), dtype=np.bool_)
        self.association = np.zeros((batch_size, N_ASSOCIATION))
        self.association[:, A_ACCURACY] = 1.0
        self._bind_kernel()

    # -- views ---------------------------------------------------------------------------------

    @property
    def z(self) -> NDArray[np.float64]:
        """``(B, M, 2)`` the last scan, rows ``[0, n_detections[b])`` real, in random order."""
        return self._scan

    @property
    def visible(self) -> NDArray[np.bool_]:
        """``(B, N)`` which landmarks the last scan truly detected (a copy; for rendering and
        metrics, never for the filter)."""
        return self.detected.copy()

    @property
    def n_detections(self) -> NDArray[np.int64]:
        """``(B,)`` detections in the last scan."""
        return self.association[:, A_DETECTIONS].astype(np.int64)

    # -- reset and step ------------------------------------------------------------------------

    def reset_member(self, b: int, rng: np.random.Generator) -> None:
        """New episode for member ``b`` (as the landmark core); no scan yet."""
        super().reset_member(b, rng)
        self._scan[b] = 0.0
        self.truth[b] = -1
        self.index[b] = 0
        self.d2[b] = 0.0
        self.detected[b] = False
        self.association[b] = 0.0
        self.association[b, A_ACCURACY] = 1.0

    def refill_noise(self, b: int, rng: np.random.Generator) -> None:
        """Draw the next block of member ``b``'s step noise: normals, then uniforms."""
        block, k = self.noise.shape[1], self._n_normals
        self.noise[b, :, :k] = rng.standard_normal((block, k))
        self.noise[b, :, k:] = rng.random((block, self.noise.shape[2] - k))
        self.rows[b]["noise_cursor"] = 0
        self.noise_source[b] = rng

    def step(self, rngs: Sequence[np.random.Generator]) -> int:
        """Advance every member with the actions in :attr:`actions` ``(B, 2)``.

        Returns:
            -1, or the index of a member whose action is not finite (nothing advanced then).
        """
        code = self._step_kernel()
        if code == NEED_NOISE:
            for b in np.flatnonzero(self.rows["noise_cursor"] >= self.noise.shape[1]):
                self.refill_noise(int(b), rngs[b])
            code = self._step_kernel()
        return code

    def _step_kernel(self) -> int:
        return association_step_batch(*self._kernel_args)

    # -- the kernel's arguments, bound once (a tuple of the arrays above, rebuilt on unpickling)

    def _bind_kernel(self) -> None:
        self._kernel_args = (
            self.actions, self.models.params, self.detection_params, self.noise, self.state,
            self.world, self._scan, self.truth, self.index, self.d2, self.detected,
            self.association, self.obs,
        )

    def __getstate__(self) -> dict:
        state = super().__getstate__()
        del state["_kernel_args"]
        return state

    def __setstate__(self, state: dict) -> None:
        super().__setstate__(state)
        self._bind_kernel()
