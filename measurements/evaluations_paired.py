"""Policies evaluated in separate runs on the same worlds and seeds, paired: an agent trained later beside the
baselines played once, of the final maps and at equal robot time (:mod:`emmi_gym.tools.evaluation.robot_time`).

    emmi-gym evaluate RUN/model.zip --name pose_entropy_seed0 --world dungeon_maps/test --episodes 50 --out A
    python measurements/evaluations_paired.py A BASELINES --policy pose_entropy_seed0 \\
        --baselines active_loop_closing frontier explore_plans_emmi

Each FOLDER is the ``--out`` of ``emmi-gym evaluate`` (its ``episodes.csv`` and ``traces.csv``); the folders'
episodes are pooled, and one (world, seed, policy) found in two of them is an error (give the agents distinct
``--name`` s). For each policy and baseline the two Markdown tables of ``evaluate`` go to stdout: the final maps, then
at equal robot time. With ``--compact``, two tables for all the policies instead, as a results page shows many
agents: every policy's means (the baselines first), and each policy minus each baseline, final and at equal robot
time, in the scores a page compares (:data:`COMPACT`); ``--at final`` or ``--at equal_time`` keeps one of the two,
as many agents' differences fill a page each.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from emmi_gym.inputs.csv_files import CsvFileError, read_csv_file
from emmi_gym.tools.evaluation.comparison import SCORES, difference_cell, markdown_table, paired
from emmi_gym.tools.evaluation.directions import format_number
from emmi_gym.tools.evaluation.episodes import nanmean
from emmi_gym.tools.evaluation.robot_time import TIME, TRACED, at_equal_robot_time, with_traces
from emmi_gym.world.map_sets import world_name

KEYS = ("world", "seed", "policy")
#: The scores of the compact tables: the final map's quality, then the robot time.
COMPACT = ("oracle_accuracy", "ate", "wall_consistency", "coverage", "building_accuracy", TIME)
#: What every traces file holds (the building accuracy only those written since it was traced: NaN in the others).
ALWAYS_TRACED = tuple(column for column in TRACED if column != "building_accuracy")


def pooled_episodes(folders: list[Path], traces: bool = True) -> list[dict]:
    """The episodes of every folder, each with its trace (unless not ``traces``), a world named as
    :func:`~emmi_gym.world.map_sets.world_name` says (so that evaluations made from two installs pair);
    ``SystemExit`` naming a file that is missing or not one of ``evaluate``'s, or an episode that two folders
    hold with other scores (one they hold alike, as evaluations that share a ``played/`` folder do, counts once)."""
    rows, seen = [], {}
    for folder in folders:
        try:
            episodes = read_csv_file(folder / "episodes.csv", "episodes file", required=KEYS,
                                     optional_numeric=(*SCORES, "seed"))
            points = read_csv_file(folder / "traces.csv", "traces file", required=KEYS,
                                   numeric=("sim_steps", *ALWAYS_TRACED, "seed"),
                                   optional_numeric=TRACED) if traces else []
        except (CsvFileError, OSError) as error:
            raise SystemExit(str(error)) from None
        for row in (*episodes, *points):
            row["world"] = world_name(row["world"])
        fresh = []
        for row in episodes:
            key = tuple(row[k] for k in KEYS)
            if key in seen and not same_episode(row, seen[key][1]):
                raise SystemExit(f"{folder}: the episode {dict(zip(KEYS, key, strict=True))} is also in "
                                 f"{seen[key][0]}, with other scores: evaluate each agent under its own --name")
            if key not in seen:  # the same episode in two folders (read back from one played/): counted once
                seen[key] = folder, row
                fresh.append(row)
        rows += with_traces(fresh, points, KEYS)
    return rows


def same_episode(row: dict, other: dict) -> bool:
    """Whether two rows of one (world, seed, policy) hold the same values in the columns both files have (NaN
    where both are NaN)."""
    return all(a == b or (isinstance(a, float) and isinstance(b, float) and np.isnan(a) and np.isnan(b))
               for a, b in ((row[k], other[k]) for k in row.keys() & other.keys()))


def means_table(rows: list[dict], policies: list[str]) -> str:
    """Each of ``policies``' mean of the :data:`COMPACT` scores and its revisit share, a row each."""
    columns = (*COMPACT, "revisit_share")
    lines = ["| policy | episodes | " + " | ".join(SCORES[c] for c in columns) + " |",
             "| --- | --- | " + " | ".join("---" for _ in columns) + " |"]
    for name in policies:
        mine = [row for row in rows if row["policy"] == name]
        means = [format_number(nanmean([row.get(c, np.nan) for row in mine]), c) for c in columns]
        lines.append(f"| {name} | {len(mine)} | " + " | ".join(means) + " |")
    return "\n".join(lines)


