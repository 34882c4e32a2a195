"""``emmi-gym evaluate``: a trained model on held-out episodes, beside the scripted policies if asked
(:mod:`emmi_gym.tools.training.evaluate`, which plays it as :mod:`emmi_gym.tools.evaluation.comparison` plays every
policy and makes its tables)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ...env.seeds import HELD_OUT_SEED
from . import arguments


def add_parser(subparsers) -> None:
    ev = subparsers.add_parser("evaluate", help="run a trained model on held-out episodes: return and "
                                                "ground-truth metrics, beside the scripted baselines on the same "
                                                "episodes if asked", epilog=arguments.MODEL_FILES_RUN_CODE)
    ev.add_argument("model", nargs="?", default=None,
                    help="model .zip written by 'emmi-gym train' (config.yaml beside it), or --pretrained")
    ev.add_argument("--pretrained", default=None, metavar="NAME", help="a trained agent shipped with the package")
    ev.add_argument("--name", type=arguments.label, default=None,
                    help="the name the model's rows carry (default: 'agent', or the shipped agent's name)")
    ev.add_argument("--episodes", type=arguments.EPISODES, default=10,
                    help="episodes to play (default 10; on a map set, its first maps, one episode each, or "
                         "--seeds-per-plan each)")
    ev.add_argument("--seed", type=arguments.SEED, default=HELD_OUT_SEED,
                    help=f"first episode's seed (default {HELD_OUT_SEED}: the held-out seeds)")
    arguments.add_seeds_per_plan(ev)
    ev.add_argument("--world", default=None,
                    help="a world, map set, folder or glob to play on (a set's first maps, one episode each; "
                         "default: the run's evaluation env)")
    ev.add_argument("--baselines", nargs="*", default=[], metavar="POLICY",
                    help="scripted policies or shipped agents played on the same episodes, paired with the model "
                         "(final maps, and at equal robot time), with 95%% intervals (e.g. frontier "
                         "active_loop_closing explore_plans_emmi)")
    arguments.add_workers(ev)
    ev.add_argument("--out", default=None, metavar="DIR",
                    help="with --world, --baselines or --seeds-per-plan: write episodes.csv, traces.csv (the scores "
                         "after every decision), summary.md, front.png (map quality against robot time) and maps.png "
                         "(one episode's maps, where the model went back) here")
    arguments.add_quiet(ev)
    ev.add_argument("--video", default=None, metavar="DIR", help="record every episode (gymnasium RecordVideo)")
    arguments.add_torch_threads(ev, "1: the env's kernels need the cores")
    arguments.add_trust_model(ev, "the model")
    ev.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ...inputs.user_paths import output_folder
    from ..evaluation.comparison import format_table
    from ..evaluation.episodes import summarise
    from ..training.evaluate import evaluate_model
    from ..training.run_folders import RunFolder
    from ..training.train import set_torch_threads

    set_torch_threads(args.torch_threads)
    if args.video is not None:
        output_folder(args.video, "--video")
    model, name = _model_to_evaluate(args)
    arguments.trust_models(args, [model])
    config = RunFolder.config_of_model(model)  # loaded once: checking it makes the env
    if args.world is not None or args.baselines or args.seeds_per_plan > 1:
        return _evaluate_beside_baselines(args, model, name, config)
    print(f"evaluating on {config.env_id} ({config.eval_env_kwargs}), episodes seeded from {args.seed}")
    rows = evaluate_model(model, args.episodes, args.seed, args.video, config=config)
    print(format_table(rows))
    print("\nmean over episodes:")
    print(format_table([summarise(rows)]))
    if args.video:
        print(f"videos in {args.video}")
    return 0


def _model_to_evaluate(args: argparse.Namespace) -> tuple[Path, str]:
    """The model file that ``evaluate`` plays, and the name its rows carry."""
    if (args.model is None) == (args.pretrained is None):
        raise ValueError("give a model .zip or --pretrained NAME (one of them)")
    if args.pretrained is not None:
        from .. import pretrained

        return pretrained.model_path(args.pretrained), args.name or args.pretrained
    if not Path(args.model).is_file():
        raise FileNotFoundError(f"no model at {args.model}")
    return Path(args.model), args.name or "agent"


def _evaluate_beside_baselines(args: argparse.Namespace, model: Path, name: str, config) -> int:
    from ...inputs.user_paths import output_folder
    from ..evaluation.comparison import evaluation_tables, format_table, policy_means, write_evaluation
    from ..evaluation.robot_time import without_traces
    from ..training.evaluate import OWN_WORLD, TrainedAgent, compare_model, run_episodes

    if args.video:
        raise ValueError("--video records the model alone: leave out --world, --baselines and --seeds-per-plan")
    if name in args.baselines:
        raise ValueError(f"--baselines: {name} is the model evaluated; its rows could not be told apart")
    baselines = arguments.baseline_policies(args.baselines)
    for baseline in baselines:
        if not isinstance(baseline, str):
            baseline.check_plays_in(config, "--baselines")
    world = OWN_WORLD if args.world is None else args.world
    try:
        settings, _ = run_episodes(config, world, args.episodes, args.seed, args.seeds_per_plan)
    except ValueError as error:
        raise ValueError(f"--seeds-per-plan: {error}") from None
    out = None if args.out is None else output_folder(args.out)
    per_plan = f" x {args.seeds_per_plan} seeds each" if args.seeds_per_plan > 1 else ""
    print(f"evaluating {name} on {config.env_id} ({config.eval_env_kwargs}"
          f"{'' if args.world is None else f', world {args.world}'}) beside {args.baselines or 'no baseline'}: "
          f"{args.episodes} episodes{per_plan}, seeds from {args.seed}")
    rows = compare_model(model, name, world, args.episodes, args.seed, baselines, workers=args.workers,
                         progress=not args.quiet, seeds_per_plan=args.seeds_per_plan)
    means = policy_means(without_traces(rows))
    print(format_table(means))
    tables = evaluation_tables(rows, name, args.baselines)
    for table in tables:
        print("\n" + table)
    if out is not None:
        files = write_evaluation(rows, means, tables, TrainedAgent(str(model), name), baselines, settings, out)
        print(f"\nwrote {', '.join(str(p) for p in files)}")
    return 0
