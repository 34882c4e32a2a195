"""Rollout workers: the buffer the learner fills from their fragments is the one SB3 collects for the same
actions; processes, a local Ray instance and a two-node Ray cluster give the same rollouts for the same
seeds; training with them saves, resumes, starts from another model and stops on Ctrl-C as before. They
stand on SB3's public names only, which a test here checks are still there."""

import ast
import copy
import inspect
import textwrap
from collections import deque
from types import SimpleNamespace

import numpy as np
import pytest
import torch as th
import yaml
from helpers import ray_temp_dir, start_local_ray
from stable_baselines3.common.callbacks import BaseCallback

from emmi_gym.concurrency.parallel import ActorFailed
from emmi_gym.concurrency.ray_cluster import LOCAL_SYSTEM_CONFIG
from emmi_gym.tools.training.config import AgentConfigError, parse_agent_config
from emmi_gym.tools.training.evaluate import evaluate_model
from emmi_gym.tools.training.rollout_workers import RolloutWorkers, record_episodes
from emmi_gym.tools.training.run_folders import RunFolder
from emmi_gym.tools.training.semi_markov import SemiMarkovDiscounts
from emmi_gym.tools.training.train import make_vec_env, model_of, train

#: A waypoint agent with masks and semi-Markov discounts, whose 3-decision episodes end within a rollout.
MASKED = {"env": {"id": "emmi_gym/LoopCorridor-v1", "kwargs": {"particles": 3, "max_decisions": 3}},
          "algorithm": "MaskablePPO", "discount_unit": 100,
          "hyperparameters": {"n_steps": 6, "batch_size": 6, "n_epochs": 1, "policy_kwargs": {"net_arch": [16]}}}
#: A velocity agent (Box actions, clipped for the env) whose 40-step episodes are truncated within a rollout.
VELOCITY = {"env": {"id": "emmi_gym/ExploreVelocity-v0",
                    "kwargs": {"particles": 3, "generator": {"nx": 2, "ny": 2, "n_loops": 1}, "max_sim_steps": 40}},
            "algorithm": "PPO", "hyperparameters": {"n_steps": 24, "batch_size": 24, "n_epochs": 1,
                                                    "policy_kwargs": {"net_arch": [16]}}}
FIELDS = ("observations", "actions", "rewards", "episode_starts", "values", "log_probs", "advantages", "returns",
          "action_masks", "discounts")


def agent(base: dict, **extra) -> dict:
    return {**base, "policy": "MultiInputPolicy", "n_envs": 2, "total_timesteps": 10**6, "seed": 7,
            "eval": {"freq": 0}, "checkpoint_freq": 10**6, **extra}


class Buffers(BaseCallback):
    """A copy of the rollout buffer's entries at the end of each rollout (before the update reads it)."""

    def __init__(self):
        super().__init__()
        self.rollouts = []

    def _on_rollout_end(self) -> None:
        buffer = self.model.rollout_buffer
        entries = {}
        for name in FIELDS:
            value = getattr(buffer, name, None)
            if value is not None:
                entries[name] = copy.deepcopy(value)
        # the episodes SB3's logs read (return and length; "t" is the wall-clock time)
        entries["episodes"] = np.array([(info["r"], info["l"]) for info in self.model.ep_info_buffer])
        self.rollouts.append(entries)

    def _on_step(self) -> bool:
        return True


class BuffersAndWeights(Buffers):
    """:class:`Buffers`, and a copy of the learner's weights at the start of each rollout."""

    def __init__(self):
        super().__init__()
        self.weights = []

    def _on_rollout_start(self) -> None:
        self.weights.append(copy.deepcopy(self.model.policy.state_dict()))


def collect(data: dict, vec_env: str, rollouts: int, *, ray_address=None, model_hook=None, buffers=None):
    """The buffers of ``rollouts`` rollouts (with an update after each) of a model of ``data`` on ``vec_env``
    (kept by ``buffers``, a :class:`Buffers`), and its initial weights."""
    config = parse_agent_config(data)
    env = make_vec_env(config, config.n_envs, config.seed, vec_env, ray_address=ray_address)
    try:
        model = model_of(config, env)
        initial = copy.deepcopy(model.policy.state_dict())
        if model_hook is not None:
            model_hook(model)
        buffers = Buffers() if buffers is None else buffers
        callbacks = [buffers] + ([SemiMarkovDiscounts(config.discount_unit)] if config.discount_unit else [])
        model.learn(rollouts * model.n_steps * config.n_envs, callback=callbacks)
    finally:
        env.close()
    return initial, buffers.rollouts


