"""The Gymnasium environments: API conformance, seeding, vectorisation, options, behaviour."""

import copy
import multiprocessing as mp
import os
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from helpers import assert_same

import emmi_gym
from emmi_gym.env import ENV_IDS
from emmi_gym.tools.policies import FrontierPolicy

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
gym.register_envs(emmi_gym)
IDS = [f"emmi_gym/{name}" for name in ENV_IDS]
SMALL = dict(particles=5)  # fewer particles: the behaviour under test does not depend on M


frontier_action = FrontierPolicy()  # the nearest frontier (slot 0), else the first valid slot


# ------------------------------------------------------------------ registration and API


@pytest.mark.slow
@pytest.mark.parametrize("env_id", IDS)
def test_check_env_passes_without_warnings(env_id):
    env = gym.make(env_id, render_mode="rgb_array", **SMALL)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=False)
    assert [str(w.message) for w in caught] == []
    env.close()


def test_ids_register_idempotently_and_by_module_string():
    from emmi_gym.env import register_envs

    register_envs()
    register_envs()
    assert all(env_id in gym.registry for env_id in IDS)
    env = gym.make("emmi_gym:LoopCorridor-v1", **SMALL)
    assert env.unwrapped.config.world == "loop_corridor"
    env.close()


@pytest.mark.parametrize("name", ["LoopCorridor", "LoopOrder", "Explore", "ExplorePlans"])
def test_an_older_version_is_refused_naming_the_current_one(name):
    """The ids whose episodes changed went up a version; the old one raises Gymnasium's own error and the
    project's checks of an id (agent configurations, --env-id) say the same in one line."""
    from emmi_gym.inputs.env_ids import check_env_id
    from emmi_gym.inputs.errors import FieldError

    with pytest.raises(gym.error.DeprecatedEnv, match=f"Please use `emmi_gym/{name}-v1` instead"):
        gym.make(f"emmi_gym/{name}-v0")
    with pytest.raises(FieldError, match=f"expected the current version of emmi_gym/{name}, 'emmi_gym/{name}-v1'"):
        check_env_id(f"emmi_gym/{name}-v0", "config.yaml", "env.id")
    assert check_env_id(f"emmi_gym/{name}-v1", "config.yaml", "env.id") == f"emmi_gym/{name}-v1"
    with pytest.raises(FieldError, match="expected one of emmi-gym's environment ids"):
        check_env_id("emmi_gym/Nothing-v0", "config.yaml", "env.id")


def test_spaces_and_info():
    env = gym.make("emmi_gym/LoopCorridor-v1", **SMALL, info_rewards="all", info_scores="always")
    obs, info = env.reset(seed=1)
    assert obs["map"].shape == (2, 64, 64) and obs["map"].dtype == np.uint8
    assert env.observation_space.contains(obs)
    for key in ("emmi", "map_information", "mean_information_best", "pose_entropy", "weight_entropy", "path_entropy",
                "joint_entropy", "neff", "resampled", "coverage", "map_accuracy", "oracle_accuracy", "wall_consistency",
                "ate", "collisions", "sim_steps", "reward_components", "privileged_rewards"):
        assert key in info
    assert "rbpf_updates" not in info  # only with update_records
    before = info
    obs, reward, terminated, truncated, info = env.step(frontier_action(env))
    assert set(info["reward_components"]) == {"emmi", "pose_entropy", "joint_entropy", "coverage", "emmi_coverage",
                                              "map_information", "loop_spread", "oracle_accuracy",
                                              "wall_consistency", "ate", "time", "collision"}
    gained = info["map_information"] - before["map_information"]
    assert gained > 100 and info["reward_components"]["map_information"] == pytest.approx(1e-3 * gained)
    expected = info["reward_components"]["emmi"] + info["reward_components"]["time"] + \
        info["reward_components"]["collision"]
    assert reward == pytest.approx(expected)
    assert info["sim_steps_this_step"] > 10 and info["target_kind"] == "frontier"
    image = gym.make("emmi_gym/LoopCorridor-v1", observation="image", obs_size=48, **SMALL)
    assert image.observation_space.shape == (2, 48, 48)
    _, info = image.reset(seed=1)  # by default, the reward paid alone and no ground-truth score before the end
    assert set(info["reward_components"]) == {"emmi", "time", "collision"} and "oracle_accuracy" not in info


def test_update_records_list_every_update_and_change_nothing_else():
    """With update_records every filter update's metrics are in info (measured at each update); without,
    the certainty is measured once per step: the same episode, the same figures."""
    runs = []
    for records in (False, True):
        env = gym.make("emmi_gym/LoopCorridor-v1", update_records=records, info_scores="always", **SMALL)
        _, info = env.reset(seed=3)
        steps = [info]
        for _ in range(2):
            steps.append(env.step(frontier_action(env))[-1])
        runs.append((steps, env.unwrapped.slam.step, env.unwrapped.true_path))
    (lazy, lazy_updates, lazy_path), (eager, eager_updates, eager_path) = runs
    assert lazy_updates == eager_updates and np.array_equal(lazy_path, eager_path)
    for a, b in zip(lazy, eager, strict=False):
        assert {k: a[k] for k in ("emmi", "pose_entropy", "joint_entropy", "neff", "ate")} == \
            {k: b[k] for k in ("emmi", "pose_entropy", "joint_entropy", "neff", "ate")}
        assert b["rbpf_updates"][-1]["emmi"] == b["emmi"]
        assert all(set(row) >= {"step", "emmi", "joint_entropy", "neff"} for row in b["rbpf_updates"])
    assert len(eager[0]["rbpf_updates"]) > 80  # the drive to the decision point: one row per filter update
    steps = [row["step"] for info in eager for row in info["rbpf_updates"]]
    assert steps == list(range(eager_updates))  # every update once


