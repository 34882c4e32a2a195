"""A trained model in the evaluation: :class:`TrainedAgent`, the policy that plays it beside the scripted ones, and a
run's held-out evaluation: its env and episodes (:func:`run_episodes`), the model alone there with a video of each
episode if asked (:func:`evaluate_model`), or beside other policies (:func:`compare_model`). The episodes are played
and scored by :mod:`emmi_gym.tools.evaluation.comparison`, as every other policy's."""

from __future__ import annotations

import hashlib
import warnings
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from ..._moved import moved_names
from ...env.seeds import HELD_OUT_SEED
from ..evaluation import comparison
from ..evaluation.comparison import EpisodesOn, compare_on, episodes_on
from ..evaluation.episodes import ModelActor, info_options, play_episodes
from .run_folders import RunFolder
from .run_folders.model_files import load_model_file
from .train import make_agent_env

#: ``world`` of :func:`compare_model` that means the run's evaluation env's own world.
OWN_WORLD = object()
#: Evaluation episodes are seeded from here on by default: the held-out seeds (:mod:`emmi_gym.env.seeds`).
EVALUATION_SEED = HELD_OUT_SEED
#: The names that moved to :mod:`emmi_gym.tools.evaluation.comparison` (deprecated here).
__getattr__ = moved_names(__name__, comparison, ("format_table",), "0.5.0")


@dataclass(frozen=True)
class TrainedAgent:
    """A trained model to compare beside the scripted policies
    (:func:`emmi_gym.tools.evaluation.comparison.compare_on`): the ``.zip`` that ``emmi-gym train`` wrote
    (its ``config.yaml`` beside it) and the name its rows carry."""

    path: str
    name: str = "agent"

    def make_actor(self) -> ModelActor:
        return ModelActor(_model_in_this_process(self.path))

    def identity(self) -> dict:
        """What it plays, for :mod:`~emmi_gym.tools.evaluation.played_episodes`: the SHA-256 of its model file (a
        model trained on, or another file at the same path, is another policy)."""
        return {"model_sha256": hashlib.sha256(Path(self.path).read_bytes()).hexdigest()}

    def check_plays_in(self, config, what: str) -> None:
        """A ``ValueError`` starting with ``what`` (the option) unless the model was trained on ``config``'s env
        id and its spaces are those of ``config``'s evaluation env, where it is to play."""
        model, own = load_model(self.path)
        if own.env_id != config.env_id:
            raise ValueError(f"{what}: {self.name} ({self.path}) is an agent of {own.env_id}, but {config.source} "
                             f"evaluates on {config.env_id}")
        env = make_agent_env(config.env_id, config.eval_env_kwargs)
        try:
            for name, saved, expected in (("observation", model.observation_space, env.observation_space),
                                          ("action", model.action_space, env.action_space)):
                if saved != expected:
                    raise ValueError(f"{what}: {self.name}'s {name} space is {saved}, but the evaluation env of "
                                     f"{config.source} has {expected}")
        finally:
            env.close()


@lru_cache(maxsize=4)
def _model_in_this_process(path: str):
    """A model loaded once per (worker) process, acting on one torch thread."""
    import torch

    torch.set_num_threads(1)
    return load_model(path)[0]


def evaluate_model(model_path, episodes: int = 10, seed: int = EVALUATION_SEED, video_dir=None,
                   config=None, keep_trace: bool = False) -> list[dict]:
    """Run ``episodes`` episodes of the model in the held-out evaluation's environment of its run's
    configuration (the training env with ``eval.env_kwargs``; ``config``: that configuration, if the
    caller has loaded it already); with ``keep_trace``, each row's ``trace``
    (:func:`~emmi_gym.tools.evaluation.episodes.play_episode`)."""
    model_path = Path(model_path)
    model, config = load_model(model_path, config)
    env = make_agent_env(config.env_id, {**config.eval_env_kwargs, **info_options(keep_trace=keep_trace)},
                         render_mode="rgb_array" if video_dir else None)
    if video_dir is not None:
        from gymnasium.wrappers import RecordVideo

        env = RecordVideo(env, str(video_dir), episode_trigger=lambda _: True, name_prefix=model_path.stem,
                          disable_logger=True)
    try:
        return play_episodes(env, ModelActor(model), range(seed, seed + episodes), keep_trace=keep_trace)
    finally:
        env.close()


