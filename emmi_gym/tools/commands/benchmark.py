"""``emmi-gym benchmark``: the reward benchmark, an agent per reward and seed beside the scripted
baselines (:mod:`emmi_gym.tools.training.reward_benchmark`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ...env.seeds import HELD_OUT_SEED
from . import arguments


def add_parser(subparsers) -> None:
    bench = subparsers.add_parser("benchmark", help="train agents per reward variant and compare them, and the "
                                                    "scripted baselines, under the same ground-truth metrics",
                                  epilog=arguments.MODEL_FILES_RUN_CODE)
    bench.add_argument("--config", default="agents/ppo_emmi.yaml",
                       help="the agent configuration whose reward is varied (default agents/ppo_emmi.yaml)")
    bench.add_argument("--rewards", nargs="+", default=["emmi", "pose_entropy", "joint_entropy", "coverage"],
                       metavar="REWARD", help="reward variants, an agent per seed each (default emmi pose_entropy "
                                              "joint_entropy coverage; see docs/rewards.md)")
    arguments.add_seed_range(bench, 3)
    bench.add_argument("--timesteps", type=arguments.integer(1), default=None,
                       help="training steps per agent (default: the configuration's total_timesteps)")
    bench.add_argument("--episodes", type=arguments.EPISODES, default=10,
                       help="held-out evaluation episodes per agent and per baseline (default 10; on a map set, its "
                            "first maps, one episode each, or --seeds-per-plan each)")
    arguments.add_seeds_per_plan(bench)
    bench.add_argument("--eval-seed", type=arguments.SEED, default=HELD_OUT_SEED,
                       help=f"first held-out episode's seed, for the agents and the baselines alike (default "
                            f"{HELD_OUT_SEED}: the held-out seeds)")
    bench.add_argument("--baselines", nargs="*", default=["frontier", "random"], metavar="POLICY",
                       help="scripted policies or shipped agents evaluated on the same episodes, paired with the "
                            "agents (final maps, and at equal robot time) (default frontier random; none: give the "
                            "option with no names)")
    bench.add_argument("--init-from", default=None, metavar="MODEL",
                       help="every agent starts from this model's weights (as 'train --init-from'), e.g. a "
                            "clone of a scripted policy from 'emmi-gym clone'")
    bench.add_argument("--allow-no-training", action="store_true",
                       help="with --init-from: accept a model that already holds --timesteps decisions (the agents "
                            "are then that model, evaluated under each reward's env)")
    arguments.add_workers(bench)
    bench.add_argument("--rollout-workers", action="store_true",
                       help="run each agent's envs in rollout workers, a process per env (the configuration's "
                            "n_envs), instead of in the agent's process: for a machine with more cores than the "
                            "agents trained at once")
    bench.add_argument("--train-only", action="store_true",
                       help="train or resume every agent to its budget and evaluate nothing (a sitting of a budget "
                            "spread over several; run again without it to evaluate every agent and baseline once)")
    arguments.add_ray(bench, "run the agents' training and evaluation as Ray tasks instead of local processes")
    bench.add_argument("--out", default="benchmark_out",
                       help="folder for the agents' run folders, the episodes, summary and figures (default "
                            "benchmark_out; run again into it, finished agents are evaluated, unfinished ones "
                            "resumed, and the episodes kept in its played/ are not played again)")
    arguments.add_trust_model(bench, "the --init-from model")
    arguments.add_quiet(bench)
    bench.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import time

    from ...concurrency.ray_cluster import LOCAL
    from ...env.reward_registry import REWARDS
    from ...inputs.user_paths import output_folder
    from ..training.config import load_agent_config
    from ..training.reward_benchmark import run_benchmark, write_benchmark
    from ..training.run_folders import RunFolder

    bad = sorted(set(args.rewards) - set(REWARDS))
    if bad:
        raise ValueError(f"--rewards: unknown {bad}; choose from {list(REWARDS)}")
    output_folder(args.out)
    arguments.trust_models(args, [args.init_from])
    config = load_agent_config(args.config)
    if args.timesteps is None:
        args.timesteps = config.total_timesteps
    started = time.perf_counter()
    ray_address = None if args.ray is None else arguments.ray_address(args) or LOCAL  # LOCAL: Ray's default too
    baselines = arguments.baseline_policies(args.baselines)
    results = run_benchmark(config, args.rewards, arguments.seed_range(args), args.timesteps, args.episodes,
                            baselines, args.out, workers=args.workers, ray_address=ray_address,
                            progress=not args.quiet, init_from=args.init_from,
                            allow_no_training=args.allow_no_training, eval_seed=args.eval_seed,
                            rollout_workers=args.rollout_workers, train_only=args.train_only,
                            seeds_per_plan=args.seeds_per_plan, report=print)
    elapsed = time.perf_counter() - started
    if args.train_only:
        for result in results:
            job = result["job"]
            decisions = RunFolder(job.run_dir).finished_decisions()
            print(f"{job.variant} seed {job.seed}: {decisions} decisions in {job.run_dir} "
                  f"({'trained now' if result['trained'] else 'finished by an earlier run'})")
        print(f"every agent finished in {elapsed / 60:.1f} min; run again without --train-only to evaluate them and "
              "the baselines")
        return 0
    per_plan = f" x {args.seeds_per_plan} seeds" if args.seeds_per_plan > 1 else ""
    reused = sum(1 for r in results if r["job"].kind == "agent" and not r["trained"])
    kept = sum(r["kept_episodes"] for r in results)
    header = (f"Reward benchmark: {config.algorithm} on {config.env_id} ({Path(args.config).name}), "
              f"{args.timesteps} training steps per agent"
              f"{f' (from the weights of {args.init_from})' if args.init_from else ''}, "
              f"seeds {args.first_seed}-{args.first_seed + args.seeds - 1} per reward, {args.episodes} held-out "
              f"evaluation episodes each{per_plan} (seeds from {args.eval_seed}); {elapsed / 60:.1f} min wall time "
              f"({'Ray' if args.ray else 'local processes'}"
              f"{f'; {reused} agent(s) trained by an earlier run into this folder' if reused else ''}"
              f"{f'; {kept} episode(s) played by an earlier run, kept in its played/' if kept else ''}). "
              f"Mean [95% t-interval]: over agents for trained variants (one agent: its mean), over plans "
              f"for the baselines.")
    files = write_benchmark(results, args.out, header)
    print(files["summary"].read_text())
    for path in files.values():
        print(f"wrote {path}")
    return 0