def test_render_rgb_array_and_human():
    env = gym.make("emmi_gym/ExploreVelocity-v0", render_mode="rgb_array", **SMALL)
    env.reset(seed=0)
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8
    from emmi_gym.env.rendering import _BEST_PATH, _PARTICLES, _ROBOT, _TRUE_PATH, CAPTION_HEIGHT

    legend = frame[:CAPTION_HEIGHT].reshape(-1, 3)
    for colour in (_TRUE_PATH, _ROBOT, _BEST_PATH, _PARTICLES):  # each colour's name is written in it
        assert np.any(np.all(legend == colour, axis=1))
    assert env.metadata["render_fps"] == 10  # the 0.1 s control period
    human = gym.make("emmi_gym/ExploreVelocity-v0", render_mode="human", **SMALL)
    human.reset(seed=0)
    human.step(human.action_space.sample())
    human.close()


# ------------------------------------------------------------------ seeding, pickling, vectorisation


def run(env_id, seed, steps, **options):
    env = gym.make(env_id, **options)
    obs, info = env.reset(seed=seed)
    trace = [(obs, info)]
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        if env.unwrapped.config.action_mode == "waypoint":
            action = int(rng.choice(np.flatnonzero(env.unwrapped.action_masks())))
        else:
            action = rng.uniform(-1, 1, 2).astype(np.float32)
        obs, reward, terminated, truncated, info = env.step(action)
        trace.append((obs, reward, terminated, truncated, info))
        if terminated or truncated:
            break
    env.close()
    return trace


def test_same_seed_same_episode():
    assert_same(run("emmi_gym/ExploreVelocity-v0", 3, 50, **SMALL), run("emmi_gym/ExploreVelocity-v0", 3, 50, **SMALL))
    assert_same(run("emmi_gym/LoopCorridor-v1", 4, 3, **SMALL), run("emmi_gym/LoopCorridor-v1", 4, 3, **SMALL))
    other = run("emmi_gym/ExploreVelocity-v0", 5, 2, **SMALL)
    assert not np.array_equal(other[0][0]["map"], run("emmi_gym/ExploreVelocity-v0", 3, 0, **SMALL)[0][0]["map"])


def _trace_in_subprocess(queue):
    queue.put(pickle.dumps(run("emmi_gym/ExploreVelocity-v0", 3, 20, **SMALL)))


@pytest.mark.slow
def test_same_seed_same_episode_across_processes():
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    process = ctx.Process(target=_trace_in_subprocess, args=(queue,))
    process.start()
    remote = pickle.loads(queue.get(timeout=300))
    process.join(timeout=60)
    assert_same(remote, run("emmi_gym/ExploreVelocity-v0", 3, 20, **SMALL))


@pytest.mark.parametrize("env_id", IDS)
def test_pickled_and_copied_envs_continue_identically(env_id):
    env = gym.make(env_id, **SMALL, max_decisions=3).unwrapped
    env.reset(seed=2)
    waypoint = env.config.action_mode == "waypoint"
    if waypoint:
        env.step(frontier_action(env))  # a plan is made and kept (the cost map)
    clones = [pickle.loads(pickle.dumps(env)), copy.deepcopy(env)]
    for _ in range(2 if waypoint else 15):
        action = frontier_action(env) if waypoint else np.array([0.8, 0.3], dtype=np.float32)
        a = env.step(action)
        for clone in clones:
            assert_same(a, clone.step(action))


@pytest.mark.slow
def test_async_vector_env_and_sb3_subproc_spawn():
    envs = gym.make_vec("emmi_gym/ExploreVelocity-v0", num_envs=2, vectorization_mode="async", **SMALL)
    obs, _ = envs.reset(seed=0)
    assert obs["map"].shape == (2, 2, 64, 64)
    for _ in range(3):
        obs, rewards, terminated, truncated, infos = envs.step(envs.action_space.sample())
    assert rewards.shape == (2,)
    envs.close()

    from stable_baselines3.common.vec_env import SubprocVecEnv

    # a spawned child has not imported emmi_gym: the "module:Id" form makes gymnasium import it first
    vec = SubprocVecEnv([lambda: gym.make("emmi_gym:ExploreVelocity-v0", **SMALL)] * 2, start_method="spawn")
    vec.seed(0)
    obs = vec.reset()
    for _ in range(3):
        obs, rewards, dones, infos = vec.step(np.zeros((2, 2), dtype=np.float32))
    assert obs["map"].shape == (2, 2, 64, 64)
    vec.close()


# ------------------------------------------------------------------ options


