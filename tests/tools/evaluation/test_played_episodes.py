"""Evaluation episodes kept as they are played: a benchmark run again plays only the episodes it does not hold, and
what it reads back is what it would have played; files cut short or of something else are repaired or refused by
name."""

import json
import math

import pytest

from emmi_gym.tools.evaluation.comparison import ComparisonSettings
from emmi_gym.tools.evaluation.played_episodes import PlayedEpisodes, PlayedEpisodesError
from emmi_gym.tools.training import reward_benchmark
from emmi_gym.tools.training.config import parse_agent_config
from emmi_gym.tools.training.evaluate import TrainedAgent
from emmi_gym.tools.training.reward_benchmark import make_jobs, run_job

SETTINGS = ComparisonSettings("emmi_gym/ExplorePlans-v1", {"particles": 3})


def _row(world, seed, ate=0.5):
    return {"world": world, "seed": seed, "ate": ate, "sim_steps_to_target": math.nan,
            "trace": [{"sim_steps": 0.0, "ate": 0.0}, {"sim_steps": 40.0, "ate": ate}]}


def test_kept_rows_read_back_as_they_were_written(tmp_path):
    played = PlayedEpisodes.in_folder(tmp_path, "frontier", SETTINGS, "frontier")
    assert len(played) == 0 and played.get("a.png", 1) is None
    played.add(_row("a.png", 1))
    played.add(_row("a.png", 2, ate=0.25))
    again = PlayedEpisodes.in_folder(tmp_path, "frontier", SETTINGS, "frontier")
    assert len(again) == 2 and again.get("b.png", 1) is None
    # bit for bit, NaN and the trace included
    assert json.dumps(again.get("a.png", 2)) == json.dumps(_row("a.png", 2, ate=0.25))
    again.get("a.png", 1)["trace"].clear()  # a copy: the kept row stays whole
    assert len(again.get("a.png", 1)["trace"]) == 2


def test_another_evaluation_keeps_its_episodes_in_another_file(tmp_path):
    first = PlayedEpisodes.in_folder(tmp_path, "frontier", SETTINGS, "frontier")
    first.add(_row("a.png", 1))
    other_settings = ComparisonSettings(SETTINGS.env_id, {"particles": 5})
    for other in (PlayedEpisodes.in_folder(tmp_path, "frontier", other_settings, "frontier"),
                  PlayedEpisodes.in_folder(tmp_path, "frontier", SETTINGS, "random")):
        assert other.path != first.path and other.get("a.png", 1) is None
    assert PlayedEpisodes.in_folder(tmp_path, "frontier", SETTINGS, "frontier").get("a.png", 1) is not None


def test_a_trained_agent_is_its_model_files_digest(tmp_path):
    model = tmp_path / "model.zip"
    model.write_bytes(b"weights one")
    one = TrainedAgent(str(model), "agent").identity()
    model.write_bytes(b"weights two")  # trained on, at the same path
    assert TrainedAgent(str(model), "agent").identity() != one
    assert PlayedEpisodes.in_folder(tmp_path, "agent", SETTINGS, TrainedAgent(str(model))).identity["policy"] == \
        TrainedAgent(str(model)).identity()


def test_a_last_line_cut_short_is_dropped_and_the_file_goes_on(tmp_path):
    played = PlayedEpisodes.in_folder(tmp_path, "frontier", SETTINGS, "frontier")
    played.add(_row("a.png", 1))
    with open(played.path, "a") as f:
        f.write(json.dumps(_row("a.png", 2))[:30])  # killed mid-write
    again = PlayedEpisodes.in_folder(tmp_path, "frontier", SETTINGS, "frontier")
    assert len(again) == 1 and again.get("a.png", 2) is None
    again.add(_row("a.png", 2))
    assert len(PlayedEpisodes.in_folder(tmp_path, "frontier", SETTINGS, "frontier")) == 2
    played.path.write_text('{"identi')  # killed before the header was whole: started again
    fresh = PlayedEpisodes.in_folder(tmp_path, "frontier", SETTINGS, "frontier")
    fresh.add(_row("a.png", 3))
    assert len(PlayedEpisodes.in_folder(tmp_path, "frontier", SETTINGS, "frontier")) == 1


def test_a_file_that_is_not_this_evaluations_episodes_is_refused_by_line(tmp_path):
    played = PlayedEpisodes.in_folder(tmp_path, "frontier", SETTINGS, "frontier")
    played.add(_row("a.png", 1))
    whole = played.path.read_text()
    header, first = whole.splitlines()
    for text, message in ((f"{header}\nnot json\n{first}\n", "line 2: not JSON"),
                          (f"{header}\n[1, 2]\n", "line 2: a JSON object expected, found list"),
                          (f"{header}\n{{\"world\": 3, \"seed\": 1}}\n", "line 2: an episode with its world"),
                          ('{"identity": {"policy": "other"}}\n', "line 1: the identity of another evaluation")):
        played.path.write_text(text)
        with pytest.raises(PlayedEpisodesError, match="line") as error:
            PlayedEpisodes.in_folder(tmp_path, "frontier", SETTINGS, "frontier")
        assert str(played.path) in str(error.value) and message in str(error.value)
        assert played.path.read_text() == text  # nothing removed


def _config():
    return parse_agent_config({"env": {"id": "emmi_gym/ExplorePlans-v1", "kwargs": {"particles": 3,
                                                                                    "max_decisions": 2}},
                               "algorithm": "MaskablePPO", "policy": "MultiInputPolicy", "n_envs": 1,
                               "vec_env": "dummy", "total_timesteps": 16, "eval": {"freq": 0}})


def _rows(out, plans):
    (job,) = make_jobs(_config(), [], range(0), 16, plans, ["frontier"], out, eval_seed=70, seeds_per_plan=2)
    return run_job(job)


def test_a_benchmark_run_again_plays_only_the_episodes_it_does_not_hold(tmp_path, monkeypatch):
    """An evaluation stopped after one plan (two seeds) and run again to two plans plays the second plan's two
    episodes alone, and its rows are those of the same evaluation played whole into another folder."""
    whole = _rows(tmp_path / "whole", 2)
    first = _rows(tmp_path / "resumed", 1)
    assert (len(first["rows"]), first["kept_episodes"]) == (2, 0)
    played = []
    original = reward_benchmark.play_on_world

    def counted(world, seed, *args, **kwargs):
        played.append(seed)
        return original(world, seed, *args, **kwargs)

    monkeypatch.setattr(reward_benchmark, "play_on_world", counted)
    resumed = _rows(tmp_path / "resumed", 2)
    assert len(played) == 2 and resumed["kept_episodes"] == 2
    assert json.dumps(resumed["rows"]) == json.dumps(whole["rows"])
    again = _rows(tmp_path / "resumed", 2)
    assert len(played) == 2 and again["kept_episodes"] == 4
    assert json.dumps(again["rows"]) == json.dumps(whole["rows"])


class _OwnPolicy:
    """A policy object of a user's own that does not say what it plays (no ``identity()``)."""

    name = "own"

    def make_actor(self):
        from emmi_gym.tools.evaluation.comparison import make_actor

        return make_actor("frontier")


def test_a_policy_that_does_not_say_what_it_plays_is_played_every_time(tmp_path):
    from dataclasses import replace

    (job,) = make_jobs(_config(), [], range(0), 16, 1, ["frontier"], tmp_path, eval_seed=70)
    own = replace(job, policy=_OwnPolicy())
    assert [run_job(own)["kept_episodes"] for _ in range(2)] == [0, 0]
    assert not (tmp_path / "played").exists()
