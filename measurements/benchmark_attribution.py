"""How much of the differences in the map between policies their routes explain (the order, the revisits, the
robot time), and what each policy gains beyond them (:mod:`emmi_gym.tools.experiments.attribution`).

    python measurements/benchmark_attribution.py FOLDER [FOLDER ...] [--policies NAME ...] [--bootstrap 2000]

A FOLDER is the ``--out`` of ``emmi-gym benchmark`` (its ``benchmark_episodes.csv``: the agents of every reward
and the baselines, all on the same held-out worlds) or of ``emmi-gym evaluate`` (its ``episodes.csv``; several
such folders on the same worlds and seeds are pooled, each agent under its own ``--name``). Every episode is one
row (``--policies``: only those policies', by the names the tables give them); the tables go to stdout as Markdown.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import _arguments as arguments
from evaluations_paired import pooled_episodes

from emmi_gym.tools.experiments.attribution import markdown, policy_name
from emmi_gym.tools.experiments.report import read_csv


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="+", type=Path,
                        help="the --out folder of 'emmi-gym benchmark', or those of 'emmi-gym evaluate'")
    parser.add_argument("--bootstrap", type=arguments.integer(100, 100_000), default=2000,
                        help="resamplings of the worlds for the intervals")
    parser.add_argument("--policies", nargs="+", metavar="NAME",
                        help="fit only these policies' episodes (default: every episode in the folders)")
    args = parser.parse_args()
    benchmark = args.folders[0] / "benchmark_episodes.csv"
    if len(args.folders) == 1 and benchmark.is_file():
        rows = read_csv(benchmark)
    else:
        rows = pooled_episodes(args.folders, traces=False)
    if args.policies:
        names = {policy_name(row) for row in rows}
        missing = sorted(set(args.policies) - names)
        if missing:
            parser.error(f"--policies: no episodes of {missing} in the folders, which hold {sorted(names)}")
        rows = [row for row in rows if policy_name(row) in args.policies]
    try:
        print(markdown(rows, args.bootstrap))
    except ValueError as error:
        raise SystemExit(f"{', '.join(map(str, args.folders))}: {error}") from None


if __name__ == "__main__":
    main()