@pytest.mark.parametrize("options, message", [
    (dict(colour="red"), r"gym.make: field 'colour': expected one of the known options \[.*'reward'"),
    (dict(reward="fun"), r"field 'reward': expected a registered reward's name \(one of \['emmi', 'pose_entropy', "
                         r"'joint_entropy', 'coverage', 'emmi_coverage', 'map_information'.*\) or a Reward, "
                         r"got 'fun'"),
    (dict(action_mode="teleport"), r"expected one of \['waypoint', 'velocity'\]"),
    (dict(particles=0), r"field 'particles': expected an integer in \[1, 1000\]"),
    (dict(laser={"beams": 10}), r"field 'laser.beams': expected one of the known options \['fov', 'n_beams'"),
    (dict(laser={"n_beams": -1}), r"field 'laser.n_beams': expected an integer in \[1, 10000\]"),
    (dict(odometry_noise={"rot_from_rot": -1}), r"field 'odometry_noise.rot_from_rot': expected a finite number in "
                                                r"\[0, 1\], got -1"),
    (dict(world="nowhere"), "unknown world 'nowhere'"),
    (dict(world="office"), "start_at='decision' needs a 'to_decision' route"),
    (dict(coverage_target=1.5), r"field 'coverage_target': expected a finite number in \(0, 1\]"),
    (dict(slam={"likelihood_exponent": -1}), r"field 'slam.likelihood_exponent': expected a finite number in \(0, 1\]"),
    # wrong types, never a TypeError from deep inside
    (dict(laser={"n_beams": 3.0}), r"field 'laser.n_beams': expected an integer in \[1, 10000\].*, got 3.0"),
    (dict(laser={"n_beams": float("nan")}), r"field 'laser.n_beams': .*, got nan"),
    (dict(slam={"likelihood_sigma": 1e-300}), r"field 'slam.likelihood_sigma': expected a finite number in "
                                              r"\[0.001, 10\]"),
    (dict(world=None, generator={"spacing": float("inf")}), r"field 'generator.spacing': .*, got inf"),
    (dict(world=None, generator={"wall_thickness": "x"}), r"field 'generator.wall_thickness': .*, got 'x'"),
    (dict(egocentric="no"), r"field 'egocentric': expected true or false, got 'no'"),
    (dict(slam={"particles": 5}), r"field 'slam.particles': expected no particles inside slam: "
                                  r"give it as the top-level"),
    (dict(time_cost="cheap"), r"field 'time_cost': expected a finite number in \[0, 1000\], got 'cheap'"),
    # values that would give NaN or inf later
    (dict(reward_scale=float("inf")), r"field 'reward_scale': expected a finite number in \(0, 1e\+06\] or null"),
    (dict(reward_scale=1e308), r"field 'reward_scale': .*, got 1e\+308"),
    (dict(odometry_noise={"rot_from_rot": 1e300}), r"field 'odometry_noise.rot_from_rot': expected a finite number in "
                                                   r"\[0, 1\]"),
    (dict(slam={"logodds_step": 1e6}), r"field 'slam.logodds_step': expected a finite number in \[0.001, 1\]"),
    (dict(laser={"range_sigma": float("inf")}), r"field 'laser.range_sigma': .*, got inf"),
    (dict(world=None, generator={"wall_thickness": float("nan")}), r"field 'generator.wall_thickness': .*, got nan"),
    # sizes: bounded before anything is allocated
    (dict(particles=10**9), r"field 'particles': expected an integer in \[1, 1000\] "
                            r"\(each particle holds a whole map\)"),
    (dict(obs_size=10**6), r"field 'obs_size': expected an integer in \[36, 256\]"),
    (dict(n_frontiers=10**7), r"field 'n_frontiers': expected an integer in \[1, 64\]"),
    (dict(world=None, generator={"nx": 10**4}), r"field 'generator.nx': expected an integer in \[2, 20\]"),
    (dict(world=None, generator={"spacing": 1e6}), r"field 'generator.spacing': expected a finite number in "
                                                   r"\[1.6, 50\] m"),
    (dict(laser={"n_beams": 10**8}), r"field 'laser.n_beams': expected an integer in \[1, 10000\]"),
    (dict(resolution=1e-9), r"field 'resolution': expected a finite number in \[0.01, 1\] m"),
])
def test_bad_options_raise_a_clear_error(options, message):
    with pytest.raises(ValueError, match=message):
        gym.make("emmi_gym/LoopCorridor-v1", **options)


def test_the_options_are_built_once_into_one_typed_tree():
    """gym.make builds the nested options with the config (a preset, a dict of fields or the dataclass itself are
    one value), and the env hands those objects down; the filter's particles and resolution are the top-level
    options, declared once."""
    from dataclasses import fields

    from emmi_gym.env.config import EnvConfig, make_config
    from emmi_gym.slam import RBPFConfig
    from emmi_gym.world import GeneratorConfig, LaserConfig, OdometryNoise
    from emmi_gym.world.loop_worlds import LoopWorldConfig

    sick = LaserConfig(fov=np.pi, n_beams=181, max_range=30.0, range_sigma=0.01, drop_probability=0.005)
    config = make_config(laser="sick_lms200", odometry_noise={"preset": "poor"}, slam={"linear_update": 1.0},
                         particles=7, resolution=0.2)
    assert config.laser == sick and config == make_config(**{**vars(config), "laser": sick})
    assert isinstance(config.odometry_noise, OdometryNoise) and config.generator == GeneratorConfig()
    assert (config.slam.linear_update, config.slam.particles, config.slam.resolution) == (1.0, 7, 0.2)
    assert pickle.loads(pickle.dumps(config)) == config
    loops = make_config(world="loop_order", generator={"loop_width": 30.0}).generator
    assert loops == LoopWorldConfig(loop_width=30.0)
    env = gym.make("emmi_gym/Explore-v1", laser=sick, slam=RBPFConfig(particles=5, linear_update=1.0),
                   **SMALL).unwrapped
    assert env.laser_config is env.config.laser and env.slam_config is env.config.slam
    env.reset(seed=0)
    assert env.slam.config is env.config.slam  # the filter runs on the object gym.make built
    declared = {f.name: f.metadata["check"] for f in fields(RBPFConfig)}
    assert all(f.metadata["check"] is declared[f.name] for f in fields(EnvConfig) if f.name in ("particles",
                                                                                                 "resolution"))
    with pytest.raises(ValueError, match=r"field 'slam.particles': expected 15, as the top-level option particles"):
        make_config(slam=RBPFConfig(particles=5))
    with pytest.raises(ValueError, match=r"field 'generator': expected a mapping of options or a GeneratorConfig, "
                                         r"got LoopWorldConfig"):
        make_config(world=None, generator=LoopWorldConfig())
    with pytest.raises(ValueError, match=r"field 'generator.nx': expected one of the known options \['loop_width'"):
        make_config(world="loop_order", generator={"nx": 3})


