"""The model a run starts from, checked against the run's configuration before anything is written: a new
run's ``--init-from`` (rl-baselines3-zoo's ``--trained-agent``) and a resumed run's own checkpoint. Its
algorithm and policy class (the policy it was saved with), its network (``policy_kwargs``), its env id
(from the ``config.yaml`` written beside it, where there is one: a warning where there is none), its
observation and action spaces (against the configuration's env), its weights (all finite), and the
decisions left to train (its own count towards ``total_timesteps``)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

from .config import AgentConfig, algorithm_class, env_of_file, policy_argument, sb3_policy_kwargs
from .model_files import check_model_file, load_model_file
from .run_folder import RunError, run_config_path


@dataclass(frozen=True)
class WarmStart:
    """A model checked by :func:`check_init_from`: its ``path`` and the ``decisions`` it holds."""

    path: Path
    decisions: int


def check_model_fits(path, config: AgentConfig, what: str) -> int:
    """The decisions the model at ``path`` holds, once checked to be one a run of ``config`` can go on from: its
    algorithm, policy class, network and spaces ``config``'s, its weights finite;
    :class:`~emmi_gym.training.model_files.ModelFileError` naming the file if it does not load or is not finite,
    :class:`~emmi_gym.training.run_folder.RunError` starting with ``what`` (the option and the file) if it does
    not match."""
    import gymnasium as gym

    import emmi_gym  # noqa: F401  (registers the ids)

    model = load_model_file(path, config.algorithm, device="cpu")
    policy = policy_argument(config.policy)
    wanted = policy if isinstance(policy, type) else algorithm_class(config.algorithm).policy_aliases[policy]
    if type(model.policy) is not wanted:
        raise RunError(f"{what}: a model of the policy {type(model.policy).__name__}, but {config.source} names "
                       f"policy {config.policy} ({wanted.__name__}): give a model of that policy, or a "
                       "configuration of the model's")
    network = config.hyperparameters.get("policy_kwargs")
    network = sb3_policy_kwargs(network) if network else {}
    # the keys the configuration gives, and net_arch always (the algorithms add keys of their own: A2C its
    # optimizer, SAC use_sde)
    saved = {key: model.policy_kwargs.get(key) for key in {*network, "net_arch"}}
    if saved != {key: network.get(key) for key in saved}:
        raise RunError(f"{what}: the model's network is policy_kwargs {model.policy_kwargs}, but {config.source} "
                       f"gives {network}: give a model of that network, or a configuration of the model's")
    env = gym.make(config.env_id, **config.env_kwargs)
    try:
        spaces = {
            "observation": (model.observation_space, env.observation_space),
            "action": (model.action_space, env.action_space),
        }
    finally:
        env.close()
    for name, (saved, expected) in spaces.items():
        if saved != expected:
            raise RunError(f"{what}: the model's {name} space is {saved}, but the env of {config.source} "
                           f"({config.env_id} with its env.kwargs) has {expected}")
    return int(model.num_timesteps)


def check_init_from(path, config: AgentConfig, allow_no_training: bool = False) -> WarmStart:
    """``path`` checked to be a model a new run of ``config`` can start from (see the module docstring):
    :class:`~emmi_gym.training.model_files.ModelFileError` naming the file if it is not one that loads or
    its weights are not finite, :class:`~emmi_gym.training.run_folder.RunError` naming the model and the
    configuration if they do not match, or if no decision would train (unless ``allow_no_training``); a
    warning if no ``config.yaml`` beside it says which env it was trained on."""
    path = check_model_file(path, config.algorithm)  # the file first: what is missing or damaged, not a warning
    own_config = run_config_path(path)
    if own_config is None:
        warnings.warn(f"--init-from {path}: no config.yaml beside it or in its run folder says which env it was "
                      f"trained on; its spaces are checked against {config.env_id}'s, its env id cannot be",
                      stacklevel=2)
    else:
        env_id = env_of_file(own_config)[0]
        if env_id != config.env_id:
            raise RunError(
                f"--init-from {path}: a model of {env_id} (its configuration {own_config}), but "
                f"{config.source} trains on {config.env_id}: start from a model of {config.env_id}, or "
                f"train with a configuration of {env_id}"
            )
    decisions = check_model_fits(path, config, f"--init-from {path}")
    if decisions >= config.total_timesteps and not allow_no_training:
        raise RunError(
            f"--init-from {path}: the model holds {decisions} decisions and {config.source} trains to "
            f"total_timesteps {config.total_timesteps} (its decisions count towards them): no decision "
            f"would train. Give a larger budget (--timesteps above {decisions}), or pass "
            "--allow-no-training to copy the model into a new run as it is"
        )
    return WarmStart(path, decisions)
