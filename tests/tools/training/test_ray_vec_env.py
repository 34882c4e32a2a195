"""Training envs as Ray actors: the same episodes as subprocesses for the same seeds."""

import time

import numpy as np
import pytest
from helpers import assert_same, start_local_ray

from emmi_gym.tools.training.config import parse_agent_config
from emmi_gym.tools.training.train import make_vec_env, train

pytestmark = pytest.mark.slow  # each test starts a local Ray instance (module fixture) and trains or steps in actors

ray = pytest.importorskip("ray")

#: A small generated world whose 40-step episodes end inside the test, so automatic resets are compared too.
FAST_ENV = {"particles": 3, "generator": {"nx": 2, "ny": 2, "n_loops": 1}, "max_sim_steps": 40}


def agent_config(**extra) -> dict:
    return {"env": {"id": "emmi_gym/ExploreVelocity-v0", "kwargs": FAST_ENV}, "algorithm": "PPO",
            "policy": "MultiInputPolicy",
            "hyperparameters": {"policy_kwargs": {"net_arch": [16]}, "n_steps": 16, "batch_size": 16, "n_epochs": 1},
            "n_envs": 2, "vec_env": "ray", "total_timesteps": 32, "seed": 3,
            "eval": {"freq": 1000, "episodes": 1, "seed": 500}, "checkpoint_freq": 1000, **extra}


@pytest.fixture(scope="module")
def local_ray():
    start_local_ray()
    yield
    ray.shutdown()


def play(vec_env: str, steps: int = 90) -> list:
    """Everything the trainer sees from two seeded envs under fixed actions: observations, rewards, ends,
    the terminal observations of automatic resets, and an attribute read through the workers."""
    env = make_vec_env(parse_agent_config(agent_config(vec_env=vec_env)), 2, seed=11, vec_env=vec_env)
    actions = np.random.default_rng(0).uniform(-1, 1, (steps, 2, 2)).astype(np.float32)
    seen = [env.reset(), env.get_attr("decisions")]
    for action in actions:
        observation, reward, done, infos = env.step(action)
        seen += [observation, reward, done, [info.get("terminal_observation") for info in infos]]
    env.close()
    return seen


def test_ray_actors_give_the_same_episodes_as_subprocesses(local_ray):
    on_ray, in_subprocesses = play("ray"), play("subproc")
    assert sum(bool(np.any(step)) for step in on_ray[4::4]) >= 2  # episodes ended and were reset on the way
    assert_same(on_ray, in_subprocesses)


def test_training_with_ray_actors_saves_a_model_and_closes_them(local_ray, tmp_path):
    result = train(parse_agent_config(agent_config()), tmp_path, progress=False)
    assert result.model_path.exists() and result.timesteps >= 32
    assert cpus_free_within(10.0) == 2  # every actor ended, its CPU given back


def cpus_free_within(seconds: float) -> float:
    """The local instance's free CPUs once they are all free again, or after ``seconds``."""
    deadline = time.monotonic() + seconds
    while ray.available_resources().get("CPU", 0) < 2 and time.monotonic() < deadline:
        time.sleep(0.2)
    return ray.available_resources().get("CPU", 0)


def test_a_failing_env_raises_in_the_trainer_instead_of_hanging(local_ray):
    env = make_vec_env(parse_agent_config(agent_config()), 2, seed=11, vec_env="ray")
    env.reset()
    with pytest.raises(Exception, match="action"):
        env.step(np.full((2, 5), np.nan, dtype=np.float32))  # a wrong action shape, refused in the worker
    env.close()
