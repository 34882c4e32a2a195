"""``emmi-gym paper-example``: EMMI against the joint entropy on the paper's Fig. 5 example
(:func:`emmi_gym.certainty.examples.fig5_contrast`)."""

from __future__ import annotations

import argparse
import sys

#: The name this command had before 0.3.0; it still runs, with a note, until 0.4.0.
OLD_NAME = "metrics"


def add_parser(subparsers) -> None:
    example = subparsers.add_parser("paper-example",
                                    help="show EMMI vs the joint entropy on the paper's Fig. 5 example")
    example.set_defaults(func=run)
    old = subparsers.add_parser(OLD_NAME, help="the old name of paper-example (goes in 0.4.0)")
    old.set_defaults(func=run, renamed_from=OLD_NAME)


def run(args: argparse.Namespace) -> int:
    from ...certainty.examples import fig5_contrast

    if getattr(args, "renamed_from", None):
        print(f"note: `emmi-gym {args.renamed_from}` is now `emmi-gym paper-example`; the old name goes in "
              "emmi-gym 0.4.0", file=sys.stderr)

    rows = fig5_contrast()
    keys = list(rows[0])
    print("Fig. 5 of Blanco et al. (IROS 2006): two equally weighted particles that agree or")
    print("disagree (p = 0.01 vs 0.99) on a 10x10 patch of a 40x40 map.\n")
    print(" | ".join(f"{k:>22}" for k in keys))
    for row in rows:
        print(" | ".join(f"{row[k]:>22.4f}" if isinstance(row[k], float) else f"{row[k]:>22}" for k in keys))
    agree, disagree = rows
    print(f"\nEMMI falls by {agree['emmi_bits'] - disagree['emmi_bits']:.3f} bits/cell when the particles disagree;")
    change = disagree["map_entropy_term_bits"] - agree["map_entropy_term_bits"]
    print(f"the joint entropy's map term changes by {change:.3f} bits.")
    return 0
