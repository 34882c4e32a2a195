"""Evaluating a trained model: episodes on held-out seeds, a table of return and every ground-truth
metric, and optionally a video of each episode (gymnasium's ``RecordVideo``)."""

from __future__ import annotations

from pathlib import Path

from .config import algorithm_class
from .episodes import ModelActor, run_episodes
from .train import load_run_config, make_env

#: Evaluation episodes are seeded from here on by default: apart from training (config seeds)
#: and from the periodic evaluation during training (eval.seed).
EVALUATION_SEED = 200_000


def evaluate_model(model_path, episodes: int = 10, seed: int = EVALUATION_SEED, video_dir=None,
                   config=None) -> list[dict]:
    """Run ``episodes`` episodes of the model in the held-out evaluation's environment of its run's
    configuration (the training env with ``eval.env_kwargs``; ``config``: that configuration, if the
    caller has loaded it already)."""
    model_path = Path(model_path)
    if not model_path.is_file():
        raise FileNotFoundError(f"no model at {model_path}")
    config = config or load_run_config(model_path)
    model = algorithm_class(config.algorithm).load(model_path, device="cpu")
    env = make_env(config.env_id, config.eval_env_kwargs, render_mode="rgb_array" if video_dir else None)
    if video_dir is not None:
        from gymnasium.wrappers import RecordVideo

        env = RecordVideo(env, str(video_dir), episode_trigger=lambda _: True, name_prefix=model_path.stem,
                          disable_logger=True)
    try:
        return run_episodes(env, ModelActor(model), range(seed, seed + episodes))
    finally:
        env.close()


def format_table(rows: list[dict], columns=None) -> str:
    """A fixed-width text table of episode rows (NaN shown as '-')."""
    columns = columns or list(rows[0])
    widths = {c: max(len(c), 9) for c in columns}

    def cell(value, c):
        if isinstance(value, float):
            text = "-" if value != value else f"{value:.3f}" if abs(value) < 1000 else f"{value:.0f}"
        else:
            text = str(value)
        return text.rjust(widths[c])

    lines = [" ".join(c.rjust(widths[c]) for c in columns)]
    lines += [" ".join(cell(row.get(c, float("nan")), c) for c in columns) for row in rows]
    return "\n".join(lines)
