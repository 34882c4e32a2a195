"""How much of a reward benchmark's differences in the map its policies' routes explain (the order, the
revisits, the robot time), and what each policy gains beyond them
(:mod:`emmi_gym.tools.experiments.attribution`).

    python measurements/benchmark_attribution.py BENCHMARK_DIR [--bootstrap 2000]

Every episode of ``BENCHMARK_DIR/benchmark_episodes.csv`` (the agents of every reward and the scripted
policies, all on the same held-out worlds) is one row; the tables go to stdout as Markdown.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from emmi_gym.tools.commands import arguments
from emmi_gym.tools.experiments.attribution import markdown
from emmi_gym.tools.experiments.report import read_csv


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("benchmark", type=Path, help="the --out folder of 'emmi-gym benchmark'")
    parser.add_argument("--bootstrap", type=arguments.integer(100, 100_000), default=2000,
                        help="resamplings of the worlds for the intervals")
    args = parser.parse_args()
    episodes = args.benchmark / "benchmark_episodes.csv"
    if not episodes.is_file():
        raise SystemExit(f"{episodes}: not found (a finished benchmark's --out is expected)")
    print(markdown(read_csv(episodes), args.bootstrap))


if __name__ == "__main__":
    main()
