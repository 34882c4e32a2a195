"""Scripted policies compared on worlds, paired by world and seed (scripts/compare_policies.py in small)."""

import numpy as np

from emmi_gym.experiments.comparison import ComparisonSettings, compare, markdown_table, paired, plot_pair, run_episode
from emmi_gym.experiments.report import read_csv, write_csv
from emmi_gym.world.map_sets import map_set_files


def test_policies_are_paired_by_world_and_seed(tmp_path):
    worlds = [str(p) for p in map_set_files("dungeon_maps/test")[:2]]
    settings = ComparisonSettings(env_options={"max_decisions": 3})
    rows = compare(worlds, [0], ["frontier", "active_loop_closing"], settings, workers=1, progress=False)
    assert [(r["world"], r["policy"]) for r in rows] == [(w, p) for w in worlds for p in
                                                         ("frontier", "active_loop_closing")]
    assert all(r["decisions"] == 3 and 0.0 <= r["oracle_accuracy"] <= 1.0 for r in rows)
    differences = paired(rows, "ate", "active_loop_closing", "frontier")
    assert differences.shape == (2,)
    assert np.allclose(differences, [rows[1]["ate"] - rows[0]["ate"], rows[3]["ate"] - rows[2]["ate"]])
    table = markdown_table(rows, "active_loop_closing", "frontier", "test")
    assert "2 pairs" in table and "| ATE (m) |" in table
    # the same world and seed give the same episode
    again = run_episode(worlds[0], 0, "frontier", settings, keep_maps=True)
    assert again["ate"] == rows[0]["ate"] and again["oracle_accuracy"] == rows[0]["oracle_accuracy"]
    plot_pair([again, run_episode(worlds[0], 0, "active_loop_closing", settings, keep_maps=True)],
              tmp_path / "maps.png")
    write_csv(tmp_path / "episodes.csv", rows)  # what 'emmi-gym evaluate --out' writes reads back the same
    def nan_as_text(rows):
        return [{k: "nan" if isinstance(v, float) and np.isnan(v) else v for k, v in r.items()} for r in rows]

    assert nan_as_text(read_csv(tmp_path / "episodes.csv")) == nan_as_text(rows)
    assert (tmp_path / "maps.png").stat().st_size > 10_000


def test_worlds_of_takes_a_sets_first_maps_and_a_world_as_it_is():
    from emmi_gym.experiments.comparison import worlds_of

    plans = [str(p) for p in map_set_files("dungeon_maps/test")[:2]]
    assert worlds_of(["dungeon_maps/test", "loop_corridor"], 2) == [*plans, "loop_corridor"]
