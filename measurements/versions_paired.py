"""The maps of two codes (or two versions of an id) paired per world, seed and policy: are they as good?

    python measurements/versions_paired.py BEFORE/episodes.csv AFTER/episodes.csv [--percent sim_steps]

Each file is the ``episodes.csv`` of ``emmi-gym compare-policies`` (or of ``evaluate``), one run with
the code before a change and one with the code after, on the same worlds and seeds. Rows are paired
by (world's plan, seed, policy); for each policy and score the table gives both means and the mean of
the paired differences (after - before) with its 95% Student-t interval, and for the scores of
``--percent`` (robot time by default) the difference and its interval as a share of the mean before.
The Markdown table goes to stdout.
"""

from __future__ import annotations

import argparse
from collections import defaultdict

import numpy as np

from emmi_gym.inputs.csv_files import CsvFileError, read_csv_file
from emmi_gym.tools.evaluation.intervals import difference_interval

SCORES = ("ate", "oracle_accuracy", "wall_consistency", "coverage", "sim_steps")
KEYS = ("plan", "seed", "policy")


def paired_rows(before: list[dict], after: list[dict]) -> dict[str, list[tuple[dict, dict]]]:
    """For each policy, the (before, after) rows of the (plan, seed) both files hold; raises ``SystemExit``
    when the files share none."""
    later = {tuple(row[k] for k in KEYS): row for row in after}
    pairs: dict[str, list[tuple[dict, dict]]] = defaultdict(list)
    for row in before:
        key = tuple(row[k] for k in KEYS)
        if key in later:
            pairs[row["policy"]].append((row, later[key]))
    if not pairs:
        raise SystemExit("the two files share no (plan, seed, policy): were they run on the same worlds and seeds?")
    return pairs


def table(pairs: dict[str, list[tuple[dict, dict]]], scores, percent) -> str:
    """The Markdown table of :func:`paired_rows`' pairs."""
    lines = ["| policy | score | pairs | before | after | after - before [95%] |",
             "| --- | --- | --- | --- | --- | --- |"]
    for policy, rows in pairs.items():
        for score in scores:
            old = np.array([b[score] for b, _ in rows])
            new = np.array([a[score] for _, a in rows])
            mean, low, high, n = difference_interval(new - old, score)
            cell = f"{mean:+.4g} [{low:+.4g}, {high:+.4g}]"
            if score in percent:
                base = float(np.nanmean(old))
                cell += f" = {100 * mean / base:+.1f}% [{100 * low / base:+.1f}%, {100 * high / base:+.1f}%]"
            lines.append(f"| {policy} | {score} | {n} | {np.nanmean(old):.4g} | {np.nanmean(new):.4g} | {cell} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", help="episodes.csv of the code before")
    parser.add_argument("after", help="episodes.csv of the code after")
    parser.add_argument("--scores", nargs="+", default=list(SCORES), help="the columns compared")
    parser.add_argument("--percent", nargs="*", default=["sim_steps"],
                        help="scores whose difference is also given as a share of the mean before")
    args = parser.parse_args()
    try:
        before, after = (read_csv_file(path, "episodes file", required=KEYS, numeric=args.scores)
                         for path in (args.before, args.after))
    except CsvFileError as error:
        raise SystemExit(str(error)) from None
    print(table(paired_rows(before, after), args.scores, set(args.percent)))


if __name__ == "__main__":
    main()
