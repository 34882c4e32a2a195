"""The model a new run starts from (``--init-from``, rl-baselines3-zoo's ``--trained-agent``), checked
against the run's configuration before anything is written: its algorithm (the policy it was saved
with), its env id (from the ``config.yaml`` written beside it, where there is one), its observation
and action spaces (against the configuration's env), its weights (all finite), and the decisions
left to train (its own count towards ``total_timesteps``)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from .callbacks import first_non_finite
from .config import AgentConfig, env_of_file
from .model_files import ModelFileError, load_model_file
from .run_folder import RunError, run_config_path


@dataclass(frozen=True)
class WarmStart:
    """A model checked by :func:`check_init_from`: its ``path`` and the ``decisions`` it holds."""

    path: Path
    decisions: int


def check_init_from(path, config: AgentConfig, allow_no_training: bool = False) -> WarmStart:
    """``path`` checked to be a model a run of ``config`` can start from (see the module docstring):
    :class:`~emmi_gym.training.model_files.ModelFileError` naming the file if it is not one that loads or
    its weights are not finite, :class:`~emmi_gym.training.run_folder.RunError` naming the model and the
    configuration if they do not match, or if no decision would train (unless ``allow_no_training``)."""
    import gymnasium as gym

    import emmi_gym  # noqa: F401  (registers the ids)

    path = Path(path)
    model = load_model_file(path, config.algorithm, device="cpu")
    bad = first_non_finite(model.policy)
    if bad is not None:
        raise ModelFileError(str(path), "", f"a model whose weights are all finite; {bad}")
    own_config = run_config_path(path)
    if own_config is not None:
        env_id = env_of_file(own_config)[0]
        if env_id != config.env_id:
            raise RunError(
                f"--init-from {path}: a model of {env_id} (its configuration {own_config}), but "
                f"{config.source} trains on {config.env_id}: start from a model of {config.env_id}, or "
                f"train with a configuration of {env_id}"
            )
    env = gym.make(config.env_id, **config.env_kwargs)
    try:
        spaces = {
            "observation": (model.observation_space, env.observation_space),
            "action": (model.action_space, env.action_space),
        }
    finally:
        env.close()
    for name, (saved, wanted) in spaces.items():
        if saved != wanted:
            raise RunError(
                f"--init-from {path}: the model's {name} space is {saved}, but the env of "
                f"{config.source} ({config.env_id} with its env.kwargs) has {wanted}"
            )
    decisions = int(model.num_timesteps)
    if decisions >= config.total_timesteps and not allow_no_training:
        raise RunError(
            f"--init-from {path}: the model holds {decisions} decisions and {config.source} trains to "
            f"total_timesteps {config.total_timesteps} (its decisions count towards them): no decision "
            f"would train. Give a larger budget (--timesteps above {decisions}), or pass "
            "--allow-no-training to copy the model into a new run as it is"
        )
    return WarmStart(path, decisions)