def test_the_old_ways_to_read_the_nested_options_warn():
    from emmi_gym.env.config import make_config
    from emmi_gym.inputs import validation

    config = make_config(laser="sick_lms200")
    for method, field in (("laser_config", "laser"), ("odometry_config", "odometry_noise"),
                          ("slam_config", "slam"), ("generator_config", "generator")):
        with pytest.warns(FutureWarning, match=rf"EnvConfig.{method}\(\) is deprecated: read EnvConfig.{field}.*"
                                               r"0\.5\.0"):
            assert getattr(config, method)() is getattr(config, field)
    with pytest.warns(FutureWarning, match="Preset is deprecated: Options"):
        assert validation.Preset(("a",))("a") == "a"


def test_bad_render_mode_and_reset_option():
    # gymnasium itself warns first that 'screen' is not in metadata["render_modes"]
    with (pytest.raises(ValueError, match=r"render_mode='screen' is not valid"),
          pytest.warns(UserWarning, match="screen")):
        gym.make("emmi_gym/LoopCorridor-v1", render_mode="screen")
    env = gym.make("emmi_gym/ExploreVelocity-v0", **SMALL)
    with pytest.raises(ValueError, match=r"unknown reset option\(s\) \['speed'\]"):
        env.reset(seed=0, options={"speed": 2})


# ------------------------------------------------------------------ behaviour


def test_decision_point_offers_the_papers_choice():
    """At the decision point one slot closes the loop (target A, the start) and one enters the new area (B)."""
    env = gym.make("emmi_gym/LoopCorridor-v1")
    obs, _ = env.reset(seed=0)
    world, targets = env.unwrapped.world, env.unwrapped.targets
    a, b = world.place("target_a"), world.place("target_b")
    revisits = [t for t in targets if t is not None and t.kind == "revisit"]
    frontiers = [t for t in targets if t is not None and t.kind == "frontier"]
    assert any(np.hypot(t.x - a.x, t.y - a.y) < 2.0 for t in revisits)
    # the side corridor to the new area opens west of the decision point, between y = 8 and 10,
    # and leads towards target B
    pose = env.unwrapped.estimated_pose
    assert any(t.x < 2.5 and 7.5 <= t.y <= 10.5
               and np.hypot(t.x - b.x, t.y - b.y) < np.hypot(pose[0] - b.x, pose[1] - b.y) for t in frontiers)
    mask = env.unwrapped.action_masks()
    assert mask.tolist() == [t is not None for t in targets]
    # the observation describes every slot: the policy can tell the loop-closing target from the frontiers
    rows = obs["targets"]
    assert rows.shape == (8, 8) and rows[:, 0].tolist() == mask.tolist()
    assert rows[:, 1].tolist() == [float(t is not None and t.kind == "revisit") for t in targets]
    assert not rows[~mask].any()
    xmin, ymin, xmax, ymax = world.bounds
    side = max(xmax - xmin, ymax - ymin)
    for row, t in zip(rows, targets, strict=False):
        if t is None:
            continue
        np.testing.assert_allclose(row[2:5] * [side, side, 2 * side],
                                   [t.x - pose[0], t.y - pose[1], t.travel_cost], atol=1e-4)
        if t.kind == "revisit":  # a loop the particles disagree about: more than a cell (0.1 m), less than 1 m
            assert row[6] >= 1 / 3 - 1e-6 and 0.1 < row[7] * 0.5 < 1.0
        else:
            assert row[5] > 0 and row[6] == row[7] == 0


def episode_return(env, policy) -> tuple[float, dict, bool]:
    total, done, terminated = 0.0, False, False
    while not done:
        _, reward, terminated, truncated, info = env.step(policy(env))
        total += reward
        done = terminated or truncated
    return total, info, terminated


@pytest.mark.slow
def test_frontier_policy_covers_the_map_and_beats_doing_nothing():
    """Under the default (EMMI) reward, exploring to the coverage target earns more than standing
    still or spinning in place until the step budget runs out (the same budget for all three)."""
    budget = dict(SMALL, max_sim_steps=6000)
    explore = gym.make("emmi_gym/LoopCorridor-v1", **budget)
    explore.reset(seed=0)
    explore_return, info, terminated = episode_return(explore, frontier_action)
    assert terminated and info["coverage"] >= 0.9
    assert info["sim_steps"] < explore.unwrapped.config.max_sim_steps

    returns = {}
    for name, command in (("still", (0.0, 0.0)), ("spin", (0.0, 1.0))):
        env = gym.make("emmi_gym/LoopCorridor-v1", action_mode="velocity", **budget)
        env.reset(seed=0)
        returns[name], info, terminated = episode_return(
            env, lambda _, command=command: np.array(command, dtype=np.float32))
        assert not terminated and info["sim_steps"] == env.unwrapped.config.max_sim_steps
    assert returns["still"] < explore_return and returns["spin"] < explore_return, (returns, explore_return)


