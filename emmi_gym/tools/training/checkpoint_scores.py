"""The learning curve of a training run from its checkpoints: every checkpoint plays the same held-out
episodes, all of them in parallel (:func:`emmi_gym.tools.evaluation.comparison.compare_on`), and each
checkpoint's row is the mean of the episodes' ground-truth measures.

``emmi-gym train``'s periodic evaluation plays one episode at a time in the learner's process, while
the env workers wait; a run trained with ``eval.freq: 0`` gets its curve afterwards, on every core and
on as many episodes as wanted (``emmi-gym score-checkpoints``, :func:`score_runs`)."""

from __future__ import annotations

import math
from pathlib import Path

from ...formats.atomic_files import write_csv
from ...inputs.user_paths import output_folder
from ...inputs.validation import MAX_EPISODES
from ..evaluation.comparison import compare_on
from ..evaluation.episodes import nanmean
from ..evaluation.loop_order import LOOP_ORDER_KEY
from .evaluate import EVALUATION_SEED, OWN_WORLD, TrainedAgent, run_episodes
from .run_folders import RunFolder

#: The measures of a checkpoint's row: the means over its episodes of these columns of the episode rows.
MEASURES = ("return", "oracle_accuracy", "wall_consistency", "ate", "map_accuracy", "coverage", "reached_target",
            "sim_steps_to_target", "revisit_share", LOOP_ORDER_KEY, "sim_steps", "decisions")


def score_checkpoints(run_dir, world=OWN_WORLD, episodes: int = 16, seed: int = EVALUATION_SEED, *,
                      workers: int | None = None, progress: bool = True) -> tuple[list[dict], list[dict]]:
    """``(curve, rows)``: ``curve`` a row per whole checkpoint of ``run_dir`` (``timesteps``, then the
    mean of each of :data:`MEASURES` over the episodes, of the finite values: ``sim_steps_to_target``
    over those that reached the target), fewest decisions first; ``rows`` every episode, its policy
    named ``model_<N>``. The episodes are :func:`~emmi_gym.tools.training.evaluate.run_episodes`
    ``(world, episodes, seed)`` in the run's evaluation env (by default on that env's own world); a
    damaged checkpoint (cut short by a kill) is skipped with a warning."""
    if not 1 <= episodes <= MAX_EPISODES:
        raise ValueError(f"episodes: expected an integer in [1, {MAX_EPISODES}], got {episodes!r}")
    found = RunFolder(run_dir).whole_checkpoints()
    settings, pairs = run_episodes(RunFolder.config_of_model(found[0][1]), world, episodes, seed)
    agents = [TrainedAgent(str(path), f"model_{decisions}") for decisions, path in found]
    rows = compare_on(pairs, agents, settings, workers=workers, progress=progress,
                      start_method="spawn")  # torch and fork do not mix
    curve = []
    for decisions, _ in found:
        mine = [r for r in rows if r["policy"] == f"model_{decisions}"]
        curve.append({"timesteps": decisions, **{k: nanmean([r.get(k, math.nan) for r in mine]) for k in MEASURES}})
    return curve, rows


#: The files :func:`score_runs` writes into each run folder.
CURVE_FILE, EPISODES_FILE = "checkpoint_scores.csv", "checkpoint_episodes.csv"


def score_runs(runs, world=OWN_WORLD, episodes: int = 16, seed: int = EVALUATION_SEED, *,
               workers: int | None = None, progress: bool = True, report=None) -> dict[Path, list[dict]]:
    """Score every run folder of ``runs`` and write, in each, :data:`CURVE_FILE` (a row per checkpoint) and
    :data:`EPISODES_FILE` (every episode), each renamed into place once whole; each run's curve, and
    ``report(run, curve)`` once a run is written. Every folder is checked first (there, with checkpoints,
    writable), before any episode is played."""
    runs = [Path(run) for run in runs]
    for run in runs:
        RunFolder(run).whole_checkpoints()
        output_folder(run, "run folder")
    curves = {}
    for run in runs:
        curve, rows = score_checkpoints(run, world, episodes, seed, workers=workers, progress=progress)
        write_csv(run / CURVE_FILE, curve)
        write_csv(run / EPISODES_FILE, rows)
        curves[run] = curve
        if report is not None:
            report(run, curve)
    return curves

