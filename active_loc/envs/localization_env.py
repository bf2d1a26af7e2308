"""``ActiveLocalizationEnv``: a robot in a known landmark map localizes itself with an EKF."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from active_loc.envs.actions import action_space, check_action
from active_loc.envs.association_core import A_ACCURACY, AssociationCore
from active_loc.envs.belief_image import copy_observation, image_observation_space
from active_loc.envs.config import LocalizationConfig
from active_loc.envs.grid_core import GridCore
from active_loc.envs.landmark_core import LandmarkCore
from active_loc.envs.outcome import RewardSettings, StepOutcome, step_info
from active_loc.envs.particle_core import ParticleCore
from active_loc.envs.planner_view import PlannerView
from active_loc.maps import OccupancyGrid
from active_loc.scenarios import scenario_kwargs


class ActiveLocalizationEnv(gym.Env):
    """Active localization in a known map, with an EKF or a Monte Carlo belief.

    ## Description

    A unicycle robot moves with noisy controls in a map it knows: point landmarks, or an
    occupancy grid seen through a lidar. It does not know its own pose exactly: the env keeps
    its belief with a real filter fed by the robot's own sensor (``belief="ekf"``, the
    chapter's Algorithm 2, on landmark maps, or Algorithm 3 when the landmarks look identical;
    ``belief="mcl"``, Algorithm 4, on landmark maps or grids; ``belief="grid"``, Algorithm 1,
    a histogram over map cells and heading bins, on grids) and rewards the agent for
    information gain, the drop in the belief's entropy. The sensor sees only what is inside its
    field of view and range, so the actions decide what the robot learns.

    ## Action Space

    ``action_type="continuous"``: ``Box(-1, 1, (2,), float32)``

    | index | action              | maps linearly to                        |
    |-------|---------------------|-----------------------------------------|
    | 0     | forward speed       | ``V in [v_min, v_max]`` (m/s)           |
    | 1     | turn rate           | ``omega in [-omega_max, omega_max]`` (rad/s) |

    Values outside [-1, 1] are clipped; NaN or inf raises ``ValueError``. Float64 actions are
    used at full precision. ``action_type="discrete"``: ``Discrete(6)``, the primitives stay,
    forward, forward-left, forward-right, turn left, turn right
    (:data:`active_loc.envs.actions.PRIMITIVES`).

    ## Observation Space

    ``observation="belief"``: ``Box(-1, 1, (D,), float32)``: the belief mean, heading, log
    standard deviations, correlations and entropy, then per landmark slot its position relative
    to the belief mean and this step's measurement with a visibility flag (layout in
    :mod:`active_loc.envs.observations`; D = 11 + 6 max_landmarks for the EKF). A particle or
    grid belief adds an 8 x 8 histogram of its mass over the map, and on grids the scan is the
    lidar ranges / max_range (:mod:`active_loc.envs.particle_core`,
    :mod:`active_loc.envs.grid_core`). Built from the belief and the sensor, never from the
    true pose.

    ## Rewards

    ``reward="info_gain"``: ``H(b_{t-1}) - H(b_t)`` (nats) ``- step_cost``
    ``- collision_penalty`` on a blocked move; also ``"neg_entropy"``, ``"logdet"``,
    ``"trace"`` (:mod:`active_loc.envs.rewards`); ``+outcome_reward`` on the step the episode
    terminates with a right belief, ``-outcome_reward`` with a confidently wrong one (0 by
    default). ``info["reward_terms"]`` names every term.

    ## Starting State

    Random map (or the scenario's), true pose uniform in the free space with any heading (or
    fixed). ``initial_belief="gaussian"``: mean = true pose + N(0, diag(initial_error_std^2)),
    covariance diag(initial_belief_std^2); ``"uniform"`` (MCL, grid): the whole free space. No
    measurement has been taken at reset. With ``kidnap=True`` the robot is moved once, unseen
    by the filter, at a step drawn in ``kidnap_window`` x ``horizon``.

    ## Episode End

    Terminated when the belief is confident (largest position std below
    ``localized_position_std`` and heading std below ``localized_heading_std``, and no
    kidnapping ahead or within ``kidnap_grace`` steps behind) unless
    ``terminate_when_localized=False``; truncated by ``max_episode_steps`` of the registration.

    ## Info

    Every step: ``pose_error`` (m), ``heading_error`` (rad), ``entropy`` (nats),
    ``localized`` (confident), ``is_success`` (confident and within ``success_position_tol``
    and ``success_heading_tol`` of the truth), ``collisions`` (this episode so far),
    ``reward_terms``, ``n_visible``, ``nis`` (normalized innovation squared of the EKF update),
    ``kidnapped`` (the robot was kidnapped this step), ``association_accuracy`` (with
    identical-looking landmarks and ``belief="ekf"``: the fraction of this step's detections
    the data association assigned correctly, clutter counting as correct when left unmatched;
    1.0 on a step without detections and with known correspondences). Errors and the
    association accuracy use the truth: they are for evaluation, never seen by the agent; with
    a kidnapping, success also needs it to be past.

    ## Arguments

    ``gymnasium.make("ActiveLoc/LandmarkEKF-v0", render_mode=None, **kwargs)`` where kwargs are
    fields of :class:`active_loc.envs.config.LocalizationConfig` (``belief``, ``map``,
    ``action_type``, ``observation``, ``reward``, noise levels, thresholds, ...).
    """

    metadata: dict[str, Any] = {"render_modes": ["human", "rgb_array"], "render_fps": 10}  # noqa: RUF012

    def __init__(
        self,
        scenario: str = "landmark_tracking",
        render_mode: str | None = None,
        **kwargs: Any,
    ) -> None:
        unknown = sorted(set(kwargs) - set(LocalizationConfig.field_names()))
        if unknown:
            # Python's own wording, which wrappers such as TorchRL's GymEnv recognize when they
            # probe for an optional keyword (frameskip) and retry without it
            raise TypeError(
                f"ActiveLocalizationEnv.__init__() got an unexpected keyword argument "
                f"{unknown[0]!r} (unknown env kwargs {unknown}; valid ones are the fields of "
                "LocalizationConfig)"
            )
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode={render_mode!r} is not one of {self.metadata['render_modes']}"
            )
        self.scenario = scenario
        self.config = LocalizationConfig(**{**scenario_kwargs(scenario), **kwargs})
        self.render_mode = render_mode
        self.core: LandmarkCore | ParticleCore
        if self.config.belief == "grid":
            self.core = GridCore(self.config)  # Markov localization on grid cells: Algorithm 1
        elif self.config.belief == "mcl":
            self.core = ParticleCore(self.config)
        elif not self.config.known_correspondences:
            self.core = AssociationCore(self.config)  # identical-looking landmarks: Algorithm 3
        else:
            self.core = LandmarkCore(self.config, batch_size=1)
        self.action_space = action_space(self.config.action_type)
        self.observation_space = observation_space(self.config, self.core.obs.shape[1])
        self._continuous = self.config.action_type == "continuous"
        # config values read on every step, as plain attributes
        self._reward = reward_settings(self.config)
        self._terminate_when_localized = bool(self.config.terminate_when_localized)
        self._steps = 0
        self._collisions = 0
        self._renderer: Any = None
        self._true_path: list[NDArray[np.float64]] = []
        self._belief_path: list[NDArray[np.float64]] = []
        self._has_reset = False

    # -- gymnasium API ----------------------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        super().reset(seed=seed)
        self.core.reset_member(0, self.np_random)
        self._steps = 0
        self._collisions = 0
        self._has_reset = True
        if self.render_mode is not None:
            self._true_path = [self.core.pose[0, :2].copy()]
            self._belief_path = [self.core.belief_mean[0, :2].copy()]
        info = self._info(self.core.outcome(0))
        if self.render_mode == "human":
            self.render()
        return copy_observation(self.core.observations, 0), info

    def step(
        self, action: Any
    ) -> tuple[NDArray[np.float32], float, bool, bool, dict[str, Any]]:
        if not self._has_reset:
            raise RuntimeError("call reset() before step()")
        core = self.core
        self._write_action(action)
        if core.step((self.np_random,)) >= 0:
            raise ValueError(f"action contains NaN or inf: {action!r}")
        self._steps += 1
        outcome = core.outcome(0)
        if outcome.collided:
            self._collisions += 1
        info = self._info(outcome)
        reward = self._reward.total(outcome)
        if self.render_mode is not None:
            self._true_path.append(core.pose[0, :2].copy())
            self._belief_path.append(core.belief_mean[0, :2].copy())
            if self.render_mode == "human":
                self.render()
        terminated = self._terminate_when_localized and outcome.terminal
        return copy_observation(core.observations, 0), reward, terminated, False, info

    def render(self) -> NDArray[np.uint8] | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode= to make()")
            return None
        if not self._has_reset:
            raise RuntimeError("call reset() before render()")
        if self._renderer is None:
            from active_loc.envs.rendering import GridRenderer, LandmarkRenderer

            grid = isinstance(self.core.maps[0], OccupancyGrid)
            self._renderer = GridRenderer() if grid else LandmarkRenderer()
        frame = self._frame()
        if self.render_mode == "rgb_array":
            return self._renderer.render_rgb(frame)
        self._renderer.show(frame)
        return None

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # -- planners ---------------------------------------------------------------------------

    def planner_view(self) -> PlannerView:
        """A copy of the belief, the map, the models and the action set; never the true pose."""
        if not self._has_reset:
            raise RuntimeError("call reset() before planner_view()")
        lmap = self.core.maps[0]
        assert lmap is not None
        return PlannerView(
            belief=self.core.belief.copy(),
            map=lmap,
            motion=self.core.models.motion,
            sensor=self.core.models.sensor,
            action_space=self.action_space,
            limits=self.core.models.limits,
            step=self._steps,
            known_correspondences=self.config.known_correspondences,
            association_gate=self.config.association_gate,
            likelihood_exponent=self.config.likelihood_exponent,
            collision_penalty=self.config.collision_penalty,
            range_table=getattr(self.core, "range_table", None),
            scan_dual=getattr(self.core, "scan_dual", None),
        )

    # -- helpers ----------------------------------------------------------------------------

    def _write_action(self, action: Any) -> None:
        """Check an action (:func:`~active_loc.envs.actions.check_action`) and write its
        control into ``core.actions[0]``: the continuous action as it is (the core decodes
        it), a discrete one as its primitive's control."""
        checked = check_action(action, self.action_space)
        if self._continuous:
            self.core.actions[0] = checked
        else:
            self.core.actions[0] = self.core.models.primitives[checked]

    def _info(self, outcome: StepOutcome) -> dict[str, Any]:
        """The info dict of the core's last step."""
        return localization_info(outcome, self._collisions, self._association_accuracy(),
                                 self._reward)

    def _association_accuracy(self) -> float:
        """This step's data-association accuracy against the true correspondences; 1.0 when
        the filter is given the correspondences (or associates per particle, MCL)."""
        core = self.core
        if isinstance(core, AssociationCore):
            return float(core.association[0, A_ACCURACY])
        return 1.0

    def _frame(self) -> Any:
        """What the renderer draws this step (truth included: rendering is for people)."""
        title = self.spec.id if self.spec is not None else type(self).__name__
        return build_frame(
            self.core, 0, self._true_path, self._belief_path, self._steps, title
        )


