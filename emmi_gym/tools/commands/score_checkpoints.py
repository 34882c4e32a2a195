"""``emmi-gym score-checkpoints``: every checkpoint of training runs on the same held-out episodes, in
parallel (:mod:`emmi_gym.tools.training.checkpoint_scores`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ...env.seeds import HELD_OUT_SEED
from . import arguments


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "score-checkpoints", help="score every checkpoint of training runs on the same held-out episodes, in "
                                  "parallel: the learning curve of a run trained with eval.freq: 0",
        description="Writes checkpoint_scores.csv (a row per checkpoint: the mean of each ground-truth measure) "
                    "and checkpoint_episodes.csv (every episode) into each run folder.",
        epilog=arguments.MODEL_FILES_RUN_CODE)
    parser.add_argument("runs", nargs="+", type=Path, help="run folders of 'emmi-gym train'")
    parser.add_argument("--world", default=None, help="world, map set, folder or glob (default: the run's own)")
    parser.add_argument("--episodes", type=arguments.EPISODES, default=16, help="episodes per checkpoint (default 16)")
    parser.add_argument("--seed", type=arguments.SEED, default=HELD_OUT_SEED,
                        help=f"first episode seed (default {HELD_OUT_SEED}: held out, as 'emmi-gym evaluate'; to "
                             "choose a checkpoint, score it on seeds below that, e.g. 400000)")
    arguments.add_workers(parser)
    arguments.add_quiet(parser)
    arguments.add_trust_model(parser, "the runs' checkpoints")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..evaluation.comparison import format_table
    from ..training.checkpoint_scores import CURVE_FILE, EPISODES_FILE, score_runs
    from ..training.evaluate import OWN_WORLD

    def report(run_dir, curve) -> None:
        print(f"{run_dir}: {len(curve)} checkpoints x {args.episodes} episodes: wrote {run_dir / CURVE_FILE} and "
              f"{run_dir / EPISODES_FILE}\n{format_table(curve)}\n", flush=True)

    arguments.trust_models(args, args.runs)
    score_runs(args.runs, OWN_WORLD if args.world is None else args.world, args.episodes, args.seed,
               workers=args.workers, progress=not args.quiet, report=report)
    return 0
