"""The Gymnasium environment: act, let the RBPF map, observe the expected map, earn the change in EMMI."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from .. import certainty
from ..geometry.grid import GridGeometry
from ..navigation.candidates import Target
from ..navigation.follower import WaypointFollower
from ..scoring.scores import (
    absolute_trajectory_error,
    accuracy_of_labels,
    building_accuracy_of_labels,
    building_cells,
    map_labels,
    oracle_scores_of_labels,
)
from ..slam import RBPF, RBPFConfig, UpdateMetrics
from ..world import (
    GeneratorConfig,
    GroundTruth,
    LaserConfig,
    OdometryNoise,
    RobotConfig,
    Simulator,
    WorldSpec,
    rasterise,
)
from ..world.loop_worlds import LoopWorldConfig
from ..world.map_sets import WorldSource
from .actions import ActionType, action_factory
from .config import EnvConfig, make_config
from .episode import RobotEpisode
from .memory import check_env_memory
from .observation import ObservationType, observation_factory
from .rendering import HumanWindow, render_frame
from .rewards import FILTER_MEASURES, Reward, StepRewards

#: Simulator steps (60 s) added to the time a route takes at full speed, in the bound on driving it.
ROUTE_SLACK_STEPS = 600


class EmmiEnv(gym.Env):
    """Active SLAM: a robot in a pymunk world maps it with an RBPF; observation = the expected map.

    See :class:`~emmi_gym.env.config.EnvConfig` for every option. What an action is and how it is
    carried out is the action type's (:mod:`emmi_gym.env.actions`, ``action_type``, picked by
    ``action_mode`` and ``velocity_actions``): in waypoint mode an action picks one of
    ``n_frontiers + n_revisits`` candidate targets (use :meth:`action_masks` with sb3-contrib's
    MaskablePPO) and the robot drives there; in velocity mode it is a velocity command for one
    simulator step. What the agent observes is the observation type's
    (:mod:`emmi_gym.env.observation`, ``observation_type``, picked by ``observation``). What a step pays is
    the reward's (:mod:`emmi_gym.env.rewards`, ``reward``, picked by name or given), and only what it and
    ``info`` read is measured: the ground-truth scores (:meth:`ground_truth_scores`) for a reward that
    reads one, ``info_scores="always"`` or the episode's last ``info``.

    The environment owns the loop: the action type drives the episode's robot (``episode``, a
    :class:`~emmi_gym.env.episode.RobotEpisode`: the simulator, the filter fed from it, the oracle
    map), then the environment recomputes what it derives from the expected map if the filter
    updated, and the observation type reads the result through public accessors
    (:attr:`expected_map`, :attr:`metrics`, :attr:`estimated_pose`, :attr:`targets`).
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10}

    def __init__(self, render_mode: str | None = None, **options):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode={render_mode!r} is not valid; choose one of "
                             f"{self.metadata['render_modes']} or None")
        self.config: EnvConfig = make_config(**options)
        cfg = self.config
        self.render_mode = render_mode
        self.robot_config = RobotConfig()
        self.metadata = dict(self.metadata, render_fps=int(round(1.0 / self.robot_config.control_period)))
        self._worlds = WorldSource(cfg.world, cfg.generator, cfg.pixel_size)
        fixed = self._worlds.fixed
        if self._worlds.files is not None and cfg.start_at == "decision":
            raise ValueError(f"the map set {cfg.world!r} has no 'to_decision' routes: use start_at='start'")
        if fixed is not None and cfg.start_at == "decision" and "to_decision" not in fixed.routes:
            raise ValueError(f"start_at='decision' needs a 'to_decision' route; world '{fixed.name}' "
                             f"has {sorted(fixed.routes)}: use start_at='start'")
        if fixed is not None:  # refuse maps too large now, not at the first reset
            grid = GridGeometry.covering(*fixed.bounds, cfg.resolution)
            check_env_memory(grid, cfg.particles, fixed.source or fixed.name)
        # the world's (set when a world is loaded)
        self.world: WorldSpec | None = None
        self.sim: Simulator | None = None
        self.geometry: GridGeometry | None = None
        self.truth: GroundTruth | None = None
        self._reachable: np.ndarray | None = None  # the truth's reachable free space, and its cells (at least 1)
        self._n_reachable = 1
        self._building: np.ndarray | None = None  # the truth's cells a laser could ever observe (building_cells)
        # the episode's (set at reset)
        self.slam: RBPF | None = None
        self.episode: RobotEpisode | None = None
        # derived from the expected map, recomputed when the filter updated (_refresh)
        self._metrics: UpdateMetrics | None = None
        self._expected: np.ndarray | None = None
        self._coverage = 0.0
        self._seen: np.ndarray | None = None  # the oracle map's labels as of the same update
        self._scores: dict | None = None  # the ground-truth scores as of the same update, once asked for
        self.reward: Reward  # the reward paid, and those info shows beside it
        self.info_rewards: tuple[Reward, ...]
        self.reward, self.info_rewards = cfg.rewards()
        self._rewards = StepRewards(self.reward, self.info_rewards, cfg.reward_scale, cfg.time_cost,
                                    cfg.collision_cost)
        self._before: dict | None = None  # the measures the rewards read, as the next step's rewards compare them
        self._window: HumanWindow | None = None
        self._watchers: list = []  # called after every filter update (watch_updates)
        self.action_type: ActionType = action_factory(self, cfg)
        self.action_space = self.action_type.space()
        self.observation_type: ObservationType = observation_factory(self, cfg)
        self.observation_space = self.observation_type.space()

    @property
    def laser_config(self) -> LaserConfig:
        """The simulated laser's settings (the ``laser`` option, built)."""
        return self.config.laser

    @property
    def odometry_config(self) -> OdometryNoise:
        """The odometry's noise (the ``odometry_noise`` option, built)."""
        return self.config.odometry_noise

    @property
    def slam_config(self) -> RBPFConfig:
        """The filter's settings (the ``slam`` option, built with ``particles`` and ``resolution``)."""
        return self.config.slam

    @property
    def generator_config(self) -> GeneratorConfig | LoopWorldConfig:
        """The generated worlds' options (the ``generator`` option, built for the world's family)."""
        return self.config.generator

    # ------------------------------------------------------------------ episode

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        options = dict(options or {})
        start_at = options.pop("start_at", self.config.start_at)
        if options:
            raise ValueError(f"unknown reset option(s) {sorted(options)}; valid: ['start_at']")
        rng = self.np_random
        world = self._worlds.draw(rng)
        if world is not self.world:
            self._set_world(world)
        self.sim.reset(rng)
        self.slam = RBPF(self.slam_config, max_range=self.laser_config.max_range, geometry=self.geometry)
        self.slam.reset(self.sim.odometry_pose, rng)
        self.action_type.reset()
        self.episode = RobotEpisode(self.sim, self.slam, self.laser_config.angles, self.config.max_sim_steps,
                                    measure_updates=self.config.update_records, watchers=tuple(self._watchers))
        if start_at == "decision":
            if "to_decision" not in world.routes:
                raise ValueError(f"start_at='decision' needs a 'to_decision' route in world '{world.name}'")
            self._drive_route(world, "to_decision")
        self.episode.restart_counts()
        self._refresh()
        self._before = self._measures()
        return self.observation_type.observe(), self._info(self._rewards.none(), end=False)

    def _drive_route(self, world, name: str) -> None:
        """Drive a route of the world with the true pose (the filter running), within a bound of time:
        three times what its length takes at full speed, plus a minute (routes are checked against
        the walls when the world loads; the bound catches what the check cannot foresee)."""
        route = world.route(name)
        follower = WaypointFollower(route, self.robot_config.max_speed, self.robot_config.max_turn_rate)
        length = follower.remaining_length(self.sim.true_pose)
        budget = int(3 * length / (self.robot_config.max_speed * self.robot_config.control_period)) + ROUTE_SLACK_STEPS
        for _ in range(budget):
            v, omega = follower.command(self.sim.true_pose)
            if follower.done:
                return
            self.episode.step(v, omega)
        x, y, _ = self.sim.true_pose
        raise RuntimeError(f"world '{world.name}': the route '{name}' ({length:.1f} m) was not driven within "
                           f"{budget} simulator steps; the robot is stuck at ({x:.2f}, {y:.2f}) before waypoint "
                           f"{follower.index} {follower.remaining[0]}")

    def _set_world(self, world) -> None:
        check_env_memory(GridGeometry.covering(*world.bounds, self.config.resolution), self.config.particles,
                         world.source or world.name)  # before any of its grids is made
        self.world = world
        self.sim = Simulator(world, self.robot_config, self.laser_config, self.odometry_config)
        self.geometry = GridGeometry.covering(*world.bounds, self.config.resolution)
        self.action_type.set_world()
        self.truth = rasterise(world, self.config.resolution, self.geometry)
        self._reachable = self.truth.reachable
        self._n_reachable = max(1, int(self._reachable.sum()))
        self._building = building_cells(self.truth.grid)

    def step(self, action):
        if self.slam is None:
            raise RuntimeError("call reset() before step()")
        steps0, collisions0 = self.sim_steps, self.collisions
        acted = self.action_type.act(action)
        self._refresh()
        after = self._measures()
        components = self._rewards.components(self._before, after, self.sim_steps - steps0,
                                               self.collisions - collisions0)
        self._before = after
        reward = self._rewards.total(components)
        terminated = self._coverage >= self.config.coverage_target
        truncated = self.sim_steps >= self.config.max_sim_steps or self.action_type.truncated()
        observation = self.observation_type.observe()
        info = self._info(components, end=terminated or truncated)
        info["sim_steps_this_step"] = self.sim_steps - steps0
        info.update(acted)
        if self.render_mode == "human":
            self.render()
        return observation, reward, bool(terminated), bool(truncated and not terminated), info

    # ------------------------------------------------------------------ derived state (after filter updates)

    def _refresh(self) -> None:
        """Recompute what depends on the expected map, only if the filter updated since last time; else only
        the action type's candidates, if it asks (a target it gave up)."""
        if not self.episode.take_filter_updated():
            if self.action_type.wants_refresh():
                self.action_type.refresh()
            return
        self._metrics = self.slam.measure()
        self._expected = self.slam.expected_map().copy()  # as of this refresh (the filter's own changes)
        self._expected.flags.writeable = False  # handed out by expected_map, never changed
        # coverage: the reachable free space the scans have swept, read on the oracle map (the same scans at
        # the true poses), so that it measures exploration and not how well the estimated map lines up
        # with the floor plan (a map turned by a few degrees would otherwise never reach the target)
        self._seen = self.episode.oracle.labels()
        self._coverage = float(np.count_nonzero((self._seen == 0) & self._reachable)) / self._n_reachable
        self._scores = None  # measured when asked (ground_truth_scores)
        self.action_type.refresh()
        self.observation_type.refresh()

    def ground_truth_scores(self) -> dict[str, float]:
        """The scores against the ground truth (:data:`~emmi_gym.env.rewards.SCORES`) as of the filter's last
        update, measured once per update when first asked: the accuracy against the floor plan and against the
        oracle map, the wall consistency, the ATE and the building accuracy (the share of the building mapped
        correctly, unmapped cells counting as wrong) (ground truth, for evaluation and privileged rewards
        only; what the episode's last ``info`` holds)."""
        if self._expected is None:
            raise RuntimeError("call reset() before ground_truth_scores(): there is no map to score yet")
        if self._scores is None:
            mine = map_labels(self._expected)  # labelled once (unobserved, free, occupied) for every score
            oracle_accuracy, wall_consistency = oracle_scores_of_labels(mine, self._seen, self.geometry.resolution)
            ate = absolute_trajectory_error(self.slam.paths[self.slam.best], self.episode.true_poses_at_updates,
                                            align=False)
            self._scores = {"map_accuracy": accuracy_of_labels(mine, self.truth.grid),
                            "oracle_accuracy": oracle_accuracy, "wall_consistency": wall_consistency, "ate": ate,
                            "building_accuracy": building_accuracy_of_labels(mine, self.truth.grid, self._building)}
        return dict(self._scores)

    def _measures(self) -> dict[str, float]:
        """What the rewards read now (:attr:`StepRewards.reads`): the filter's certainty, the coverage, and the
        ground-truth scores only if a reward reads one."""
        m, measures = self._metrics, {}
        for name in self._rewards.reads:
            if name == "loop_spread":
                measures[name] = certainty.widest_loop_spread(self.slam.paths, self.slam.log_weights, log_weights=True)
            elif name in FILTER_MEASURES:
                measures[name] = getattr(m, name)
            elif name == "coverage":
                measures[name] = self._coverage
            else:
                measures[name] = self.ground_truth_scores()[name]
        return measures

    def watch_updates(self, watcher) -> None:
        """Call ``watcher(slam, true_pose)`` after every filter update of the episodes from the next
        reset on, the drive to the decision point included: the filter (its particles' poses, weights
        and paths) and the true pose at that update. For measuring the filter against the truth
        (:mod:`emmi_gym.tools.experiments.calibration`); the agent never sees what it reads."""
        if not callable(watcher):
            raise TypeError(f"watch_updates takes a callable (slam, true_pose), got {type(watcher).__name__}")
        self._watchers.append(watcher)

    def action_masks(self) -> np.ndarray:
        """Which actions are valid now (for sb3-contrib's MaskablePPO): in waypoint mode the non-empty
        target slots, never all False (with no target at all, slot 0, turning in place, stays valid);
        else all."""
        return self.action_type.action_masks()

    @property
    def decisions(self) -> int:
        """Waypoint decisions taken this episode (0 in velocity mode)."""
        return self.action_type.decisions

    @property
    def sim_steps(self) -> int:
        """Simulator steps taken this episode (after the drive to the decision point); 0 before a reset."""
        return self.episode.sim_steps if self.episode is not None else 0

    @property
    def collisions(self) -> int:
        """Simulator steps this episode spent driving into a wall; 0 before a reset."""
        return self.episode.collisions if self.episode is not None else 0

    @property
    def estimated_pose(self) -> np.ndarray:
        """The robot's pose as the RBPF believes it now (best particle plus odometry since its update)."""
        return self.episode.pose_estimate()

    @property
    def true_path(self) -> np.ndarray:
        """(T, 3) true poses at every simulator step of the episode (ground truth, for evaluation only)."""
        return np.array(self.episode.true_path)

    @property
    def expected_map(self) -> np.ndarray:
        """The expected map (eq. 6) as of the filter's last update before the observation: occupancy
        probabilities on the grid of ``geometry``, read-only (each update gives a new array; copy it to
        change it)."""
        return self._expected

    @property
    def metrics(self) -> UpdateMetrics:
        """The certainty of the particle set (EMMI, entropies, Neff) as of the same update as :attr:`expected_map`."""
        return self._metrics

    @property
    def targets(self) -> list[Target | None]:
        """The candidate target of each action slot (None: empty), in the map frame; [] in velocity mode."""
        return self.action_type.targets

    @property
    def oracle_map(self) -> np.ndarray:
        """The oracle map now (:mod:`emmi_gym.scoring.oracle`): this episode's scans at the true poses, probabilities on
        the grid of ``geometry`` (ground truth, for evaluation only)."""
        return self.episode.oracle.probabilities()

    @property
    def loop_spreads(self) -> list[float]:
        """For each action slot, the loop spread (m) of its revisit target: how much the particles disagree
        about the robot's position relative to the place it revisits
        (:func:`~emmi_gym.certainty.loop_displacement_spread`); 0 for frontiers and empty slots; [] in velocity
        mode."""
        return self.action_type.loop_spreads

    # ------------------------------------------------------------------ info, rendering

    def _info(self, components: dict, end: bool) -> dict:
        """The measures now, the ground-truth scores at the episode's ``end`` (or always, if asked), the rewards'
        components and which of them read the ground truth."""
        m = self._metrics
        scores = self.ground_truth_scores() if end or self.config.info_scores == "always" else {}
        return {
            "emmi": m.emmi, "map_information": m.map_information, "mean_information_best": m.mean_information_best,
            "pose_entropy": m.pose_entropy,
            "weight_entropy": m.weight_entropy, "path_entropy": m.path_entropy, "joint_entropy": m.joint_entropy,
            "neff": m.neff, "resampled": m.resampled, "coverage": self._coverage, **scores,
            "collisions": self.collisions, "sim_steps": self.sim_steps, "reward_components": dict(components),
            "privileged_rewards": list(self._rewards.privileged), "world": self.world.name,
            **({"rbpf_updates": self.episode.take_update_records()} if self.config.update_records else {}),
        }

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        frame = render_frame(self.world.bounds, self.truth.grid, self.geometry, self._expected, self.sim.true_pose,
                             self.episode.true_path, self.slam.poses, self.slam.paths[self.slam.best],
                             self.robot_config.radius)
        if self.render_mode == "rgb_array":
            return frame
        if self._window is None:
            self._window = HumanWindow(self.metadata["render_fps"])
        self._window.show(frame)
        return None

    def close(self):
        if self._window is not None:
            self._window.close()
            self._window = None
