"""Training an agent from its configuration: vectorised envs, TensorBoard, SB3's progress bar,
periodic held-out evaluation with the ground-truth metrics, checkpoints, resuming, Ctrl-C safety.

A run folder holds ``config.yaml`` (the resolved configuration), ``model.zip`` (the final
model), ``checkpoints/`` (``model_<steps>_steps.zip``, with the replay buffer for off-policy
algorithms), ``eval/`` (SB3's ``evaluations.npz`` and the best model),
``eval_ground_truth.csv`` (the ground-truth means of every evaluation) and ``tb/``
(TensorBoard logs).
"""

from __future__ import annotations

import copy
import re
import time
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import gymnasium as gym
import yaml

from .callbacks import eval_callback_class
from .config import AgentConfig, algorithm_class, load_agent_config, policy_argument
from .loop_order import LoopOrderInfo
from .semi_markov import SemiMarkovDiscounts, rollout_buffer_class

_CHECKPOINT = re.compile(r"model_(\d+)_steps\.zip$")
OFF_POLICY = ("DQN", "SAC")


@dataclass(frozen=True)
class TrainResult:
    run_dir: Path
    model_path: Path
    timesteps: int
    wall_seconds: float
    interrupted: bool = False


def make_env(env_id: str, kwargs: dict, render_mode: str | None = None) -> gym.Env:
    """``gym.make`` of an emmi_gym id, wrapped to report the episode's loop order (:class:`LoopOrderInfo`);
    importable by reference, so spawned workers can build it."""
    import emmi_gym  # noqa: F401  (registers the ids in a fresh worker process)

    return LoopOrderInfo(gym.make(env_id, render_mode=render_mode, **kwargs))


def make_vec_env(config: AgentConfig, n_envs: int, seed: int, vec_env: str):
    """SB3 vectorised envs (Monitor-wrapped): subprocesses when asked and there is more than one env."""
    from stable_baselines3.common.env_util import make_vec_env as sb3_make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    cls = SubprocVecEnv if vec_env == "subproc" and n_envs > 1 else DummyVecEnv
    return sb3_make_vec_env(partial(make_env, config.env_id, config.env_kwargs), n_envs=n_envs, seed=seed,
                            vec_env_cls=cls)


def latest_checkpoint(run_dir: Path) -> Path | None:
    """The checkpoint of a run folder with the most steps, if any."""
    found = [(int(m.group(1)), p) for p in (run_dir / "checkpoints").glob("model_*_steps.zip")
             if (m := _CHECKPOINT.search(p.name))]
    return max(found)[1] if found else None


def load_run_config(model_path) -> AgentConfig:
    """The configuration written beside a model (in its folder or the run folder above a checkpoint)."""
    model_path = Path(model_path)
    for folder in (model_path.parent, model_path.parent.parent):
        if (folder / "config.yaml").is_file():
            return load_agent_config(folder / "config.yaml")
    raise FileNotFoundError(f"no config.yaml beside {model_path} or in its run folder: was it written by "
                            f"'emmi-gym train'?")


def train(config: AgentConfig, run_dir, *, resume: bool = False, progress: bool = True,
          verbose: int = 0) -> TrainResult:
    """Train ``config`` into ``run_dir`` (see the module docstring); with ``resume``, continue from the
    folder's latest checkpoint up to ``config.total_timesteps``."""
    from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback

    run_dir = Path(run_dir)
    checkpoints = run_dir / "checkpoints"
    start = latest_checkpoint(run_dir) if resume else None
    if resume and start is None:
        raise FileNotFoundError(f"--resume: no checkpoint in {checkpoints}")
    if not resume and (run_dir / "model.zip").exists():
        raise FileExistsError(f"{run_dir} already holds a trained model: use --resume or another --out")
    run_dir.mkdir(parents=True, exist_ok=True)
    with open(run_dir / "config.yaml", "w") as f:
        yaml.safe_dump(config.as_yaml_dict(), f, sort_keys=False)

    env = make_vec_env(config, config.n_envs, config.seed, config.vec_env)
    eval_env = make_vec_env(config, 1, config.eval.seed, "dummy")
    cls = algorithm_class(config.algorithm)
    if start is not None:
        model = cls.load(start, env=env, tensorboard_log=str(run_dir / "tb"))
        buffer = start.with_name(start.name.replace("model_", "model_replay_buffer_").replace(".zip", ".pkl"))
        if config.algorithm in OFF_POLICY and buffer.exists():
            model.load_replay_buffer(buffer)
    else:
        hyperparameters = copy.deepcopy(config.hyperparameters)  # SB3 adds to policy_kwargs in place
        if config.discount_unit is not None:
            hyperparameters["rollout_buffer_class"] = rollout_buffer_class(
                config.algorithm, isinstance(env.observation_space, gym.spaces.Dict))
        model = cls(policy_argument(config.policy), env, seed=config.seed, tensorboard_log=str(run_dir / "tb"),
                    verbose=verbose, **hyperparameters)
    per_env = max(1, config.n_envs)
    evaluation = eval_callback_class(config.algorithm)(
        eval_env, eval_freq=max(config.eval.freq // per_env, 1), n_eval_episodes=config.eval.episodes,
        log_path=str(run_dir / "eval"), best_model_save_path=str(run_dir / "eval"), deterministic=True,
        verbose=verbose, eval_seed=config.eval.seed, ground_truth_csv=run_dir / "eval_ground_truth.csv")
    checkpointing = CheckpointCallback(max(config.checkpoint_freq // per_env, 1), str(checkpoints), name_prefix="model",
                                       save_replay_buffer=config.algorithm in OFF_POLICY)
    callbacks = [checkpointing, evaluation]
    if config.discount_unit is not None:
        callbacks.append(SemiMarkovDiscounts(config.discount_unit))
    remaining = max(config.total_timesteps - model.num_timesteps, 0)
    started = time.perf_counter()
    interrupted = False
    try:
        model.learn(remaining, callback=CallbackList(callbacks), progress_bar=progress,
                    reset_num_timesteps=start is None, tb_log_name="run")
        model_path = run_dir / "model.zip"
        model.save(model_path)
    except KeyboardInterrupt:  # Ctrl-C: keep what was learnt, as a checkpoint --resume continues from
        interrupted = True
        model_path = checkpoints / f"model_{model.num_timesteps}_steps.zip"
        checkpoints.mkdir(parents=True, exist_ok=True)
        model.save(model_path)
        if config.algorithm in OFF_POLICY:
            model.save_replay_buffer(checkpoints / f"model_replay_buffer_{model.num_timesteps}_steps.pkl")
    finally:
        env.close()
        eval_env.close()
    return TrainResult(run_dir, model_path, int(model.num_timesteps), time.perf_counter() - started, interrupted)
