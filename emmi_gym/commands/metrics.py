"""``emmi-gym metrics``: EMMI against the joint entropy on the paper's Fig. 5 example
(:func:`emmi_gym.certainty.examples.fig5_contrast`)."""

from __future__ import annotations

import argparse


def add_parser(subparsers) -> None:
    metrics = subparsers.add_parser("metrics", help="show EMMI vs the joint entropy on the paper's Fig. 5 example")
    metrics.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..certainty.examples import fig5_contrast

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
