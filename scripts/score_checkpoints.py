"""Score every checkpoint of training runs on the same held-out episodes, in parallel: the learning
curve of a run trained with ``eval.freq: 0``, or one on more episodes than its periodic evaluation.

    python scripts/score_checkpoints.py runs/ppo_plans_emmi_16envs_seed3 --world dungeon_maps/train \\
        --seed 400000 --episodes 16 --workers 16
    python scripts/plot_learning_curves.py runs/ppo_plans_emmi_16envs_seed3 --scores checkpoint_scores.csv \\
        --out curve.png

Writes, in each run folder, ``checkpoint_scores.csv`` (a row per checkpoint: ``timesteps``, then the
mean of each ground-truth measure over the episodes, as ``eval_ground_truth.csv``) and
``checkpoint_episodes.csv`` (every episode), and prints the curve.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from emmi_gym.experiments.report import write_csv
from emmi_gym.training.checkpoint_scores import score_checkpoints
from emmi_gym.training.evaluate import EVALUATION_SEED, OWN_WORLD, format_table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="run folders of 'emmi-gym train'")
    parser.add_argument("--world", default=None, help="world, map set, folder or glob (default: the run's own)")
    parser.add_argument("--episodes", type=int, default=16)
    parser.add_argument("--seed", type=int, default=EVALUATION_SEED, help="first episode seed")
    parser.add_argument("--workers", type=int, default=None, help="worker processes (default one per core)")
    args = parser.parse_args()
    for run in args.runs:
        curve, rows = score_checkpoints(run, OWN_WORLD if args.world is None else args.world, args.episodes,
                                        args.seed, workers=args.workers)
        write_csv(run / "checkpoint_scores.csv", curve)
        write_csv(run / "checkpoint_episodes.csv", rows)
        print(f"{run}: {len(curve)} checkpoints x {args.episodes} episodes\n{format_table(curve)}\n", flush=True)


if __name__ == "__main__":
    main()