def test_spinning_in_place_farms_emmi_but_not_emmi_coverage():
    """Fast version of measurements/reward_farming.py: 150 steps of spinning at the start of a plan with a 180-degree
    laser. Re-scanning raises EMMI (a mean over observed cells) well beyond the time cost; weighted by coverage
    the same rise pays little; standing still pays exactly the time cost under every variant."""
    spin, still = {}, {}
    for returns, command in ((spin, (0.0, 1.0)), (still, (0.0, 0.0))):
        env = gym.make("emmi_gym/ExplorePlans-v1", action_mode="velocity", max_sim_steps=150, info_rewards="all")
        env.reset(seed=0)
        done = False
        while not done:
            _, _, terminated, truncated, info = env.step(np.array(command, dtype=np.float32))
            for name, value in info["reward_components"].items():
                returns[name] = returns.get(name, 0.0) + value
            done = terminated or truncated
    time_cost = spin["time"]
    assert time_cost == pytest.approx(-0.3)
    assert spin["emmi"] + time_cost > 1.0
    assert spin["emmi_coverage"] < 0.2 * spin["emmi"]
    assert all(still[name] == pytest.approx(0.0, abs=1e-9) for name in ("emmi", "emmi_coverage", "coverage",
                                                                          "map_information"))


def test_pooled_map_keeps_thin_walls():
    """A wall one cell thick under 0.5 m pixels of 0.1 m cells still shows in every pixel it crosses."""
    from emmi_gym.env.observation import MapPooling
    from emmi_gym.geometry.grid import GridGeometry

    geometry = GridGeometry(0.1, 0.0, 0.0, 100, 100)
    em = np.full(geometry.shape, 0.5)
    em[:, :] = 0.1           # all known free
    em[:, 52] = 0.95         # a wall at x = 5.2 m, one cell thick
    em[80:, :30] = 0.5       # an unknown corner
    image = MapPooling()(em, geometry, (0.0, 0.0, 0.5), 20)
    wall_col = 10            # x 5.0 - 5.5 m
    assert (image[:, wall_col] == 242).all()
    assert image[10, 3] == 25 and image[0, 0] == 127


def test_the_map_image_follows_the_robot_between_filter_updates():
    """Channel 1 marks the estimated path (128) and the robot (255) at every step, though the map and the
    path are drawn only when the filter updates: each observation equals one drawn from scratch."""
    from emmi_gym.env.observation import MapPooling, map_and_path, view_window, with_robot

    env = gym.make("emmi_gym/ExploreVelocity-v0", **SMALL)
    obs, _ = env.reset(seed=0)
    core = env.unwrapped
    robot_pixels, updates = set(), set()
    for _ in range(30):
        obs, *_ = env.step(np.array([1.0, 0.2], dtype=np.float32))
        pose, path = core.estimated_pose, core.slam.paths[core.slam.best]
        window = view_window(core.world.bounds, pose, 64, False, 0.0)
        pooled = MapPooling()(core.expected_map, core.geometry, window, 64)
        np.testing.assert_array_equal(obs["map"], with_robot(map_and_path(pooled, path, window, 64), pose, window, 64))
        x0, y0, mpp = window
        row, col = 63 - int(np.floor((pose[1] - y0) / mpp)), int(np.floor((pose[0] - x0) / mpp))
        assert obs["map"][1, row, col] == 255
        robot_pixels.add((row, col))
        updates.add(core.slam.step)
    assert len(robot_pixels) > len(updates) > 1  # the robot moved on between updates
    assert (obs["map"][1] == 128).any()  # the path it left behind


def test_the_laser_is_simulated_only_when_the_filter_will_use_it():
    env = gym.make("emmi_gym/ExploreVelocity-v0", **SMALL)
    env.reset(seed=0)
    core, scans = env.unwrapped, []
    original = core.sim.scan
    core.sim.scan = lambda: scans.append(1) or original()
    for _ in range(30):  # standing still: no filter update is due
        env.step(np.zeros(2, dtype=np.float32))
    assert scans == []
    for _ in range(30):  # 30 steps at full speed = 1.8 m: about one update per 0.5 m
        _, _, _, _, info = env.step(np.array([1.0, 0.0], dtype=np.float32))
        assert len(scans) == core.slam.step - 1  # one scan per update since reset's first one
    assert 2 <= len(scans) <= 4


def test_targets_near_a_blocked_attempt_are_not_offered_again():
    from emmi_gym.navigation.candidates import BLOCKED_RADIUS, candidate_slots

    env = gym.make("emmi_gym/LoopCorridor-v1", **SMALL)
    env.reset(seed=0)
    core = env.unwrapped
    first = next(t for t in core.targets if t is not None)
    slots = candidate_slots(core.expected_map, core.slam.paths[core.slam.best], core.action_type.navigation.costs, 6, 2,
                            blocked=[(first.x, first.y)])
    assert all(t is None or np.hypot(t.x - first.x, t.y - first.y) > BLOCKED_RADIUS for t in slots)
    assert sum(t is not None for t in slots) >= 1


