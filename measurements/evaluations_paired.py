"""Policies evaluated in separate runs on the same worlds and seeds, paired: an agent trained later beside the
baselines played once, of the final maps and at equal robot time (:mod:`emmi_gym.tools.experiments.robot_time`).

    emmi-gym evaluate RUN/model.zip --name pose_entropy_seed0 --world dungeon_maps/test --episodes 50 --out A
    python measurements/evaluations_paired.py A BASELINES --policy pose_entropy_seed0 \\
        --baselines active_loop_closing frontier explore_plans_emmi

Each FOLDER is the ``--out`` of ``emmi-gym evaluate`` (its ``episodes.csv`` and ``traces.csv``); the folders'
episodes are pooled, and one (world, seed, policy) found in two of them is an error (give the agents distinct
``--name`` s). For each baseline the two Markdown tables of ``evaluate`` go to stdout: the final maps, then at equal
robot time.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from emmi_gym.inputs.csv_files import CsvFileError, read_csv_file
from emmi_gym.tools.experiments.comparison import SCORES, markdown_table
from emmi_gym.tools.experiments.robot_time import TRACED, at_equal_robot_time, with_traces

KEYS = ("world", "seed", "policy")


def pooled_episodes(folders: list[Path], traces: bool = True) -> list[dict]:
    """The episodes of every folder, each with its trace (unless not ``traces``); ``SystemExit`` naming a file
    that is missing or not one of ``evaluate``'s, or an episode that two folders hold."""
    rows, seen = [], {}
    for folder in folders:
        try:
            episodes = read_csv_file(folder / "episodes.csv", "episodes file", required=KEYS,
                                     optional_numeric=(*SCORES, "seed"))
            points = read_csv_file(folder / "traces.csv", "traces file", required=KEYS,
                                   numeric=("sim_steps", *TRACED, "seed")) if traces else []
        except (CsvFileError, OSError) as error:
            raise SystemExit(str(error)) from None
        for row in episodes:
            key = tuple(row[k] for k in KEYS)
            if key in seen:
                raise SystemExit(f"{folder}: the episode {dict(zip(KEYS, key, strict=True))} is also in {seen[key]}: "
                                 "evaluate each agent under its own --name")
            seen[key] = folder
        rows += with_traces(episodes, points, KEYS)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="+", type=Path, help="--out folders of 'emmi-gym evaluate'")
    parser.add_argument("--policy", required=True, help="the policy paired with each baseline")
    parser.add_argument("--baselines", nargs="+", required=True, help="the policies it is paired with")
    args = parser.parse_args()
    rows = pooled_episodes(args.folders)
    names = {row["policy"] for row in rows}
    missing = sorted({args.policy, *args.baselines} - names)
    if missing:
        parser.error(f"{missing}: no episodes of them in the folders, which hold {sorted(names)}")
    for baseline in args.baselines:
        print(markdown_table(rows, args.policy, baseline, f"{args.policy} - {baseline}") + "\n")
        print(markdown_table(at_equal_robot_time(rows, args.policy, baseline), args.policy, baseline,
                             f"{args.policy} - {baseline} at equal robot time") + "\n")


if __name__ == "__main__":
    main()
