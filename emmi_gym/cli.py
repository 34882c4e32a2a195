"""The ``emmi-gym`` command."""

from __future__ import annotations

import argparse
import sys


def _cmd_metrics(args: argparse.Namespace) -> int:
    from .examples import fig5_contrast

    rows = fig5_contrast()
    keys = list(rows[0])
    print("Fig. 5 of Blanco et al. (IROS 2006): two equally weighted particles that agree or")
    print("disagree (p = 0.01 vs 0.99) on a 10x10 patch of a 40x40 map.\n")
    print(" | ".join(f"{k:>22}" for k in keys))
    for row in rows:
        print(" | ".join(f"{row[k]:>22.4f}" if isinstance(row[k], float) else f"{row[k]:>22}" for k in keys))
    agree, disagree = rows
    print(f"\nEMMI falls by {agree['emmi_bits'] - disagree['emmi_bits']:.3f} bits/cell when the particles disagree;")
    print(f"the joint entropy's map term changes by {disagree['map_entropy_term_bits'] - agree['map_entropy_term_bits']:.3f} bits.")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="emmi-gym", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    metrics = sub.add_parser("metrics", help="show EMMI vs the joint entropy on the paper's Fig. 5 example")
    metrics.set_defaults(func=_cmd_metrics)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
