"""Evaluating a trained model: episodes on held-out seeds, a table of return and every ground-truth
metric, and optionally a video of each episode (gymnasium's ``RecordVideo``)."""

from __future__ import annotations

from pathlib import Path

from .config import algorithm_class
from .episodes import ModelActor, run_episodes
from .train import load_run_config, make_env

#: ``world`` of :func:`compare_model` that means the run's evaluation env's own world.
OWN_WORLD = object()
#: Evaluation episodes are seeded from here on by default: apart from training (config seeds)
#: and from the periodic evaluation during training (eval.seed).
EVALUATION_SEED = 200_000


def evaluate_model(model_path, episodes: int = 10, seed: int = EVALUATION_SEED, video_dir=None,
                   config=None) -> list[dict]:
    """Run ``episodes`` episodes of the model in the held-out evaluation's environment of its run's
    configuration (the training env with ``eval.env_kwargs``; ``config``: that configuration, if the
    caller has loaded it already)."""
    model_path = Path(model_path)
    model, config = load_model(model_path, config)
    env = make_env(config.env_id, config.eval_env_kwargs, render_mode="rgb_array" if video_dir else None)
    if video_dir is not None:
        from gymnasium.wrappers import RecordVideo

        env = RecordVideo(env, str(video_dir), episode_trigger=lambda _: True, name_prefix=model_path.stem,
                          disable_logger=True)
    try:
        return run_episodes(env, ModelActor(model), range(seed, seed + episodes))
    finally:
        env.close()


def load_model(model_path, config=None):
    """The SB3 model of a ``.zip`` written by ``emmi-gym train``, on the CPU, as the algorithm of its run's
    configuration, and that configuration (``config``: given if the caller has loaded it already)."""
    model_path = Path(model_path)
    if not model_path.is_file():
        raise FileNotFoundError(f"no model at {model_path}")
    config = config or load_run_config(model_path)
    return algorithm_class(config.algorithm).load(model_path, device="cpu"), config


def compare_model(model_path, name: str = "agent", world=OWN_WORLD, episodes: int = 10, seed: int = EVALUATION_SEED,
                  baselines=(), *, workers: int | None = None, progress: bool = True) -> list[dict]:
    """The model and the scripted ``baselines`` on the same ``episodes`` (world, seed) pairs, paired, in its
    run's evaluation env (:func:`emmi_gym.experiments.comparison.compare_on`): ``world`` a world, map
    set, folder or glob (default: the evaluation env's own world), its maps or seeds taken as
    :func:`~emmi_gym.experiments.comparison.episodes_on` says. Rows carry ``name`` for the model."""
    import gymnasium as gym

    from ..experiments.comparison import ComparisonSettings, TrainedAgent, compare_on, episodes_on

    config = load_run_config(Path(model_path))
    options = dict(config.eval_env_kwargs)
    own_world = options.pop("world", gym.spec(config.env_id).kwargs.get("world"))
    pairs = episodes_on(own_world if world is OWN_WORLD else world, episodes, seed)
    policies = [TrainedAgent(str(model_path), name), *baselines]
    return compare_on(pairs, policies, ComparisonSettings(config.env_id, options), workers=workers,
                      progress=progress)


def format_table(rows: list[dict], columns=None) -> str:
    """A fixed-width text table of episode rows (NaN shown as '-')."""
    columns = columns or list(rows[0])

    def text(value) -> str:
        if isinstance(value, float):
            return "-" if value != value else f"{value:.3f}" if abs(value) < 1000 else f"{value:.0f}"
        return str(value)

    cells = [[text(row.get(c, float("nan"))) for c in columns] for row in rows]
    widths = [max(len(c), 9, *(len(line[k]) for line in cells)) for k, c in enumerate(columns)]
    lines = [" ".join(c.rjust(w) for c, w in zip(columns, widths))]
    lines += [" ".join(t.rjust(w) for t, w in zip(line, widths)) for line in cells]
    return "\n".join(lines)
