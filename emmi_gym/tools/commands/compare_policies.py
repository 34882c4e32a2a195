"""``emmi-gym compare-policies``: scripted policies on many worlds, paired by world and seed
(:mod:`emmi_gym.tools.evaluation.comparison`), with a table of paired differences and one world's maps."""

from __future__ import annotations

import argparse

from . import arguments


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "compare-policies", help="two scripted policies on many worlds, paired by world and seed: mean [95%% "
                                 "interval] of each score and of the paired difference",
        description="Writes OUT/episodes.csv, OUT/summary.md (the table it prints) and OUT/maps.png (the world "
                    "and seed where the policies' map accuracies differ most, side by side).")
    parser.add_argument("--worlds", nargs="+", default=["dungeon_maps/test"], metavar="WORLD",
                        help="map sets (a shipped set, a folder, a glob: their first --plans maps) or worlds "
                             "(names, files); default dungeon_maps/test")
    parser.add_argument("--plans", type=arguments.integer(1, arguments.MAX_EPISODES), default=50,
                        help="maps taken from each map set (default 50)")
    arguments.add_seed_range(parser, seeds=1)
    parser.add_argument("--env-id", default="emmi_gym/ExplorePlans-v1",
                        help="the environment id (default emmi_gym/ExplorePlans-v1)")
    parser.add_argument("--options", default="{}",
                        help="JSON object of further gym.make options (default {}: the id's own)")
    parser.add_argument("--policies", nargs=2, default=["frontier", "active_loop_closing"],
                        metavar=("BASELINE", "POLICY"),
                        help="the two scripted policies, paired (default frontier active_loop_closing)")
    arguments.add_workers(parser)
    parser.add_argument("--out", default="results/plans", help="output folder (default results/plans)")
    arguments.add_quiet(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import gymnasium as gym

    from ...env import EnvConfig
    from ...inputs.env_ids import check_env_id
    from ...inputs.errors import excerpt
    from ...inputs.json_files import parse_json
    from ...inputs.user_paths import output_folder
    from ...inputs.validation import build
    from ..evaluation.comparison import (
        ComparisonSettings,
        compare,
        markdown_table,
        play_on_world,
        plot_pair,
        worlds_of,
    )
    from ..experiments.report import write_csv
    from ..policies import POLICY_NAMES

    options = parse_json(args.options.encode(), "--options", "a JSON object of gym.make options")
    if not isinstance(options, dict):
        raise ValueError(f"--options: expected a JSON object of options ({{\"name\": value, ...}}), got "
                         f"{args.options[:80]!r}")
    if "world" in options:
        raise ValueError(f"--options: a world ({excerpt(options['world'])}) is --worlds's to give: every episode is "
                         "played on one of --worlds, so pass it there")
    check_env_id(args.env_id, "command line", "--env-id")
    unknown = sorted(set(args.policies) - set(POLICY_NAMES))
    if unknown:
        raise ValueError(f"--policies: unknown {unknown}; choose from {list(POLICY_NAMES)}")
    build(EnvConfig, {**gym.spec(args.env_id).kwargs, **options}, "", source="--options")
    out = output_folder(args.out)
    settings = ComparisonSettings(args.env_id, options)
    worlds = worlds_of(args.worlds, args.plans)
    seeds = list(arguments.seed_range(args))
    baseline, policy = args.policies
    rows = compare(worlds, seeds, [baseline, policy], settings, workers=args.workers, progress=not args.quiet)
    write_csv(out / "episodes.csv", rows)
    title = f"{args.env_id}{f' {options}' if options else ''} on {len(worlds)} worlds x {len(seeds)} seeds"
    table = markdown_table(rows, policy, baseline, title)
    (out / "summary.md").write_text(table + "\n")
    print(table)
    accuracies: dict = {}
    for row in rows:
        accuracies.setdefault((row["world"], row["seed"]), {})[row["policy"]] = row["oracle_accuracy"]
    world, seed = max(accuracies, key=lambda k: abs(accuracies[k].get(policy, 0) - accuracies[k].get(baseline, 0)))
    plot_pair([play_on_world(world, seed, p, settings, keep_maps=True) for p in (baseline, policy)], out / "maps.png")
    print(f"\nwrote {out / 'summary.md'}, {out / 'episodes.csv'}, {out / 'maps.png'} ({world}, seed {seed})")
    return 0
