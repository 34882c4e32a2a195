"""Compare scripted policies on many worlds, paired by world and seed (frontier vs active loop-closing).

    python scripts/compare_policies.py [--worlds dungeon_maps/test] [--plans 50] [--seeds 0]
        [--env emmi_gym/ExplorePlans-v0] [--policies frontier active_loop_closing] [--out results/plans]
    python scripts/compare_policies.py --worlds intel aces csail fr079 --seeds 0 1 2 --out results/buildings

``--worlds`` takes map sets (a shipped set, a folder, a glob: their first ``--plans`` maps) or
worlds (names, files). Prints the markdown table (also written to OUT/summary.md), writes
OUT/episodes.csv and OUT/maps.png (one world's maps side by side).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
from _options import checked, json_object

from emmi_gym.env import ENV_IDS, EnvConfig
from emmi_gym.experiments.comparison import (ComparisonSettings, compare, markdown_table, plot_pair, run_episode,
                                              worlds_of)
from emmi_gym.experiments.report import write_csv
from emmi_gym.inputs.validation import build


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", nargs="+", default=["dungeon_maps/test"])
    parser.add_argument("--plans", type=int, default=50, help="maps taken from each map set")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--env", default="emmi_gym/ExplorePlans-v0")
    parser.add_argument("--options", default="{}", help="JSON of further gym.make options")
    parser.add_argument("--policies", nargs=2, default=["frontier", "active_loop_closing"],
                        metavar=("BASELINE", "POLICY"))
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--out", type=Path, default=Path("results/plans"))
    args = parser.parse_args()
    settings = ComparisonSettings(args.env, json_object(parser, "--options", args.options))
    if args.env not in gym.registry:
        parser.error(f"--env: no environment {args.env!r} is registered (emmi-gym's: "
                     f"{', '.join(f'emmi_gym/{name}' for name in ENV_IDS)})")
    checked(parser, build, EnvConfig, {**gym.spec(args.env).kwargs, **settings.env_options}, "", source="--options")
    worlds = worlds_of(args.worlds, args.plans)
    baseline, policy = args.policies
    rows = compare(worlds, args.seeds, [baseline, policy], settings, workers=args.workers)
    args.out.mkdir(parents=True, exist_ok=True)
    write_csv(args.out / "episodes.csv", rows)
    options = f" {settings.env_options}" if settings.env_options else ""
    title = f"{args.env}{options} on {len(worlds)} worlds x {len(args.seeds)} seeds"
    table = markdown_table(rows, policy, baseline, title)
    (args.out / "summary.md").write_text(table + "\n")
    print(table)
    # the picture: the world and seed where the policies' oracle accuracies differ most
    gaps = {}
    for r in rows:
        gaps.setdefault((r["world"], r["seed"]), {})[r["policy"]] = r["oracle_accuracy"]
    world, seed = max(gaps, key=lambda k: abs(gaps[k].get(policy, 0) - gaps[k].get(baseline, 0)))
    plot_pair([run_episode(world, seed, p, settings, keep_maps=True) for p in (baseline, policy)],
              args.out / "maps.png")
    print(f"\nwrote {args.out / 'summary.md'}, {args.out / 'episodes.csv'}, {args.out / 'maps.png'} ({world}, seed "
          f"{seed})")


if __name__ == "__main__":
    main()
