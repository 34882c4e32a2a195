"""The ``emmi-gym`` command."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from . import __version__
from .commands import ab, compare_policies, learning_curves, metrics, record, replay, score_checkpoints
from .env.seeds import DEMONSTRATION_SEED, HELD_OUT_SEED
from .inputs import arguments
from .inputs.extras import MissingExtraError, missing_extra
from .slam.kernel_cache import first_run_note

DESCRIPTION = ("Active SLAM with a Rao-Blackwellized particle filter and the EMMI reward: run the paper's A/B "
               "experiment, train and evaluate agents, benchmark rewards, record and replay CARMEN logs.")


#: Commands that run none of the numba kernels (no note on their first run).
NO_KERNELS = ("learning-curves",)

_integer, _SEED, _EPISODES = arguments.integer, arguments.SEED, arguments.EPISODES
def _torch_threads_option(parser: argparse.ArgumentParser, default: str) -> None:
    parser.add_argument("--torch-threads", type=_integer(1), default=None, metavar="N",
                        help=f"torch threads of the learner (default {default})")


def _cmd_train(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from .inputs.paths import output_folder
    from .training.config import ROLLOUT_WORKERS, load_agent_config
    from .training.train import set_torch_threads, train, training_torch_threads

    if args.out is not None:
        output_folder(args.out)  # before the configuration's env is made
    config = load_agent_config(args.config)
    if args.timesteps is not None:
        if args.timesteps < 1:
            raise ValueError(f"--timesteps must be at least 1, got {args.timesteps}")
        config = replace(config, total_timesteps=args.timesteps)
    if args.seed is not None:
        config = replace(config, seed=args.seed)
    if args.ray is not None:  # rollout workers as Ray actors; the synchronous vector env's workers for the others
        config = replace(config, vec_env="ray_workers" if config.vec_env in ROLLOUT_WORKERS else "ray")
    set_torch_threads(training_torch_threads(config) if args.torch_threads is None else args.torch_threads)
    out = args.out or output_folder(f"runs/{Path(args.config).stem}_seed{config.seed}")
    print(f"training {config.algorithm} on {config.env_id} ({config.env_kwargs}) for {config.total_timesteps} "
          f"steps with {config.n_envs} env(s), seed {config.seed}, into {out} (TensorBoard: tensorboard --logdir "
          f"{out}/tb)")
    result = train(config, out, resume=args.resume, overwrite=args.overwrite, progress=not args.quiet,
                   ray_address=arguments.ray_address(args), init_from=args.init_from,
                   allow_no_training=args.allow_no_training, report=print)
    if result.interrupted:
        print(f"\ninterrupted at {result.timesteps} steps: saved {result.model_path}; continue with --resume")
        return 130
    print(f"trained {result.timesteps} steps in {result.wall_seconds:.0f} s: wrote {result.model_path} and "
          f"{Path(out) / 'config.yaml'}")
    return 0


def _cmd_clone(args: argparse.Namespace) -> int:
    from .inputs.paths import output_folder
    from .policies import POLICY_NAMES
    from .training.config import load_agent_config
    from .training.imitation import (
        CLONE_FILES,
        Demonstrations,
        agreement,
        check_cloneable,
        clone_run,
        collect_demonstrations,
        write_clone_record,
    )
    from .training.run_folder import check_new_run_folder, clear_run_folder

    if args.policy not in POLICY_NAMES:
        raise ValueError(f"--policy: unknown {args.policy!r}; choose from {list(POLICY_NAMES)}")
    check_new_run_folder(Path(args.out), args.overwrite, resumable=False, inputs={"--demos": args.demos},
                         files=CLONE_FILES)
    out = output_folder(args.out)
    config = load_agent_config(args.config)
    check_cloneable(config)  # before any episode is played
    if args.demos:
        demonstrations = Demonstrations.load(*args.demos)  # checked, then read into one set of arrays
    else:
        demonstrations = collect_demonstrations(config, args.policy, args.episodes, args.seed, workers=args.workers,
                                                progress=not args.quiet)
    if args.overwrite:  # once every input is read
        clear_run_folder(out, CLONE_FILES)
    if not args.demos:
        demonstrations.save(out / "demonstrations.npz")
    print(f"{len(demonstrations)} decisions of {args.policy} in {demonstrations.episodes} episodes")
    model_path, losses, model = clone_run(config, demonstrations, out, epochs=args.epochs)
    record = {"policy": args.policy, "episodes": demonstrations.episodes, "decisions": len(demonstrations),
              "epochs": args.epochs, "losses": [round(loss, 4) for loss in losses],
              "agreement": round(agreement(model, demonstrations), 4)}
    write_clone_record(out, record)
    print(f"loss {losses[0]:.3f} -> {losses[-1]:.3f}; the model takes the demonstrated action at "
          f"{record['agreement']:.1%} of the decisions. Wrote {model_path}; train on with: emmi-gym train "
          f"{args.config} --init-from {model_path}")
    return 0


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from .experiments.episodes import summarise
    from .inputs.paths import output_folder
    from .training.evaluate import evaluate_model, format_table
    from .training.train import load_run_config, set_torch_threads

    set_torch_threads(args.torch_threads)
    if args.video is not None:
        output_folder(args.video, "--video")
    model, name = _model_to_evaluate(args)
    config = load_run_config(model)  # loaded once: checking it makes the env
    if args.world is not None or args.baselines:
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
        from . import pretrained

        return pretrained.model_path(args.pretrained), args.pretrained
    if not Path(args.model).is_file():
        raise FileNotFoundError(f"no model at {args.model}")
    return Path(args.model), "agent"


def _evaluate_beside_baselines(args: argparse.Namespace, model: Path, name: str, config) -> int:
    from .experiments.comparison import markdown_table, policy_means
    from .experiments.report import write_csv
    from .inputs.paths import output_folder, write_text_atomically
    from .policies import POLICY_NAMES
    from .training.evaluate import OWN_WORLD, compare_model, format_table, write_figures

    if args.video:
        raise ValueError("--video records the model alone: leave out --world and --baselines")
    unknown = sorted(set(args.baselines) - set(POLICY_NAMES))
    if unknown:
        raise ValueError(f"--baselines: unknown {unknown}; choose from {list(POLICY_NAMES)}")
    world = OWN_WORLD if args.world is None else args.world
    out = None if args.out is None else output_folder(args.out)
    print(f"evaluating {name} on {config.env_id} ({config.eval_env_kwargs}"
          f"{'' if args.world is None else f', world {args.world}'}) beside {args.baselines or 'no baseline'}: "
          f"{args.episodes} episodes, seeds from {args.seed}")
    rows = compare_model(model, name, world, args.episodes, args.seed, args.baselines, workers=args.workers,
                         progress=not args.quiet)
    means = policy_means(rows)
    print(format_table(means))
    tables = [markdown_table(rows, name, baseline, f"{name} - {baseline}") for baseline in args.baselines]
    for table in tables:
        print("\n" + table)
    if out is not None:
        write_csv(out / "episodes.csv", rows)
        write_text_atomically(out / "summary.md", "\n\n".join([format_table(means), *tables]) + "\n")
        figures = write_figures(rows, model, name, args.baselines, out)
        print(f"\nwrote {', '.join(str(p) for p in [out / 'episodes.csv', out / 'summary.md', *figures])}")
    return 0


def _cmd_benchmark(args: argparse.Namespace) -> int:
    import time

    from .concurrency.ray_cluster import LOCAL
    from .env.config import REWARDS
    from .inputs.paths import output_folder
    from .training.benchmark import run_benchmark, write_benchmark
    from .training.config import load_agent_config

    bad = sorted(set(args.rewards) - set(REWARDS))
    if bad:
        raise ValueError(f"--rewards: unknown {bad}; choose from {list(REWARDS)}")
    output_folder(args.out)
    config = load_agent_config(args.config)
    if args.timesteps is None:
        args.timesteps = config.total_timesteps
    started = time.perf_counter()
    ray_address = None if args.ray is None else arguments.ray_address(args) or LOCAL  # LOCAL: Ray's default too
    results = run_benchmark(config, args.rewards, arguments.seed_range(args), args.timesteps, args.episodes,
                            args.baselines, args.out, workers=args.workers, ray_address=ray_address,
                            progress=not args.quiet, init_from=args.init_from,
                            allow_no_training=args.allow_no_training, eval_seed=args.eval_seed, report=print)
    elapsed = time.perf_counter() - started
    reused = sum(1 for r in results if r["job"].kind == "agent" and not r["trained"])
    header = (f"Reward benchmark: {config.algorithm} on {config.env_id} ({Path(args.config).name}), "
              f"{args.timesteps} training steps per agent"
              f"{f' (from the weights of {args.init_from})' if args.init_from else ''}, "
              f"seeds {args.first_seed}-{args.first_seed + args.seeds - 1} per reward, {args.episodes} held-out "
              f"evaluation episodes each (seeds from {args.eval_seed}); {elapsed / 60:.1f} min wall time "
              f"({'Ray' if args.ray else 'local processes'}"
              f"{f'; {reused} agent(s) trained by an earlier run into this folder' if reused else ''}). "
              f"Mean [95% t-interval]: over agents for trained variants (one agent: its mean), over episodes "
              f"for scripted ones.")
    files = write_benchmark(results, args.out, header)
    print(files["summary"].read_text())
    for path in files.values():
        print(f"wrote {path}")
    return 0


def _add_train_parser(sub) -> None:
    tr = sub.add_parser("train", help="train an SB3 agent from a configuration in agents/")
    tr.add_argument("config", help="agent configuration (.yaml), e.g. agents/ppo_emmi.yaml")
    tr.add_argument("--timesteps", type=_integer(1), default=None, help="override total_timesteps")
    tr.add_argument("--seed", type=_SEED, default=None, help="override seed")
    tr.add_argument("--out", default=None, help="run folder (default runs/<config>_seed<seed>)")
    tr.add_argument("--resume", action="store_true",
                    help="continue the run in --out from its latest checkpoint, with the configuration it started "
                         "with (only the budget, the envs' number and vectorisation, the evaluation and checkpoint "
                         "schedules may change)")
    tr.add_argument("--overwrite", action="store_true",
                    help="start a new run in a folder that holds one, removing the files a run writes there "
                         "(without it a folder that is not empty is refused)")
    tr.add_argument("--init-from", default=None, metavar="MODEL",
                    help="start from this model's weights (same algorithm, env id, spaces and network) and train on "
                         "with this configuration; its decisions count towards the total")
    tr.add_argument("--allow-no-training", action="store_true",
                    help="with --init-from: accept a model that already holds the configuration's total_timesteps "
                         "(copy it into a new run without training)")
    arguments.add_ray(tr, "run the env workers as Ray actors (vec_env: ray_workers, or ray for vec_env subproc "
                          "and dummy)")
    arguments.add_quiet(tr)
    _torch_threads_option(tr, "1 beside rollout workers and env subprocesses; one per core when the envs run "
                              "in this process")
    tr.set_defaults(func=_cmd_train)


def _add_clone_parser(sub) -> None:
    cl = sub.add_parser("clone", help="behaviour cloning: fit a configuration's model to a scripted policy's "
                                      "decisions, a warm start for 'train --init-from'")
    cl.add_argument("config", help="agent configuration (.yaml) of a waypoint env, e.g. agents/ppo_plans_emmi.yaml")
    cl.add_argument("--policy", default="active_loop_closing", help="the scripted policy (default active_loop_closing)")
    cl.add_argument("--episodes", type=_EPISODES, default=64,
                    help="demonstration episodes in the training env (default 64)")
    cl.add_argument("--seed", type=_SEED, default=DEMONSTRATION_SEED,
                    help=f"first demonstration episode's seed (default {DEMONSTRATION_SEED})")
    cl.add_argument("--demos", nargs="+", default=None, metavar="NPZ",
                    help="demonstrations.npz files to fit instead of playing episodes")
    cl.add_argument("--epochs", type=_integer(1), default=20,
                    help="passes over the demonstrations in the maximum-likelihood fit (default 20)")
    arguments.add_workers(cl)
    cl.add_argument("--out", required=True, help="folder for model.zip, config.yaml, demonstrations.npz, clone.yaml")
    cl.add_argument("--overwrite", action="store_true",
                    help="write into a folder that is not empty, replacing an earlier clone's files there")
    arguments.add_quiet(cl)
    cl.set_defaults(func=_cmd_clone)


def _add_evaluate_parser(sub) -> None:
    ev = sub.add_parser("evaluate", help="run a trained model on held-out episodes: return and ground-truth "
                                         "metrics, beside the scripted baselines on the same episodes if asked")
    ev.add_argument("model", nargs="?", default=None,
                    help="model .zip written by 'emmi-gym train' (config.yaml beside it), or --pretrained")
    ev.add_argument("--pretrained", default=None, metavar="NAME", help="a trained agent shipped with the package")
    ev.add_argument("--episodes", type=_EPISODES, default=10,
                    help="episodes to play (default 10; on a map set, its first maps, one episode each)")
    ev.add_argument("--seed", type=_SEED, default=HELD_OUT_SEED,
                    help=f"first episode's seed (default {HELD_OUT_SEED}: the held-out seeds)")
    ev.add_argument("--world", default=None,
                    help="a world, map set, folder or glob to play on (a set's first maps, one episode each; "
                         "default: the run's evaluation env)")
    ev.add_argument("--baselines", nargs="*", default=[], metavar="POLICY",
                    help="scripted policies played on the same episodes, paired with the model, with 95%% "
                         "intervals (e.g. frontier active_loop_closing)")
    arguments.add_workers(ev)
    ev.add_argument("--out", default=None, metavar="DIR",
                    help="with --world or --baselines: write episodes.csv, summary.md, front.png (map quality "
                         "against robot time) and maps.png (one episode's maps, where the model went back) here")
    arguments.add_quiet(ev)
    ev.add_argument("--video", default=None, metavar="DIR", help="record every episode (gymnasium RecordVideo)")
    _torch_threads_option(ev, "1: the env's kernels need the cores")
    ev.set_defaults(func=_cmd_evaluate)


def _add_benchmark_parser(sub) -> None:
    bench = sub.add_parser("benchmark", help="train agents per reward variant and compare them, and the scripted "
                                             "baselines, under the same ground-truth metrics")
    bench.add_argument("--config", default="agents/ppo_emmi.yaml",
                       help="the agent configuration whose reward is varied (default agents/ppo_emmi.yaml)")
    bench.add_argument("--rewards", nargs="+", default=["emmi", "pose_entropy", "joint_entropy", "coverage"],
                       metavar="REWARD", help="reward variants, an agent per seed each (default emmi pose_entropy "
                                              "joint_entropy coverage; see docs/rewards.md)")
    arguments.add_seed_range(bench, 3)
    bench.add_argument("--timesteps", type=_integer(1), default=None,
                       help="training steps per agent (default: the configuration's total_timesteps)")
    bench.add_argument("--episodes", type=_EPISODES, default=10,
                       help="held-out evaluation episodes per agent and per baseline (default 10)")
    bench.add_argument("--eval-seed", type=_SEED, default=HELD_OUT_SEED,
                       help=f"first held-out episode's seed, for the agents and the baselines alike (default "
                            f"{HELD_OUT_SEED}: the held-out seeds)")
    bench.add_argument("--baselines", nargs="*", default=["frontier", "random"], metavar="POLICY",
                       help="scripted policies evaluated on the same episodes (default frontier random; none: "
                            "give the option with no names)")
    bench.add_argument("--init-from", default=None, metavar="MODEL",
                       help="every agent starts from this model's weights (as 'train --init-from'), e.g. a "
                            "clone of a scripted policy from 'emmi-gym clone'")
    bench.add_argument("--allow-no-training", action="store_true",
                       help="with --init-from: accept a model that already holds --timesteps decisions (the agents "
                            "are then that model, evaluated under each reward's env)")
    arguments.add_workers(bench)
    arguments.add_ray(bench, "run the agents' training and evaluation as Ray tasks instead of local processes")
    bench.add_argument("--out", default="benchmark_out",
                       help="folder for the agents' run folders, the episodes, summary and figures (default "
                            "benchmark_out; run again into it, finished agents are evaluated, unfinished ones resumed)")
    arguments.add_quiet(bench)
    bench.set_defaults(func=_cmd_benchmark)


def build_parser() -> argparse.ArgumentParser:
    """The ``emmi-gym`` parser: one subparser per command, each built by its own function."""
    parser = argparse.ArgumentParser(prog="emmi-gym", description=DESCRIPTION)
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for add_parser in (ab.add_demo_parser, ab.add_parser, _add_train_parser, _add_clone_parser, _add_evaluate_parser,
                       _add_benchmark_parser, metrics.add_parser, record.add_parser, replay.add_parser,
                       score_checkpoints.add_parser, learning_curves.add_parser, compare_policies.add_parser):
        add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    from .concurrency.interrupts import EXIT_INTERRUPTED, EXIT_TERMINATED, RunStopped, terminate_as_interrupt

    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command not in NO_KERNELS and (note := first_run_note()) is not None:
        print(note, file=sys.stderr, flush=True)
    with terminate_as_interrupt() as terminated:  # SIGTERM stops a command as Ctrl-C does
        try:
            status = args.func(args)
        except MissingExtraError as exc:
            parser.exit(2, f"emmi-gym {args.command}: error: {exc}\n")
        except ModuleNotFoundError as exc:  # an optional extra the command needs: the line that installs it
            missing = missing_extra(exc, f"{args.command!r}")
            if missing is None:
                raise
            parser.exit(2, f"emmi-gym {args.command}: error: {missing}\n")
        except (ValueError, KeyError, OSError) as exc:  # bad input, a file or folder: a message, not a traceback
            message = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
            parser.exit(2, f"emmi-gym {args.command}: error: {message}\n")
        except RunStopped as exc:  # a worker died or stalled: what the run saved, and how to go on
            parser.exit(1, f"emmi-gym {args.command}: error: {exc}\n")
        except KeyboardInterrupt as exc:  # before a run could save anything, or with what it kept
            parser.exit(EXIT_TERMINATED if terminated else EXIT_INTERRUPTED,
                        f"\nemmi-gym {args.command}: interrupted{f': {exc}' if str(exc) else ''}\n")
    return EXIT_TERMINATED if terminated and status == EXIT_INTERRUPTED else status


if __name__ == "__main__":
    sys.exit(main())
