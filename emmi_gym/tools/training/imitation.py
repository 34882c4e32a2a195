"""Behaviour cloning from a scripted policy: a warm start for reinforcement learning.

:func:`collect_demonstrations` plays a scripted policy of :mod:`emmi_gym.tools.policies` (for instance
``active_loop_closing``), or any policy of :func:`~emmi_gym.tools.evaluation.comparison.compare_on` (an object
with ``make_actor()``: a trained agent, a planner), in an agent configuration's training env and records, at
every decision, the observation, the action masks and the action taken. :func:`clone` fits a model's policy to
them by maximum likelihood: it minimises the negative log-probability of the demonstrated action
under the policy, the masked slots excluded (Pomerleau's behaviour cloning; the same loss as the
``imitation`` library's BC, which passes no action masks). :func:`clone_run` fits a fresh model of
a configuration and saves it as a run that ``emmi-gym train CONFIG --init-from MODEL`` continues
with RL (``emmi-gym clone``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...concurrency.parallel import run_in_processes
from ...formats.atomic_files import write_atomically, write_text_atomically
from .callbacks import NonFiniteError, first_non_finite
from .config import AgentConfig
from .demonstrations import Demonstrations
from .run_folders import RunFolder

#: What ``emmi-gym clone`` writes into its folder (all that ``--overwrite`` removes).
CLONE_FILES = ("model.zip", "config.yaml", "demonstrations.npz", "clone.yaml")


def _demonstration(job) -> tuple[int, Demonstrations]:
    """One episode of ``policy`` in ``gym.make(env_id, **env_kwargs)`` with ``seed``: (seed, its decisions)."""
    import gymnasium as gym

    from ..evaluation.comparison import make_actor

    env_id, env_kwargs, policy, seed = job
    env = gym.make(env_id, **env_kwargs)
    core, actor = env.unwrapped, make_actor(policy)
    actor.reset(seed)
    observation, _ = env.reset(seed=seed)
    observations, masks, actions = [], [], []
    done = False
    while not done:
        masks.append(core.action_masks())
        observations.append(observation)
        actions.append(int(actor(env, observation)))
        observation, _, terminated, truncated, _ = env.step(actions[-1])
        done = terminated or truncated
    env.close()
    return seed, Demonstrations({key: np.stack([o[key] for o in observations]) for key in observations[0]},
                                np.array(masks, dtype=bool), np.array(actions, dtype=np.int64), 1)


def collect_demonstrations(config: AgentConfig, policy, episodes: int, seed: int, *,
                           workers: int | None = None, progress: bool = True) -> Demonstrations:
    """``episodes`` episodes of ``policy`` (a scripted policy's name, or a picklable object with ``make_actor()``
    as :func:`~emmi_gym.tools.evaluation.comparison.compare_on` takes) in ``config``'s training env (its id and
    keywords), seeded ``seed``, ``seed + 1``...; in ``workers`` processes, joined in the order of their seeds.
    Needs a waypoint env (action masks)."""
    check_cloneable(config)
    jobs = ((config.env_id, dict(config.env_kwargs), policy, seed + k) for k in range(episodes))
    spawn = None if isinstance(policy, str) else "spawn"  # a trained agent's torch and fork do not mix
    parts = run_in_processes(_demonstration, jobs, total=episodes, workers=workers, desc="demonstrations",
                             progress=progress, start_method=spawn)
    return Demonstrations.joined([part for _, part in sorted(parts, key=lambda part: part[0])])


def clone(model, demonstrations: Demonstrations, *, epochs: int = 20, batch_size: int = 256,
          learning_rate: float = 1e-3, seed: int = 0) -> list[float]:
    """Fit ``model``'s policy (a MaskablePPO model) to ``demonstrations`` by maximum likelihood: Adam on
    the mean negative log-probability of the demonstrated actions, masked slots excluded, over
    ``epochs`` shuffled passes; the mean loss of each epoch. The critic is left as it is. A non-finite
    loss, gradient or weight stops the fit with :class:`~emmi_gym.tools.training.callbacks.NonFiniteError`
    (before the step that would spread it into the weights)."""
    import torch as th

    policy = model.policy
    policy.set_training_mode(True)
    optimizer = th.optim.Adam(policy.parameters(), lr=learning_rate)
    generator = np.random.default_rng(seed)
    n = len(demonstrations)
    losses = []
    for epoch in range(epochs):
        order, total = generator.permutation(n), 0.0
        for start in range(0, n, batch_size):
            batch = order[start:start + batch_size]
            arrays = {key: value[batch] for key, value in demonstrations.observations.items()}
            rows = non_finite_rows(arrays)
            if rows.size:
                raise NonFiniteError(f"cloning stopped in epoch {epoch + 1}: the observations of the demonstrated "
                                     f"decisions {sorted(batch[rows].tolist())[:8]} are not finite (NaN or infinite)")
            observations, _ = policy.obs_to_tensor(arrays)
            actions = th.as_tensor(demonstrations.actions[batch], device=policy.device)
            _, log_prob, _ = policy.evaluate_actions(observations, actions,
                                                     action_masks=demonstrations.masks[batch])
            loss = -log_prob.mean()
            optimizer.zero_grad()
            loss.backward()
            bad = None if th.isfinite(loss) else f"the loss is {loss.item()}"
            bad = bad or first_non_finite(policy)
            if bad is not None:
                raise NonFiniteError(f"cloning stopped in epoch {epoch + 1}: {bad}, on a batch of {len(batch)} "
                                     "demonstrated decisions (a learning rate too large?); nothing was saved")
            optimizer.step()
            total += loss.item() * len(batch)
        losses.append(total / n)
    policy.set_training_mode(False)
    return losses


def non_finite_rows(arrays: dict[str, np.ndarray]) -> np.ndarray:
    """The rows (decisions) of stacked observation arrays where a float holds NaN or an infinity."""
    rows = np.zeros(len(next(iter(arrays.values()))), dtype=bool)
    for value in arrays.values():
        if value.dtype.kind == "f":
            rows |= ~np.isfinite(value.reshape(len(value), -1)).all(axis=1)
    return np.flatnonzero(rows)


def agreement(model, demonstrations: Demonstrations, batch_size: int = 1024) -> float:
    """The share of demonstrated decisions where ``model``'s deterministic action is the demonstrated one."""
    taken = []
    for start in range(0, len(demonstrations), batch_size):
        part = slice(start, start + batch_size)
        actions, _ = model.predict({key: value[part] for key, value in demonstrations.observations.items()},
                                   deterministic=True, action_masks=demonstrations.masks[part])
        taken.append(np.asarray(actions))
    return float(np.mean(np.concatenate(taken) == demonstrations.actions))