def observation_space(config: LocalizationConfig, vector_size: int) -> gym.spaces.Space:
    """The observation space of a config whose observation vector has ``vector_size``
    entries: that vector's ``Box``, or with ``observation="image"`` the ``Dict`` of
    :mod:`active_loc.envs.belief_image`."""
    if config.observation == "image":
        return image_observation_space(config.image_size, config.image_headings, vector_size)
    return gym.spaces.Box(-1.0, 1.0, (vector_size,), dtype=np.float32)


def reward_settings(config: LocalizationConfig) -> RewardSettings:
    """The reward of a localization task."""
    return RewardSettings(config.reward, float(config.step_cost),
                          float(config.collision_penalty))


def localization_info(
    outcome: StepOutcome, collisions: int, association_accuracy: float, reward: RewardSettings
) -> dict[str, Any]:
    """A step's info dict (:func:`~active_loc.envs.outcome.step_info` and the localization
    envs' own keys, typed by its rule): what the single env returns, and what the vector env
    hands out per sub-env (``ActiveLocalizationVectorEnv.step_with_info_dicts``)."""
    return step_info(outcome, collisions, reward, n_visible=outcome.n_visible,
                     nis=outcome.nis, kidnapped=outcome.kidnapped,
                     association_accuracy=association_accuracy)