def replaying(initial: dict, rollouts: list):
    """A hook that gives a model ``initial`` weights and makes its policy act as recorded in ``rollouts``: the
    recorded actions, their log-probability and the value, as SB3's forward pass returns them."""
    actions = iter(step for rollout in rollouts for step in rollout["actions"])

    def hook(model):
        policy = model.policy
        policy.load_state_dict(initial)

        def forward(obs, deterministic=False, **masks):
            taken = th.as_tensor(next(actions)).reshape(-1, *model.action_space.shape)
            return taken, policy.predict_values(obs), policy.get_distribution(obs, **masks).log_prob(taken)

        policy.forward = forward

    return hook


@pytest.mark.slow
@pytest.mark.parametrize("base", [MASKED, VELOCITY], ids=["MaskablePPO, masks, semi-Markov", "PPO, Box actions"])
def test_the_learner_fills_the_buffer_sb3_collects_for_the_same_actions(base):
    initial, from_workers = collect(agent(base), "workers", 2)
    _, from_sb3 = collect(agent(base), "dummy", 2, model_hook=replaying(initial, from_workers))
    ends = sum(int(rollout["episode_starts"][1:].sum()) for rollout in from_workers)
    assert ends >= 2  # episodes ended and were reset within the rollouts (a truncation bootstrapped)
    for ours, sb3 in zip(from_workers, from_sb3, strict=True):
        assert set(ours) == set(sb3)
        for name in ("observations", "actions", "episode_starts", "action_masks", "episodes"):
            if name in ours:
                np.testing.assert_array_equal(_arrays(ours[name]), _arrays(sb3[name]), err_msg=name)
        for name in ("rewards", "values", "log_probs", "advantages", "returns", "discounts"):
            if name in ours:
                np.testing.assert_allclose(ours[name], sb3[name], rtol=1e-5, atol=1e-6, err_msg=name)


def _arrays(value):
    return np.concatenate([v.ravel() for v in value.values()]) if isinstance(value, dict) else value


def same_rollouts(a: list, b: list) -> None:
    for first, second in zip(a, b, strict=True):
        for name in first:
            np.testing.assert_array_equal(_arrays(first[name]), _arrays(second[name]), err_msg=name)


@pytest.fixture
def ray():
    ray = pytest.importorskip("ray")
    yield ray
    ray.shutdown()


@pytest.fixture
def ray_files(monkeypatch):
    """Ray's files (``RAY_TMPDIR``) in a folder of the test's own, not the machine's ``/tmp/ray``."""
    with ray_temp_dir() as temp:
        monkeypatch.setenv("RAY_TMPDIR", str(temp))
        yield temp


@pytest.mark.slow
@pytest.mark.parametrize("policy_lag", [0, 1])
def test_processes_and_a_local_ray_instance_give_the_same_rollouts(ray, policy_lag):
    start_local_ray()
    data = agent(MASKED, policy_lag=policy_lag)
    same_rollouts(collect(data, "workers", 3)[1], collect(data, "ray_workers", 3)[1])


@pytest.mark.slow
def test_a_two_node_ray_cluster_gives_the_same_rollouts_as_processes(ray, ray_files):
    """Two nodes of one CPU each, as Ray's own tests make a cluster on one machine: the two workers (one CPU
    each) can only run one on each node. The cluster's files (the address file ``ray.init()`` would join among
    them) go to a folder of its own, not the machine's ``/tmp/ray``."""
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False,
                                                            "_system_config": dict(LOCAL_SYSTEM_CONFIG)})
    try:
        cluster.add_node(num_cpus=1)
        ray.init(address=cluster.address, logging_level="ERROR", log_to_driver=False)
        busy = []

        def cpus_in_use(model):
            model.env.get_attr("decisions")  # both workers answer: both started
            busy.append(ray.cluster_resources()["CPU"] - ray.available_resources().get("CPU", 0.0))

        on_cluster = collect(agent(MASKED), "ray_workers", 2, ray_address=cluster.address, model_hook=cpus_in_use)[1]
        assert len([node for node in ray.nodes() if node["Alive"]]) == 2 and busy == [2.0]  # a worker on each
        same_rollouts(collect(agent(MASKED), "workers", 2)[1], on_cluster)
    finally:
        ray.shutdown()
        cluster.shutdown()


