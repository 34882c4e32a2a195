"""The ``emmi-gym`` command: a dispatch table over :mod:`emmi_gym.tools.commands`, where each subcommand builds its
own parser and runs it, and :mod:`emmi_gym.tools.commands.dispatch` turns what it raises into a line and a status."""

from __future__ import annotations

import argparse
import sys

from .. import __version__
from .commands import (
    ab,
    benchmark,
    clone,
    compare_policies,
    evaluate,
    learning_curves,
    paper_example,
    record,
    replay,
    score_checkpoints,
    train,
)
from .commands.dispatch import run_subcommand

DESCRIPTION = ("Active SLAM with a Rao-Blackwellized particle filter and the EMMI reward: run the paper's A/B "
               "experiment, train and evaluate agents, benchmark rewards, record and replay CARMEN logs and ROS "
               "bags.")

#: Each subcommand's parser, in the order ``--help`` lists them (the A/B module also adds ``demo``).
PARSERS = (ab.add_demo_parser, ab.add_parser, train.add_parser, clone.add_parser, evaluate.add_parser,
           benchmark.add_parser, paper_example.add_parser, record.add_parser, replay.add_parser,
           score_checkpoints.add_parser, learning_curves.add_parser, compare_policies.add_parser)


def build_parser() -> argparse.ArgumentParser:
    """The ``emmi-gym`` parser: ``--version`` and one subparser per command."""
    parser = argparse.ArgumentParser(prog="emmi-gym", description=DESCRIPTION)
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    subparsers = parser.add_subparsers(dest="command", required=True)
    for add_parser in PARSERS:
        add_parser(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Parse ``argv`` (default: the command line) and run the command; its exit status."""
    parser = build_parser()
    return run_subcommand(parser, parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
