"""``emmi-gym clone``: behaviour cloning, a configuration's model fitted to a scripted policy's decisions
(:mod:`emmi_gym.tools.training.imitation`)."""

from __future__ import annotations

import argparse

from ...env.seeds import DEMONSTRATION_SEED
from . import arguments


def add_parser(subparsers) -> None:
    cl = subparsers.add_parser("clone", help="behaviour cloning: fit a configuration's model to a scripted "
                                             "policy's decisions, a warm start for 'train --init-from'")
    cl.add_argument("config", help="agent configuration (.yaml) of a waypoint env, e.g. agents/ppo_plans_emmi.yaml")
    cl.add_argument("--policy", default=None,
                    help="the scripted policy (default active_loop_closing; not with --demos, whose files hold the "
                         "decisions to fit)")
    cl.add_argument("--episodes", type=arguments.EPISODES, default=64,
                    help="demonstration episodes in the training env (default 64)")
    cl.add_argument("--seed", type=arguments.SEED, default=DEMONSTRATION_SEED,
                    help=f"first demonstration episode's seed (default {DEMONSTRATION_SEED})")
    cl.add_argument("--demos", nargs="+", default=None, metavar="NPZ",
                    help="demonstrations.npz files to fit instead of playing episodes")
    cl.add_argument("--epochs", type=arguments.integer(1), default=20,
                    help="passes over the demonstrations in the maximum-likelihood fit (default 20)")
    arguments.add_workers(cl)
    cl.add_argument("--out", required=True, help="folder for model.zip, config.yaml, demonstrations.npz, clone.yaml")
    cl.add_argument("--overwrite", action="store_true",
                    help="write into a folder that is not empty, replacing an earlier clone's files there")
    arguments.add_quiet(cl)
    cl.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ...inputs.user_paths import output_folder
    from ..policies import POLICY_NAMES
    from ..training.config import load_agent_config
    from ..training.imitation import (
        CLONE_FILES,
        Demonstrations,
        agreement,
        check_cloneable,
        clone_run,
        collect_demonstrations,
        write_clone_record,
    )
    from ..training.run_folders import RunFolder

    if args.demos and args.policy:
        raise ValueError(f"--policy {args.policy} with --demos: the demonstrations files hold their own decisions; "
                         "give one or the other")
    policy = args.policy or "active_loop_closing"
    if policy not in POLICY_NAMES:
        raise ValueError(f"--policy: unknown {policy!r}; choose from {list(POLICY_NAMES)}")
    folder = RunFolder(args.out, CLONE_FILES)
    folder.check_new(args.overwrite, resumable=False, inputs={"--demos": args.demos})
    out = output_folder(args.out)
    config = load_agent_config(args.config)
    check_cloneable(config)  # before any episode is played
    if args.demos:
        demonstrations = Demonstrations.load(*args.demos)  # checked, then read into one set of arrays
    else:
        demonstrations = collect_demonstrations(config, policy, args.episodes, args.seed, workers=args.workers,
                                                progress=not args.quiet)
    if args.overwrite:  # once every input is read
        folder.clear()
    if not args.demos:
        demonstrations.save(out / "demonstrations.npz")
    source = {"demonstrations": [str(path) for path in args.demos]} if args.demos else {"policy": policy}
    print(f"{len(demonstrations)} decisions of {', '.join(args.demos) if args.demos else policy} in "
          f"{demonstrations.episodes} episodes")
    model_path, losses, model = clone_run(config, demonstrations, out, epochs=args.epochs)
    record = {**source, "episodes": demonstrations.episodes, "decisions": len(demonstrations),
              "epochs": args.epochs, "losses": [round(loss, 4) for loss in losses],
              "agreement": round(agreement(model, demonstrations), 4)}
    write_clone_record(out, record)
    print(f"loss {losses[0]:.3f} -> {losses[-1]:.3f}; the model takes the demonstrated action at "
          f"{record['agreement']:.1%} of the decisions. Wrote {model_path}; train on with: emmi-gym train "
          f"{args.config} --init-from {model_path}")
    return 0