def test_targets_are_offered_again_when_every_one_lies_by_a_blocked_attempt():
    """Better a target where an attempt ended blocked before the map changed than none at all: the robot
    stood still to the end of the episode (4 of 100 random-action episodes of Explore-v1). Block every
    target offered until only targets by blocked points are left: those are offered again."""
    from emmi_gym.navigation.candidates import BLOCKED_RADIUS

    env = gym.make("emmi_gym/LoopCorridor-v1", **SMALL)
    env.reset(seed=0)
    core = env.unwrapped
    for _ in range(30):
        offered = [t for t in core.targets if t is not None]
        assert offered and core.action_masks().sum() == len(offered)
        blocked = core.action_type.blocked
        if blocked and all(min(np.hypot(t.x - x, t.y - y) for x, y in blocked) <= BLOCKED_RADIUS for t in offered):
            break
        core.action_type.blocked.extend((t.x, t.y) for t in offered)
        core.action_type.refresh()
    else:
        pytest.fail("targets away from every blocked point were still offered after 30 rounds")


def test_with_no_target_left_the_robot_turns_in_place_and_the_filter_sees_it():
    """move_base's rotate recovery: with every slot empty the robot turns in place for the stay (the
    filter updates on the turns, which cleared the ghost walls that shut the robot in for good in
    2 of 100 random-action episodes of Explore-v1); an empty slot picked while targets are left
    still stands still, so turning (which raises EMMI) is not an action an agent can choose."""
    from emmi_gym.env.actions import STAY_STEPS

    env = gym.make("emmi_gym/LoopCorridor-v1", **SMALL)
    env.reset(seed=0)
    core = env.unwrapped
    n = core.config.n_actions
    target = next(t for t in core.action_type.slots if t is not None)
    core.action_type.slots = [target] + [None] * (n - 1)
    pose, updates, steps = core.sim.true_pose.copy(), core.slam.step, core.sim_steps
    _, _, _, _, info = env.step(1)
    assert info["target_kind"] == "none" and core.sim_steps == steps + STAY_STEPS
    moved = core.sim.true_pose - pose  # the robot coasts to a stop from reset's drive
    assert np.hypot(*moved[:2]) < 0.05 and abs(moved[2]) < 0.01 and core.slam.step == updates

    core.action_type.slots = [None] * n
    _, _, _, _, info = env.step(0)
    assert info["target_kind"] == "none" and core.sim_steps == steps + 2 * STAY_STEPS
    turned = STAY_STEPS * core.robot_config.control_period * core.robot_config.max_turn_rate
    assert np.hypot(*(core.sim.true_pose[:2] - pose[:2])) < 0.05
    assert core.slam.step - updates >= int(0.8 * turned / core.slam.config.angular_update)


def test_a_wall_seen_on_the_way_makes_the_robot_replan():
    from emmi_gym.geometry.grid import GridGeometry
    from emmi_gym.navigation.planner import path_obstructed, travel_costs

    geometry = GridGeometry(0.1, 0.0, 0.0, 60, 100)      # 10 m x 6 m, all known free
    em = np.full(geometry.shape, 0.1)
    straight = [(1.0, 3.0), (9.0, 3.0)]
    assert not path_obstructed(em, geometry, straight, 0.2)
    em[10:50, 50] = 0.9                                  # a wall at x = 5 m from y = 1 to 5 m
    assert path_obstructed(em, geometry, straight, 0.2)
    assert not path_obstructed(em, geometry, straight, 0.2, skip=8.5)  # only the part past the wall is checked
    clear = np.full(geometry.shape, 0.1)
    echoes = np.arange(25, 35), np.full(10, 50)            # the scan sees a wall at x = 5 m the map lacks
    assert path_obstructed(clear, geometry, straight, 0.2, layer=(*echoes, 0.9))
    assert not path_obstructed(clear, geometry, straight, 0.2, layer=(*echoes, 0.5))  # a layer below blocking_p
    assert not path_obstructed(clear, geometry, straight, 0.2, layer=(np.array([5]), np.array([50]), 0.9))  # 2.5 m off
    costs = travel_costs(em, geometry, (1.0, 3.0), 0.2, goal_xy=(9.0, 3.0))
    detour = [(1.0, 3.0)] + costs.path_to(9.0, 3.0)
    assert not path_obstructed(em, geometry, detour, 0.2)
    assert max(y for _, y in detour) > 5.2 or min(y for _, y in detour) < 0.8  # round an end of the wall
    assert np.hypot(*np.subtract(detour[-1], (9.0, 3.0))) < 0.1