#: When the compact differences read the episodes: their final maps, and at equal robot time.
MOMENTS = ("final", "equal_time")


def differences_table(rows: list[dict], policies: list[str], baselines: list[str], moments=MOMENTS) -> str:
    """Each of ``policies`` minus each of ``baselines``, paired by (world, seed): the :data:`COMPACT` scores of the
    final maps, then read at equal robot time (the robot time then: the mean of the shorter episodes); only the
    ``moments`` of :data:`MOMENTS` given."""
    lines = ["| policy minus | pairs | " + " | ".join(SCORES[c] for c in COMPACT) + " |",
             "| --- | --- | " + " | ".join("---" for _ in COMPACT) + " |"]
    for name in policies:
        for baseline in baselines:
            for when in moments:
                read = rows if when == "final" else at_equal_robot_time(rows, name, baseline)
                cells = [difference_cell(paired(read, c, name, baseline), c) for c in COMPACT]
                if when == "equal_time":
                    cells[-1] = "at " + format_number(np.mean([r[TIME] for r in read if r["policy"] == name]), TIME)
                pairs = len(paired(read, "coverage", name, baseline))
                label = "" if len(moments) == 1 else ", " + when.replace("_", " ")
                lines.append(f"| {name} - {baseline}{label} | {pairs} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="+", type=Path, help="--out folders of 'emmi-gym evaluate'")
    parser.add_argument("--policy", nargs="+", required=True, help="the policies paired with each baseline")
    parser.add_argument("--baselines", nargs="+", required=True, help="the policies they are paired with")
    parser.add_argument("--compact", action="store_true",
                        help="two tables for all the policies: their means, and each minus each baseline")
    parser.add_argument("--at", nargs="+", choices=MOMENTS, default=list(MOMENTS),
                        help="with --compact: the differences of the final maps, at equal robot time, or both")
    args = parser.parse_args()
    rows = pooled_episodes(args.folders)
    names = {row["policy"] for row in rows}
    missing = sorted({*args.policy, *args.baselines} - names)
    if missing:
        parser.error(f"{missing}: no episodes of them in the folders, which hold {sorted(names)}")
    played = {}
    for row in rows:
        played.setdefault(row["policy"], set()).add((row["world"], row["seed"]))
    for policy in args.policy:
        for baseline in args.baselines:
            if not played[policy] & played[baseline]:
                parser.error(f"{policy} and {baseline} played no episode on the same world and seed, so none pairs "
                             f"them: e.g. {min(played[policy])} against {min(played[baseline])}")
    if args.compact:
        print(means_table(rows, [*args.baselines, *args.policy]) + "\n")
        print(differences_table(rows, args.policy, args.baselines, args.at))
        return
    for policy in args.policy:
        for baseline in args.baselines:
            print(markdown_table(rows, policy, baseline, f"{policy} - {baseline}") + "\n")
            print(markdown_table(at_equal_robot_time(rows, policy, baseline), policy, baseline,
                                 f"{policy} - {baseline} at equal robot time") + "\n")


if __name__ == "__main__":
    main()
