"""``emmi-gym learning-curves``: the held-out evaluations' ground truth of training runs against decisions
trained, in one figure (:mod:`emmi_gym.tools.training.learning_curves`)."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "learning-curves", help="draw training runs' learning curves: the held-out evaluations' ground truth "
                                "against decisions trained",
        description="Runs given the same LABEL (the seeds of one configuration) are drawn as their mean, the band "
                    "spanning them; --baselines-csv draws each scripted policy's mean as a level line.")
    parser.add_argument("runs", nargs="+", metavar="RUN_DIR[=LABEL]", help="run folders of 'emmi-gym train'")
    parser.add_argument("--scores", default="eval_ground_truth.csv",
                        help="the file of each run folder to draw (default eval_ground_truth.csv; "
                             "checkpoint_scores.csv: the file of 'emmi-gym score-checkpoints')")
    parser.add_argument("--baselines-csv", type=Path, default=None,
                        help="episodes.csv of 'emmi-gym evaluate --out' or 'emmi-gym compare-policies', or "
                             "benchmark_episodes.csv of 'emmi-gym benchmark'")
    parser.add_argument("--out", type=Path, required=True, help="the figure's file (no suffix: .png)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..training.learning_curves import plot

    print(f"wrote {plot(args.runs, args.out, args.scores, args.baselines_csv)}")
    return 0