def test_a_loop_through_unseen_space_is_offered_by_the_length_of_its_route():
    """A U-shaped path of 22 m whose start lies 10 m away, 8 m of them unknown: the route is 10 m
    (the loop closes 2.2 times its length), though the planner's cost, twice per unknown metre, is
    18 m, which alone would fail the 1.5 ratio."""
    from emmi_gym.geometry.grid import GridGeometry
    from emmi_gym.navigation.candidates import LOOP_RATIO, revisit_targets
    from emmi_gym.navigation.planner import travel_costs

    geometry = GridGeometry(0.1, 0.0, 0.0, 140, 100)     # 10 m x 14 m, unknown
    em = np.full(geometry.shape, 0.5)
    em[10:30, 10:90] = 0.1                               # the corridors driven, known free: y = 2 (x 2..8) ...
    em[10:130, 70:90] = 0.1                              # ... x = 8 (y 2..12) ...
    em[110:130, 10:90] = 0.1                             # ... and y = 12 (x 8..2)
    path = np.array([(x, 2.0, 0.0) for x in np.arange(2.0, 8.0, 0.5)]
                    + [(8.0, y, 0.0) for y in np.arange(2.0, 12.0, 0.5)]
                    + [(x, 12.0, 0.0) for x in np.arange(8.0, 1.9, -0.5)])
    costs = travel_costs(em, geometry, path[-1, :2], 0.2)
    route = costs.route_lengths(path[:1, :2])[0]
    walked = np.array([tuple(path[-1, :2])] + costs.path_to(*path[0, :2], spacing=0.1))
    assert route == pytest.approx(np.hypot(*np.diff(walked, axis=0).T).sum(), abs=0.15)
    assert 9.8 < route < 10.6 and costs.cost_to(*path[0, :2]) > 22.0 / LOOP_RATIO
    start = [t for t in revisit_targets(path, costs) if np.hypot(t.x - 2.0, t.y - 2.0) < 1.0]
    assert start and 1.0 - 1.0 / start[0].gain >= 1.0 - 1.0 / LOOP_RATIO


def test_planning_covers_the_explored_part_of_a_large_map_with_the_same_costs(monkeypatch):
    """A room of 6 m x 4 m explored in a 60 m x 40 m map: the costs are computed over the room plus
    PLANNING_MARGIN, and equal those over the whole map (paths, route lengths, frontiers)."""
    from emmi_gym.geometry.grid import GridGeometry
    from emmi_gym.navigation import planner
    from emmi_gym.navigation.candidates import frontier_targets

    geometry = GridGeometry(0.1, 0.0, 0.0, 400, 600)
    em = np.full(geometry.shape, 0.5)
    em[200:240, 300:360] = 0.1                           # the room, known free, open to the east at x = 36 m
    em[199, 300:361] = em[240, 300:361] = em[199:241, 299] = 0.9
    em[200:215, 360] = em[225:241, 360] = 0.9            # a doorway at y = 21.5..22.5 m
    windowed = planner.travel_costs(em, geometry, (31.0, 21.0), 0.2)
    rows, cols = windowed.cumulative.shape
    margin = round(planner.PLANNING_MARGIN / geometry.resolution)
    assert (rows, cols) == (42 + 2 * margin, 62 + 2 * margin)
    monkeypatch.setattr(planner, "PLANNING_MARGIN", 100.0)  # the window is then the whole map
    whole = planner.travel_costs(em, geometry, (31.0, 21.0), 0.2)
    assert whole.cumulative.shape == geometry.shape
    inside = whole.cumulative[windowed.window]
    assert np.array_equal(np.isfinite(inside), np.isfinite(windowed.cumulative))
    assert np.allclose(inside[np.isfinite(inside)], windowed.cumulative[np.isfinite(windowed.cumulative)])
    for x, y in [(35.5, 23.5), (36.5, 22.0), (30.6, 20.6)]:
        assert windowed.cost_to(x, y) == pytest.approx(whole.cost_to(x, y))
        assert windowed.path_to(x, y) == whole.path_to(x, y)
    assert windowed.cost_to(5.0, 5.0) == np.inf and np.isfinite(whole.cost_to(5.0, 5.0))  # far off: not planned
    assert windowed.route_lengths(np.array([[35.5, 23.5]])) == pytest.approx(whole.route_lengths(
        np.array([[35.5, 23.5]])))
    assert frontier_targets(em, windowed) == frontier_targets(em, whole)
    assert len(frontier_targets(em, windowed)) == 1


def test_a_wall_seen_at_glancing_angles_hides_no_frontier_behind_it():
    """A corridor whose side walls the laser only grazed: a broken line of cells just above 0.5 among
    cells just below it (values as on the real buildings' expected maps), unknown space behind. The
    only frontier is the corridor's open end; the wall lines used to give a row of frontier targets
    that vanished as the robot drove near."""
    from emmi_gym.geometry.grid import GridGeometry
    from emmi_gym.navigation.candidates import frontier_targets
    from emmi_gym.navigation.planner import travel_costs

    geometry = GridGeometry(0.1, 0.0, 0.0, 60, 100)      # 10 m x 6 m, unknown
    em = np.full(geometry.shape, 0.5)
    em[20:41, 0:80] = 0.1                                # the corridor y = 2..4 m, known free up to x = 8 m
    grazed = np.resize([0.53, 0.46, 0.45, 0.46, 0.44, 0.46], 80)
    em[19, 0:80] = em[41, 0:80] = grazed                 # its walls, barely seen
    costs = travel_costs(em, geometry, (1.0, 3.0), 0.2)
    targets = frontier_targets(em, costs)
    assert len(targets) == 1
    assert targets[0].x == pytest.approx(7.95, abs=0.11) and 2.2 < targets[0].y < 3.8