def build_frame(
    core: LandmarkCore | ParticleCore,
    b: int,
    true_path: list[NDArray[np.float64]],
    belief_path: list[NDArray[np.float64]],
    step: int,
    title: str,
) -> Any:
    """The renderer's frame of member ``b`` of a core (truth included: rendering is for
    people), with the paths so far ``(T, 2)`` each."""
    from active_loc.envs.rendering import GridFrame, LandmarkFrame

    lmap = core.maps[b]
    assert lmap is not None
    outcome = core.outcome(b)
    particles = weights = belief_map = None
    if isinstance(core, GridCore):
        assert core.belief is not None
        belief_map = core.belief.prob[b].sum(axis=2)
    elif isinstance(core, ParticleCore):
        belief = core.member_belief(b)
        assert belief is not None
        particles, weights = belief.particles.copy(), belief.weights.copy()
    common = {
        "true_pose": core.pose[b].copy(),
        "mean": core.belief_mean[b].copy(),
        "cov": core.belief_cov[b],
        "true_path": np.array(true_path),
        "belief_path": np.array(belief_path),
        "step": step,
        "entropy": outcome.entropy,
        "title": title,
        "particles": particles,
        "weights": weights,
    }
    if isinstance(lmap, OccupancyGrid):
        assert isinstance(core, ParticleCore) and core.lidar is not None
        crowd = core.episode(b).crowd
        return GridFrame(
            grid=lmap, beam_angles=core.lidar.beam_angles, ranges=core.ranges[b].copy(),
            max_range=core.lidar.max_range, kidnapped=outcome.kidnapped,
            people=None if crowd is None else crowd.discs.copy(),
            belief_map=belief_map,
            belief_cell_size=core.config.grid_cell_size if belief_map is not None else 0.0,
            **common,
        )
    n = lmap.n_landmarks
    return LandmarkFrame(
        bounds=lmap.bounds, landmarks=lmap.positions, visible=core.visible[b, :n].copy(),
        fov=core.config.fov, max_range=core.config.max_range, **common,
    )