@pytest.mark.slow
def test_a_worker_that_stops_is_an_error_naming_it_not_a_hang():
    config = parse_agent_config(agent(VELOCITY))
    workers = make_vec_env(config, 2, 0, "workers")
    try:
        assert isinstance(workers, RolloutWorkers) and len(workers.reset()["pose"]) == 2
        workers.workers[1].process.kill()
        with pytest.raises(ActorFailed, match="rollout worker 1: the process has stopped"):
            workers.get_attr("decisions")
    finally:
        workers.close()


@pytest.mark.slow
def test_training_with_workers_stops_on_ctrl_c_resumes_and_starts_from_another_model(tmp_path, monkeypatch):
    from sb3_contrib import MaskablePPO
    from test_training import interrupt_training_at

    data = agent(MASKED, total_timesteps=36, checkpoint_freq=12)
    run_on = interrupt_training_at(monkeypatch, 24)
    stopped = train(parse_agent_config(data), tmp_path / "run", progress=False)
    assert stopped.interrupted and stopped.model_path == RunFolder(tmp_path / "run").latest_checkpoint()
    run_on()
    finished = train(parse_agent_config(data), tmp_path / "run", resume=True, progress=False)
    assert finished.timesteps >= 36 and type(MaskablePPO.load(finished.model_path)) is MaskablePPO
    assert yaml.safe_load((tmp_path / "run" / "training.yaml").read_text())["timesteps"] == finished.timesteps
    more = train(parse_agent_config(dict(data, total_timesteps=48)), tmp_path / "more", progress=False,
                 init_from=finished.model_path)
    assert more.timesteps >= 48 and len(evaluate_model(more.model_path, episodes=1)) == 1


@pytest.mark.slow
def test_with_a_policy_lag_each_rollout_is_played_with_the_weights_one_update_before():
    """policy_lag 1: the workers play the next fragments while the learner updates, so the first two rollouts
    are played with the initial weights and the third with the weights after the first update; the buffer
    holds the acting policy's log-probabilities (what PPO's ratio divides by). The first rollout is the one
    played without a lag, and the same seeds give the same rollouts."""
    models = []
    lagged = BuffersAndWeights()
    initial, rollouts = collect(agent(MASKED, policy_lag=1), "workers", 3, model_hook=models.append,
                                buffers=lagged)
    same_rollouts(rollouts[:1], collect(agent(MASKED), "workers", 1)[1])
    same_rollouts(rollouts, collect(agent(MASKED, policy_lag=1), "workers", 3)[1])
    policy = models[0].policy
    learner = lagged.weights  # the learner's weights at each rollout's start: initial, after 1 update, after 2

    def log_probs(weights, rollout):
        policy.load_state_dict(weights)
        obs = {key: th.as_tensor(value.reshape(-1, *value.shape[2:])) for key, value in rollout["observations"].items()}
        masks = rollout["action_masks"].reshape(len(rollout["actions"].reshape(-1)), -1)
        with th.no_grad():
            _, log_prob, _ = policy.evaluate_actions(obs, th.as_tensor(rollout["actions"].reshape(-1)),
                                                     action_masks=masks)
        return log_prob.numpy().reshape(rollout["log_probs"].shape)

    acted_with = [initial, initial, learner[1]]
    for rollout, weights in zip(rollouts, acted_with, strict=True):
        np.testing.assert_allclose(rollout["log_probs"], log_probs(weights, rollout), rtol=1e-5, atol=1e-6)
    assert not np.allclose(rollouts[2]["log_probs"], log_probs(learner[2], rollouts[2]), rtol=1e-5, atol=1e-6)


def test_a_policy_lag_without_rollout_workers_is_a_clear_error():
    with pytest.raises(AgentConfigError, match="policy_lag") as error:
        parse_agent_config({**agent(MASKED), "vec_env": "subproc", "policy_lag": 1}, source="agent.yaml")
    assert error.value.field == "policy_lag"


@pytest.mark.parametrize("change, expected", [
    ({}, "workers"),
    ({"algorithm": "DQN", "hyperparameters": {}, "discount_unit": None}, "subproc"),
])
def test_on_policy_algorithms_use_rollout_workers_by_default(change, expected):
    assert parse_agent_config({**agent(MASKED), **change}).vec_env == expected