def test_coverage_counts_what_the_scans_swept_not_how_the_map_lines_up():
    """With poor odometry the estimated map ends turned and shifted against the floor plan (ATE about
    0.4 m on this seed). Read on that map, coverage stayed below the target and the scripted A (close
    the loop, then the new area) drove on to the decision limit; read on the oracle map (the same scans
    at the true poses) the episode ends once the building is explored."""
    from emmi_gym import certainty
    from emmi_gym.tools.policies import make_policy

    env = gym.make("emmi_gym/LoopCorridor-v1")
    policy = make_policy("close_loop_first")
    policy.reset(1)
    env.reset(seed=1)
    decisions, done = 0, False
    while not done:
        _, _, terminated, truncated, info = env.step(policy(env))
        decisions, done = decisions + 1, terminated or truncated
    core = env.unwrapped
    reachable = core.truth.reachable
    assert terminated and info["coverage"] >= 0.9 and decisions < core.config.max_decisions
    oracle, estimated = core.oracle_map, core.expected_map
    swept = certainty.observed_cells(oracle) & (oracle < 0.5)
    assert info["coverage"] == pytest.approx(np.count_nonzero(swept & reachable) / np.count_nonzero(reachable))
    on_the_map = certainty.observed_cells(estimated) & (estimated < 0.5)
    assert np.count_nonzero(on_the_map & reachable) / np.count_nonzero(reachable) < 0.9  # the old reading
    assert info["ate"] > 0.2


def test_loop_closing_target_is_reached_without_pushing_into_walls():
    """From the decision point the start lies behind a corner the map has barely seen: the first plan
    cuts through unknown space, and only replanning on the way keeps the robot off the walls."""
    env = gym.make("emmi_gym/LoopCorridor-v1")  # 15 particles: with 5 the start is not always offered
    env.reset(seed=1)
    core = env.unwrapped
    start = core.world.place("target_a")
    slot = next(k for k, t in enumerate(core.targets) if t is not None and np.hypot(t.x - start.x, t.y - start.y) < 1)
    _, _, _, _, info = env.step(slot)
    assert np.hypot(*(core.estimated_pose[:2] - start.xy)) < 0.5
    assert info["collisions"] <= 5 and core.action_type.blocked == []


# ------------------------------------------------------------------ bounded work on bad input


def test_an_undrivable_route_ends_reset_with_an_error_not_a_hang():
    import dataclasses

    env = gym.make("emmi_gym/LoopCorridor-v1", **SMALL).unwrapped
    world = env._worlds.fixed
    # a route the loader would refuse (it ends inside the outer wall), given to the env directly
    env._worlds.fixed = dataclasses.replace(world, routes={"to_decision": [world.start.xy, (world.start.x, -5.0)]})
    with pytest.raises(RuntimeError, match=r"route 'to_decision' \(6\.0 m\) was not driven within 900 simulator steps; "
                                           r"the robot is stuck at"):
        env.reset(seed=0)


def test_obstruction_checks_look_only_as_far_as_the_laser():
    from emmi_gym.geometry.grid import GridGeometry
    from emmi_gym.navigation.planner import path_obstructed

    geometry = GridGeometry(0.1, 0.0, 0.0, 20, 200)
    expected = np.full(geometry.shape, 0.2)
    expected[:, 150] = 0.9  # a wall across the corridor, 15 m ahead
    path = [(0.5, 1.0), (19.5, 1.0), (19.5, 1e6)]  # running off 1000 km, as a lost pose estimate can
    assert path_obstructed(expected, geometry, path, 0.2)
    assert not path_obstructed(expected, geometry, path, 0.2, horizon=8.0)
    assert path_obstructed(expected, geometry, path, 0.2, skip=8.0, horizon=8.0)


def test_maps_beyond_the_memory_bound_are_refused_with_what_they_would_take():
    from emmi_gym.concurrency.threads import kernel_threads, set_kernel_threads
    from emmi_gym.slam.occupancy import MapTooLarge

    threads = kernel_threads()
    try:
        set_kernel_threads(1)  # each insertion thread adds its own working memory
        with pytest.raises(MapTooLarge, match=r"1700 x 3500 cells .* for 1000 particles would take 33.4 GiB, above "
                                              r"the bound of 4 GiB"):
            gym.make("emmi_gym/LoopCorridor-v1", particles=1000, resolution=0.01)
    finally:
        set_kernel_threads(threads)


def test_a_generated_world_whose_planning_would_pass_the_bound_is_refused_before_its_grids():
    """Counted with a replan over the whole world (the filter's maps alone fit): refused at reset, naming what
    it would take, before any grid is allocated (it used to fail inside the planner's search)."""
    import tracemalloc

    from emmi_gym.slam.occupancy import MapTooLarge

    env = gym.make("emmi_gym/LoopOrder-v1", particles=55,
                   generator={"loop_width": 200, "loop_height": 200, "new_area_length": 200})
    tracemalloc.start()
    try:
        with pytest.raises(MapTooLarge, match=r"would take 4\.\d GiB in an environment with 55 particles \(\d+ bytes "
                                              r"per cell: the filter's maps, the oracle's map, the observation, "
                                              r"planning\), above the bound of 4 GiB"):
            env.reset(seed=0)
        # refused before the grids (the particles' maps alone would take over 2 GiB); what was taken is the
        # world's own checks (its routes against its walls: 151 MB)
        assert tracemalloc.get_traced_memory()[1] < 512 * 2**20
    finally:
        tracemalloc.stop()
        env.close()


def test_map_accuracy_is_defined_when_nothing_is_known_to_both():
    from emmi_gym.scoring.scores import map_accuracy

    assert map_accuracy(np.full((4, 4), 0.5), np.ones((4, 4), dtype=np.int8)) == 0.0
    env = gym.make("emmi_gym/ExploreVelocity-v0", **SMALL, laser={"max_range": 0.3}, info_scores="always").unwrapped
    _, info = env.reset(seed=1)
    assert np.isfinite(info["map_accuracy"])
