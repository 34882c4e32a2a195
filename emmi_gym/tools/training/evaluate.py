"""Evaluating a trained model: episodes on held-out seeds, a table of return and every ground-truth
metric, and optionally a video of each episode (gymnasium's ``RecordVideo``)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from ...env.seeds import HELD_OUT_SEED
from ..evaluation.directions import better_side, format_number
from ..evaluation.episodes import ModelActor, info_options, play_episodes
from .run_folders import RunFolder
from .run_folders.model_files import load_model_file
from .train import make_agent_env

#: ``world`` of :func:`compare_model` that means the run's evaluation env's own world.
OWN_WORLD = object()
#: Evaluation episodes are seeded from here on by default: the held-out seeds (:mod:`emmi_gym.env.seeds`).
EVALUATION_SEED = HELD_OUT_SEED


@dataclass(frozen=True)
class TrainedAgent:
    """A trained model to compare beside the scripted policies
    (:func:`emmi_gym.tools.evaluation.comparison.compare_on`): the ``.zip`` that ``emmi-gym train`` wrote
    (its ``config.yaml`` beside it) and the name its rows carry."""

    path: str
    name: str = "agent"

    def make_actor(self) -> ModelActor:
        return ModelActor(_model_in_this_process(self.path))

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

    from ..evaluation.comparison import ComparisonSettings

    options = dict(config.eval_env_kwargs)
    own_world = options.pop("world", gym.spec(config.env_id).kwargs.get("world"))
    return ComparisonSettings(config.env_id, options), own_world


def compare_model(model_path, name: str = "agent", world=OWN_WORLD, episodes: int = 10, seed: int = EVALUATION_SEED,
                  baselines=(), *, workers: int | None = None, progress: bool = True) -> list[dict]:
    """The model and the ``baselines`` (scripted policies' names, :class:`TrainedAgent` s) on the same
    ``episodes`` (world, seed) pairs, paired, in its run's evaluation env
    (:func:`emmi_gym.tools.evaluation.comparison.compare_on`): ``world`` a world, map set, folder or glob
    (default: the evaluation env's own world), its maps or seeds taken as
    :func:`~emmi_gym.tools.evaluation.comparison.episodes_on` says. Rows carry ``name`` for the model, and
    each episode's ``trace`` (for the comparison at equal robot time)."""
    from ..evaluation.comparison import compare_on, episodes_on

    settings, own_world = comparison_settings(RunFolder.config_of_model(model_path))
    pairs = episodes_on(own_world if world is OWN_WORLD else world, episodes, seed)
    return compare_on(pairs, [TrainedAgent(str(model_path), name), *baselines], settings, workers=workers,
                      progress=progress, keep_trace=True, start_method="spawn")  # torch and fork do not mix


def write_figures(rows: list[dict], model_path, name: str, baselines, out) -> list[Path]:
    """``front.png`` (map quality against robot time, a point per policy) and, beside a baseline,
    ``maps.png``: the episode where the model's accuracy against the oracle map differs most from the
    first baseline's (among those where it went back, if any), both maps with where it went back."""
    from ..evaluation.comparison import play_on_world, plot_front, plot_pair, policy_name

    out = Path(out)
    plot_front(rows, out / "front.png")
    written = [out / "front.png"]
    if baselines:
        mine = {(r["world"], r["seed"]): r for r in rows if r["policy"] == name}
        theirs = {(r["world"], r["seed"]): r for r in rows if r["policy"] == policy_name(baselines[0])}
        gaps = {key: mine[key]["oracle_accuracy"] - theirs[key]["oracle_accuracy"] for key in mine.keys() & theirs}
        went_back = [key for key in gaps if mine[key].get("revisit_share", 0) > 0] or list(gaps)
        world, seed = max(sorted(went_back), key=lambda key: abs(gaps[key]))
        settings, _ = comparison_settings(RunFolder.config_of_model(model_path))
        world = None if world == "None" else world  # rows name a generated world "None"
        episodes = [play_on_world(world, seed, policy, settings, keep_maps=True, keep_steps=True)
                    for policy in (TrainedAgent(str(model_path), name), baselines[0])]
        plot_pair(episodes, out / "maps.png")
        written.append(out / "maps.png")
    return written


def format_table(rows: list[dict], columns=None) -> str:
    """A fixed-width text table of episode rows, numbers as every summary writes them (counts without
    decimals, NaN as '-'), and a line naming which side of each measure shown is better."""
    columns = columns or list(rows[0])

    def text(value, column: str) -> str:
        return format_number(value, column) if isinstance(value, float) else str(value)

    cells = [[text(row.get(c, float("nan")), c) for c in columns] for row in rows]
    widths = [max(len(c), 9, *(len(line[k]) for line in cells)) for k, c in enumerate(columns)]
    lines = [" ".join(c.rjust(w) for c, w in zip(columns, widths, strict=False))]
    lines += [" ".join(t.rjust(w) for t, w in zip(line, widths, strict=False)) for line in cells]
    sides = {side: [c for c in columns if better_side(c) == side] for side in ("higher", "lower")}
    if any(sides.values()):
        lines.append("better: " + "; ".join(f"{side} {', '.join(names)}" for side, names in sides.items() if names))
    return "\n".join(lines)