def test_rollout_workers_for_an_off_policy_algorithm_are_a_clear_error():
    with pytest.raises(AgentConfigError, match="rollout workers collect for") as error:
        parse_agent_config({**agent(MASKED), "algorithm": "DQN", "hyperparameters": {}, "discount_unit": None,
                            "vec_env": "workers"},
                           source="agent.yaml")
    assert error.value.field == "vec_env"


def parameters(function) -> list[str]:
    return list(inspect.signature(function).parameters)


def test_the_names_the_workers_use_of_sb3_are_still_there():
    """What the workers' ``collect_rollouts`` calls and reads of SB3 and sb3-contrib, all public: a release that
    renames or reshapes one fails here, in the quick lane, not in the middle of a training run."""
    from sb3_contrib import MaskablePPO
    from sb3_contrib.common.maskable.buffers import MaskableDictRolloutBuffer, MaskableRolloutBuffer
    from sb3_contrib.common.maskable.utils import get_action_masks
    from stable_baselines3.common.base_class import BaseAlgorithm
    from stable_baselines3.common.buffers import DictRolloutBuffer, RolloutBuffer
    from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
    from stable_baselines3.common.policies import ActorCriticPolicy
    from stable_baselines3.common.vec_env import VecEnv

    overridden = ["self", "env", "callback", "rollout_buffer", "n_rollout_steps"]
    assert parameters(OnPolicyAlgorithm.collect_rollouts) == overridden
    assert parameters(MaskablePPO.collect_rollouts) == [*overridden, "use_masking"]
    for buffer in (RolloutBuffer, DictRolloutBuffer):
        assert parameters(buffer.add) == ["self", "obs", "action", "reward", "episode_start", "value", "log_prob"]
        assert parameters(buffer.compute_returns_and_advantage) == ["self", "last_values", "dones"]
    for buffer in (MaskableRolloutBuffer, MaskableDictRolloutBuffer):
        assert "action_masks" in parameters(buffer.add)
    assert parameters(get_action_masks) == ["env"]
    assert parameters(BaseCallback.update_locals) == ["self", "locals_"]
    assert all(callable(getattr(BaseCallback, name)) for name in ("on_rollout_start", "on_step", "on_rollout_end"))
    assert all(callable(getattr(ActorCriticPolicy, name)) for name in
               ("forward", "set_training_mode", "reset_noise", "obs_to_tensor", "predict_values", "unscale_action"))
    assert isinstance(ActorCriticPolicy.squash_output, property)
    assert parameters(VecEnv.seed) == ["self", "seed"]
    assigned = {node.attr for cls in (BaseAlgorithm, OnPolicyAlgorithm) for node in ast.walk(ast.parse(
        textwrap.dedent(inspect.getsource(cls)))) if isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store)
        and isinstance(node.value, ast.Name) and node.value.id == "self"}
    read = {"policy", "num_timesteps", "gamma", "use_sde", "sde_sample_freq", "action_space", "device",
            "ep_info_buffer", "ep_success_buffer"}
    assert read <= assigned, sorted(read - assigned)


def test_ended_episodes_go_to_the_buffers_sb3_keeps_them_in():
    """:func:`record_episodes` keeps what SB3's own loop keeps of a step's infos for its logs (SB3 does it in a
    private method, called here to compare): each ``Monitor`` record, and ``is_success`` at an episode's end."""
    from stable_baselines3.common.base_class import BaseAlgorithm

    steps = [([{"episode": {"r": 1.5, "l": 3, "t": 0.1}, "is_success": True}, {"is_success": False}], [True, False]),
             ([{}, {"episode": {"r": -2.0, "l": 4, "t": 0.2}, "is_success": False}], [False, True]),
             ([{"is_success": True}, {}], [False, False])]
    kept = []
    for record in (record_episodes, BaseAlgorithm._update_info_buffer):
        model = SimpleNamespace(ep_info_buffer=deque(maxlen=100), ep_success_buffer=deque(maxlen=100))
        for infos, dones in steps:
            record(model, infos, np.array(dones))
        kept.append((list(model.ep_info_buffer), list(model.ep_success_buffer)))
    assert kept[0] == kept[1] == ([steps[0][0][0]["episode"], steps[1][0][1]["episode"]], [True, False])
