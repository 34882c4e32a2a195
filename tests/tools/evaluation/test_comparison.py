"""Scripted policies compared on worlds, paired by world and seed (`emmi-gym compare-policies`)."""

import numpy as np
import pytest

from emmi_gym.tools.evaluation.comparison import (
    ComparisonSettings,
    compare,
    markdown_table,
    paired,
    play_on_world,
    plot_pair,
)
from emmi_gym.tools.experiments.report import read_csv, write_csv
from emmi_gym.world.map_sets import map_set_files, world_name


def test_policies_are_paired_by_world_and_seed(tmp_path):
    worlds = [str(p) for p in map_set_files("dungeon_maps/test")[:2]]
    settings = ComparisonSettings(env_options={"max_decisions": 3})
    rows = compare(worlds, [0], ["frontier", "active_loop_closing"], settings, workers=1, progress=False)
    assert [(r["world"], r["policy"]) for r in rows] == [(world_name(w), p) for w in worlds for p in
                                                         ("frontier", "active_loop_closing")]
    assert all(r["decisions"] == 3 and 0.0 <= r["oracle_accuracy"] <= 1.0 for r in rows)
    differences = paired(rows, "ate", "active_loop_closing", "frontier")
    assert differences.shape == (2,)
    assert np.allclose(differences, [rows[1]["ate"] - rows[0]["ate"], rows[3]["ate"] - rows[2]["ate"]])
    table = markdown_table(rows, "active_loop_closing", "frontier", "test")
    assert "2 pairs" in table and "| ATE (m) |" in table
    # the same world and seed give the same episode
    again = play_on_world(worlds[0], 0, "frontier", settings, keep_maps=True)
    assert again["ate"] == rows[0]["ate"] and again["oracle_accuracy"] == rows[0]["oracle_accuracy"]
    plot_pair([again, play_on_world(worlds[0], 0, "active_loop_closing", settings, keep_maps=True)],
              tmp_path / "maps.png")
    write_csv(tmp_path / "episodes.csv", rows)  # what 'emmi-gym evaluate --out' writes reads back the same
    def nan_as_text(rows):
        return [{k: "nan" if isinstance(v, float) and np.isnan(v) else v for k, v in r.items()} for r in rows]

    assert nan_as_text(read_csv(tmp_path / "episodes.csv")) == nan_as_text(rows)
    assert (tmp_path / "maps.png").stat().st_size > 10_000


def test_worlds_of_takes_a_sets_first_maps_and_a_world_as_it_is():
    from emmi_gym.tools.evaluation.comparison import worlds_of

    plans = [str(p) for p in map_set_files("dungeon_maps/test")[:2]]
    assert worlds_of(["dungeon_maps/test", "loop_corridor"], 2) == [*plans, "loop_corridor"]


def test_compare_policies_command_writes_the_paired_table_episodes_and_maps(tmp_path, capsys):
    from emmi_gym.tools.cli import main

    worlds = [str(p) for p in map_set_files("dungeon_maps/test")[:2]]
    out = tmp_path / "out"
    assert main(["compare-policies", "--worlds", *worlds, "--seeds", "1", "--first-seed", "5", "--options",
                 '{"max_decisions": 2}', "--workers", "1", "--quiet", "--out", str(out)]) == 0
    rows = read_csv(out / "episodes.csv")
    assert [(r["world"], r["seed"], r["policy"]) for r in rows] == [(world_name(w), 5, p) for w in worlds for p in
                                                                  ("frontier", "active_loop_closing")]
    table = (out / "summary.md").read_text()
    assert "2 pairs" in table and table.strip() in capsys.readouterr().out
    assert (out / "maps.png").read_bytes().startswith(b"\x89PNG")


@pytest.mark.parametrize("argv, message", [
    (["--options", "[1]"], "--options: expected a JSON object of options"),
    (["--options", "{"], "--options"),
    (["--options", '{"max_decisions": -1}'], "max_decisions"),
    (["--env-id", "emmi_gym/Nope-v0"], "'--env-id': expected one of emmi-gym's environment ids"),
    (["--env-id", "emmi_gym/ExplorePlans-v0"], "expected the current version of emmi_gym/ExplorePlans, "
                                               "'emmi_gym/ExplorePlans-v1'"),
    (["--policies", "frontier", "nope"], "--policies: unknown ['nope']"),
])
def test_compare_policies_command_refuses_bad_options_in_one_line(tmp_path, capsys, argv, message):
    from emmi_gym.tools.cli import main

    with pytest.raises(SystemExit) as done:
        main(["compare-policies", *argv, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert done.value.code == 2 and err.startswith("emmi-gym compare-policies: error: ") and message in err, err
    assert len(err.splitlines()) == 1 and not (tmp_path / "out").exists()