def load_model(model_path, config=None):
    """The SB3 model of a ``.zip`` written by ``emmi-gym train``, on the CPU, as the algorithm of its run's
    configuration, and that configuration (``config``: given if the caller has loaded it already)."""
    model_path = Path(model_path)
    if not model_path.is_file():
        raise FileNotFoundError(f"no model at {model_path}")
    config = config or RunFolder.config_of_model(model_path)
    return load_model_file(model_path, config.algorithm, device="cpu"), config


def comparison_settings(config):
    """The env of a run's held-out evaluations as :class:`~emmi_gym.tools.evaluation.comparison.ComparisonSettings`
    (every keyword but the world, set per episode), and that env's own world."""
    import gymnasium as gym

    options = dict(config.eval_env_kwargs)
    own_world = options.pop("world", gym.spec(config.env_id).kwargs.get("world"))
    return comparison.ComparisonSettings(config.env_id, options), own_world


def run_episodes(config, world=OWN_WORLD, episodes: int = 10, seed: int = EVALUATION_SEED,
                 seeds_per_plan: int = 1) -> tuple[comparison.ComparisonSettings, EpisodesOn]:
    """The settings and the episodes of an evaluation in the held-out evaluation env of a run's ``config``
    (:func:`comparison_settings`): :func:`~emmi_gym.tools.evaluation.comparison.episodes_on` ``(world, episodes,
    seed, seeds_per_plan)``, ``world`` a world, map set, folder or glob (default: the evaluation env's own world).
    On a map set, its first ``episodes`` plans, each with ``seeds_per_plan`` seeds."""
    settings, own_world = comparison_settings(config)
    return settings, episodes_on(own_world if world is OWN_WORLD else world, episodes, seed, seeds_per_plan)


def compare_model(model_path, name: str = "agent", world=OWN_WORLD, episodes: int = 10, seed: int = EVALUATION_SEED,
                  baselines=(), *, workers: int | None = None, progress: bool = True,
                  seeds_per_plan: int = 1) -> list[dict]:
    """The model and the ``baselines`` (scripted policies' names, :class:`TrainedAgent` s) on the same episodes of
    :func:`run_episodes` in its run's evaluation env, paired
    (:func:`emmi_gym.tools.evaluation.comparison.compare_on`). Rows carry ``name`` for the model, and each
    episode's ``trace`` (for the comparison at equal robot time)."""
    settings, pairs = run_episodes(RunFolder.config_of_model(model_path), world, episodes, seed, seeds_per_plan)
    return compare_on(pairs, [TrainedAgent(str(model_path), name), *baselines], settings, workers=workers,
                      progress=progress, keep_trace=True, start_method="spawn")  # torch and fork do not mix


def write_figures(rows: list[dict], model_path, name: str, baselines, out) -> list[Path]:
    """Deprecated (goes in 0.5.0): :func:`emmi_gym.tools.evaluation.comparison.write_figures` of the model's
    :class:`TrainedAgent` in its run's evaluation env."""
    warnings.warn("emmi_gym.tools.training.evaluate.write_figures is now "
                  "emmi_gym.tools.evaluation.comparison.write_figures(rows, policy, baselines, settings, out); the "
                  "old name goes in emmi-gym 0.5.0", FutureWarning, stacklevel=2)
    settings, _ = comparison_settings(RunFolder.config_of_model(model_path))
    return comparison.write_figures(rows, TrainedAgent(str(model_path), name), baselines, settings, out)