def check_cloneable(config: AgentConfig) -> None:
    """A ``ValueError`` unless ``config`` trains a MaskablePPO agent in a waypoint env: the scripted policies
    choose target slots, and the fit reads the demonstrated masks."""
    import gymnasium as gym

    options = {**gym.spec(config.env_id).kwargs, **config.env_kwargs}
    if options.get("action_mode", "waypoint") != "waypoint":
        raise ValueError(f"{config.env_id} with action_mode {options['action_mode']!r}: the scripted policies "
                         "choose target slots, so demonstrations need a waypoint env")
    if config.algorithm != "MaskablePPO":
        raise ValueError(f"algorithm {config.algorithm}: behaviour cloning fits a MaskablePPO policy (it reads "
                         "the demonstrated action masks)")


def cloned_model(config: AgentConfig, demonstrations: Demonstrations, **fit):
    """A fresh model of ``config`` (its algorithm, policy and hyperparameters) fitted by :func:`clone`; the
    model and the losses per epoch."""
    from .train import make_vec_env, model_of

    check_cloneable(config)
    env = make_vec_env(config, 1, config.seed, "dummy")
    try:
        demonstrations.check_fits(env.observation_space)
        if demonstrations.masks.shape[1] != env.action_space.n:
            raise ValueError(f"the demonstrations have {demonstrations.masks.shape[1]} actions; the "
                             f"configuration's env {env.action_space}")
        model = model_of(config, env)
        return model, clone(model, demonstrations, seed=config.seed, **fit)
    finally:
        env.close()


def clone_run(config: AgentConfig, demonstrations: Demonstrations, run_dir, **fit):
    """Write a run folder that ``emmi-gym train --init-from`` continues (``model.zip``, ``config.yaml``);
    the model's path, the losses per epoch and the model. Nothing is written if the fit fails."""
    folder = RunFolder(run_dir, CLONE_FILES)
    model, losses = cloned_model(config, demonstrations, **fit)
    folder.write_config(config)
    return write_atomically(folder.model_path, model.save), losses, model


def write_clone_record(run_dir, record: dict) -> Path:
    """Write ``clone.yaml`` (what was fitted, the losses, the agreement) into ``run_dir``."""
    import yaml

    return write_text_atomically(Path(run_dir) / "clone.yaml", yaml.safe_dump(record, sort_keys=False))
