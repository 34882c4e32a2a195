"""``emmi-gym train``: train an agent from a configuration in agents/ (:mod:`emmi_gym.tools.training.train`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from . import arguments


def add_parser(subparsers) -> None:
    tr = subparsers.add_parser("train", help="train an SB3 agent from a configuration in agents/",
                               epilog=arguments.MODEL_FILES_RUN_CODE)
    tr.add_argument("config", help="agent configuration (.yaml), e.g. agents/ppo_emmi.yaml")
    tr.add_argument("--timesteps", type=arguments.integer(1), default=None, help="override total_timesteps")
    tr.add_argument("--seed", type=arguments.SEED, default=None, help="override seed")
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
    arguments.add_trust_model(tr, "the --init-from model and, with --resume, the run's own")
    arguments.add_quiet(tr)
    arguments.add_torch_threads(tr, "1 beside rollout workers and env subprocesses; one per core when the envs run "
                              "in this process")
    tr.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from ...inputs.user_paths import output_folder
    from ..training.config import ROLLOUT_WORKERS, load_agent_config
    from ..training.run_folders import RunFolder
    from ..training.train import set_torch_threads, train, training_torch_threads

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
    arguments.trust_models(args, [args.init_from, out if args.resume else None])
    finished = args.resume and not args.overwrite and args.init_from is None
    trained = RunFolder(out).already_trained(config) if finished else None
    if trained is not None:  # nothing is written: its model and records stay as they are
        print(f"{out}: already trained to {trained} decisions; nothing to do (give a larger --timesteps to train on)")
        return 0
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
          f"{RunFolder(out).config_path}")
    return 0
