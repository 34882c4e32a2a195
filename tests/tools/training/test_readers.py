"""The files the training side reads back (demonstrations, training.yaml, model zips, the tools' CSVs) and the
tools that read them: hostile or broken input is a clear error naming the file and the field or member, read
in bounded memory, before any work and without replacing earlier results."""

import io
import json
import tracemalloc
import zipfile

import numpy as np
import pytest
import yaml

from emmi_gym.inputs.csv_files import CsvFileError, read_csv_file
from emmi_gym.tools.cli import main as emmi_gym
from emmi_gym.tools.training import checkpoint_scores
from emmi_gym.tools.training.config import parse_agent_config
from emmi_gym.tools.training.demonstrations import Demonstrations, DemonstrationsError
from emmi_gym.tools.training.run_folders import RunFolder
from emmi_gym.tools.training.run_folders.model_files import ModelFileError, check_model_file
from emmi_gym.tools.training.run_folders.training_record import TrainingRecordError
from emmi_gym.tools.training.train import train

MEASURES = "timesteps,oracle_accuracy,ate,sim_steps,coverage\n"
CURVE = MEASURES + "8,0.5,0.2,100,0.4\n16,0.6,0.1,90,0.5\n"


def one_line_error(capsys, main, argv) -> str:
    """The message of a tool that refused ``argv``: exit status 2, no traceback, the error in one line (after
    argparse's usage, where it is argparse that refuses)."""
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err and (len(err.splitlines()) == 1 or err.startswith("usage:")), err
    return err.splitlines()[-1]


# --------------------------------------------------------------------------- CSV files and the tools


@pytest.mark.parametrize("content, expected", [
    (b"", r"expected a curve: a header line naming its columns, then a row per line \(the file is empty\)"),
    (b"timesteps,ate\n", r"expected a curve with at least one row below its header \(it holds only the header\)"),
    (b"step,ate\n1,2\n", r"expected a curve with the columns \['timesteps'\] \(its header names \['step', 'ate'\]\)"),
    (b"timesteps,ate\n1,2,3\n", r"curve\.csv:2: expected 2 fields, as the header names, got '3 fields'"),
    (b"timesteps,ate\n1,fast\n", r"curve\.csv:2: field 'ate': expected a number \(or an empty cell\), got 'fast'"),
    (b"timesteps,ate\n1,\"" + b"x" * 131_100 + b"\"\n", r"curve\.csv:2: expected a curve in CSV \(field larger than"),
    ("timesteps,ate\n1,2\n".encode("utf-16"), r"expected UTF-8 text \(the file is UTF-16"),
    (b"timesteps,ate\n1,\xff\n", r"expected UTF-8 text \(byte 16 is not UTF-8\)"),
    (b"\x89PNG\r\n\x1a\n\0\0", r"expected a text file \(byte 8 is NUL: a binary file\?\)"),
])
def test_the_csv_reader_names_the_file_line_and_column(tmp_path, content, expected):
    path = tmp_path / "curve.csv"
    path.write_bytes(content)
    with pytest.raises(CsvFileError, match=expected):
        read_csv_file(path, "curve", required=["timesteps"], numeric=["ate"])


def test_the_csv_reader_reads_numbers_and_empty_cells(tmp_path):
    (tmp_path / "c.csv").write_text("policy,ate\nfrontier,0.5\nrandom,\n\n")
    rows = read_csv_file(tmp_path / "c.csv", "curve", required=["policy"], numeric=["ate"])
    assert rows[0] == {"policy": "frontier", "ate": 0.5} and np.isnan(rows[1]["ate"]) and len(rows) == 2


@pytest.mark.parametrize("content, expected", [
    ("", "the file is empty"),
    (MEASURES, "it holds only the header"),
    (MEASURES + "8,nan,nan,nan,nan\n16,,,,\n", "field 'oracle_accuracy': expected a finite value in at least one row"),
    ("timesteps,ate\n8,0.1\n", "with the columns ['oracle_accuracy', 'sim_steps', 'coverage']"),
])
def test_learning_curves_refuses_files_that_would_draw_blank_axes(tmp_path, capsys, content, expected):
    (tmp_path / "eval_ground_truth.csv").write_text(content)
    err = one_line_error(capsys, emmi_gym, ["learning-curves", str(tmp_path), "--out", str(tmp_path / "c.png")])
    assert f"emmi-gym learning-curves: error: {tmp_path / 'eval_ground_truth.csv'}: " in err and expected in err
    assert not (tmp_path / "c.png").exists()


def test_learning_curves_checks_baselines_and_names_the_file_it_wrote(tmp_path, capsys):
    (tmp_path / "eval_ground_truth.csv").write_text(CURVE)
    (tmp_path / "garbage.csv").write_bytes(b"\x00\x01garbage")
    err = one_line_error(capsys, emmi_gym, ["learning-curves", str(tmp_path), "--out", str(tmp_path / "c"),
                                                         "--baselines-csv", str(tmp_path / "garbage.csv")])
    assert f"{tmp_path / 'garbage.csv'}: expected a text file" in err
    (tmp_path / "other.csv").write_text("policy," + MEASURES.split(",", 1)[1] + "agent,0.5,0.2,100,0.4\n")
    err = one_line_error(capsys, emmi_gym, ["learning-curves", str(tmp_path), "--out", str(tmp_path / "c"),
                                                         "--baselines-csv", str(tmp_path / "other.csv")])
    assert "field 'policy': expected episodes of at least one of ['frontier', 'active_loop_closing', 'random', " \
           "'close_loop_first', 'explore_first'], got ['agent']" in err
    (tmp_path / "episodes.csv").write_text("policy," + MEASURES.split(",", 1)[1] + "frontier,0.5,0.2,100,0.4\n")
    assert emmi_gym(["learning-curves", f"{tmp_path}=run", "--out", str(tmp_path / "c"), "--baselines-csv",
                                 str(tmp_path / "episodes.csv")]) == 0
    assert capsys.readouterr().out.strip() == f"wrote {tmp_path / 'c.png'}"
    assert (tmp_path / "c.png").read_bytes().startswith(b"\x89PNG")


def test_learning_curves_draw_runs_of_one_label_at_their_mean_decision_counts(tmp_path, monkeypatch):
    import matplotlib.axes

    drawn = []
    original = matplotlib.axes.Axes.plot
    monkeypatch.setattr(matplotlib.axes.Axes, "plot",
                        lambda ax, x, y, *a, **k: drawn.append((list(x), list(y))) or original(ax, x, y, *a, **k))
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    (tmp_path / "a" / "eval_ground_truth.csv").write_text(MEASURES + "1000,0.5,0.2,100,0.4\n2000,0.6,0.2,100,0.4\n"
                                                          "3000,0.7,0.2,100,0.4\n3072,0.7,0.2,100,0.4\n")
    (tmp_path / "b" / "eval_ground_truth.csv").write_text(MEASURES + "1140,0.7,0.2,100,0.4\n2140,0.8,0.2,100,0.4\n"
                                                          "3060,0.9,0.2,100,0.4\n")  # resumed between rollouts
    assert emmi_gym(["learning-curves", f"{tmp_path / 'a'}=emmi", f"{tmp_path / 'b'}=emmi",
                     "--out", str(tmp_path / "c.png")]) == 0
    steps, accuracy = drawn[0]  # the first measure's line
    assert steps == pytest.approx([1070, 2070, 3030]) and accuracy == pytest.approx([0.6, 0.7, 0.8])


def test_learning_curves_average_runs_of_one_label_only_over_evaluations_each_made(tmp_path, monkeypatch):
    import matplotlib.axes

    drawn = []
    original = matplotlib.axes.Axes.plot
    monkeypatch.setattr(matplotlib.axes.Axes, "plot",
                        lambda ax, x, y, *a, **k: drawn.append((list(x), list(y))) or original(ax, x, y, *a, **k))
    for run, rows in (("a", "2500,0.5,0.2,100,0.4\n5000,0.6,0.2,100,0.4\n7500,0.7,0.2,100,0.4\n"
                             "10000,0.8,0.2,100,0.4\n"),
                      ("b", "2500,0.7,0.2,100,0.4\n5000,0.8,0.2,100,0.4\n10000,0.6,0.2,100,0.4\n")):  # lacks 7500
        (tmp_path / run).mkdir()
        (tmp_path / run / "eval_ground_truth.csv").write_text(MEASURES + rows)
    assert emmi_gym(["learning-curves", f"{tmp_path / 'a'}=emmi", f"{tmp_path / 'b'}=emmi",
                     "--out", str(tmp_path / "c.png")]) == 0
    steps, accuracy = drawn[0]
    assert steps == pytest.approx([2500, 5000, 10000]) and accuracy == pytest.approx([0.6, 0.7, 0.7])


def test_learning_curves_read_the_loop_order_where_the_files_have_it(tmp_path):
    from emmi_gym.tools.training.learning_curves import read_baselines, read_curve

    (tmp_path / "curve.csv").write_text(MEASURES.rstrip("\n") + ",closed_loop_first\n8,0.5,0.2,100,0.4,0.25\n")
    (tmp_path / "episodes.csv").write_text("variant," + MEASURES.split(",", 1)[1].rstrip("\n") + ",closed_loop_first\n"
                                           "close_loop_first,0.5,0.2,100,0.4,1.0\nexplore_first,0.5,0.2,100,0.4,\n")
    assert read_curve(tmp_path / "curve.csv")["closed_loop_first"].tolist() == [0.25]
    (tmp_path / "plain.csv").write_text(CURVE)
    assert "closed_loop_first" not in read_curve(tmp_path / "plain.csv")
    means = read_baselines(tmp_path / "episodes.csv")
    assert means["close_loop_first"]["closed_loop_first"] == 1.0
    assert np.isnan(means["explore_first"]["closed_loop_first"])


def test_learning_curves_checks_its_output_and_run_folders_first(tmp_path, capsys):
    (tmp_path / "a_file").write_text("x")
    err = one_line_error(capsys, emmi_gym, ["learning-curves", str(tmp_path / "missing"), "--out",
                                                         str(tmp_path / "a_file" / "c.png")])
    assert err.endswith(f"--out {tmp_path / 'a_file'}: expected a folder that can be made and written to; "
                        f"{tmp_path / 'a_file'} is a regular file, not a folder")  # not the missing run folder
    err = one_line_error(capsys, emmi_gym, ["learning-curves", str(tmp_path / "missing"), "--out",
                                            str(tmp_path / "c.png")])
    assert err.endswith(f"run folder {tmp_path / 'missing'} does not exist")
    (tmp_path / "eval_ground_truth.csv").write_text(CURVE)
    err = one_line_error(capsys, emmi_gym, ["learning-curves", str(tmp_path), "--out", str(tmp_path / "c.xyz")])
    assert f"--out {tmp_path / 'c.xyz'}: expected a figure file named *." in err


@pytest.mark.parametrize("episodes", ["0", "-1", "100001", "ten"])
def test_score_checkpoints_refuses_episode_counts_at_parse_time_leaving_results(tmp_path, capsys, episodes):
    (tmp_path / "checkpoint_scores.csv").write_text(CURVE)
    err = one_line_error(capsys, emmi_gym, ["score-checkpoints", str(tmp_path), "--episodes", episodes])
    assert f"argument --episodes: expected an integer in [1, 100000], got '{episodes}'" in err
    assert (tmp_path / "checkpoint_scores.csv").read_text() == CURVE


def test_score_checkpoints_says_which_is_missing_in_one_line(tmp_path, capsys):
    err = one_line_error(capsys, emmi_gym, ["score-checkpoints", str(tmp_path / "nowhere")])
    assert err == f"emmi-gym score-checkpoints: error: run folder {tmp_path / 'nowhere'} does not exist"
    (tmp_path / "run").mkdir()
    err = one_line_error(capsys, emmi_gym, ["score-checkpoints", str(tmp_path / "run")])
    assert err == (f"emmi-gym score-checkpoints: error: no checkpoint in {tmp_path / 'run' / 'checkpoints'}: was "
                   f"{tmp_path / 'run'} written by 'emmi-gym train'?")
    with pytest.raises(ValueError, match=r"episodes: expected an integer in \[1, 100000\], got 0"):
        checkpoint_scores.score_checkpoints(tmp_path / "run", episodes=0)


# --------------------------------------------------------------------------- training.yaml

RECORD = "timesteps: 16\nwall_seconds: 4.5\nmachine: a machine\n"


@pytest.mark.parametrize("content, expected", [
    ("\0\1garbage", r"training\.yaml: expected a text file \(byte 0 is NUL"),
    ("- 1\n- 2\n", r"training\.yaml: expected a mapping of training record fields at the top level, not a list"),
    ("wall_seconds: " + "[" * 100_000 + "]" * 100_000 + "\n", r"training\.yaml:1:\d+: expected valid YAML: lists and "
                                                              r"mappings nested at most 32 deep"),
    ("wall_seconds: abc\n", r"training\.yaml: field 'wall_seconds': expected a finite number in \[0, inf\), got 'abc'"),
    ("wall_seconds: -100000\n", r"field 'wall_seconds': expected a finite number in \[0, inf\), got -100000"),
    ("wall_seconds: .nan\n", r"field 'wall_seconds': expected a finite number in \[0, inf\), got nan"),
    ("timesteps: 1.5\n", r"field 'timesteps': expected an integer in \[0, \d+\], got 1\.5"),
    ("steps: 3\n", r"field 'steps': expected one of the known options"),
])
def test_a_damaged_training_record_names_the_file_and_field(tmp_path, content, expected):
    (tmp_path / "training.yaml").write_text(content)
    with pytest.raises(TrainingRecordError, match=expected):
        RunFolder(tmp_path).record()


@pytest.mark.slow
def test_a_damaged_training_record_stops_training_before_it_starts(tmp_path):
    config = {"env": {"id": "emmi_gym/LoopCorridor-v1", "kwargs": {"particles": 3, "max_decisions": 3}},
              "algorithm": "MaskablePPO", "policy": "MultiInputPolicy",
              "hyperparameters": {"n_steps": 4, "batch_size": 4, "n_epochs": 1, "policy_kwargs": {"net_arch": [8]}},
              "n_envs": 1, "vec_env": "dummy", "total_timesteps": 4, "seed": 3, "eval": {"freq": 0},
              "checkpoint_freq": 4}
    run = tmp_path / "run"
    train(parse_agent_config(config), run, progress=False)
    assert RunFolder(run).record()["timesteps"] == 4 and set(RunFolder(run).record()) >= {"wall_seconds", "machine"}
    model = (run / "model.zip").read_bytes()
    (run / "training.yaml").write_text("wall_seconds: -100000\n")
    with pytest.raises(TrainingRecordError, match=r"training\.yaml: field 'wall_seconds'"):
        train(parse_agent_config(dict(config, total_timesteps=8)), run, resume=True, progress=False)
    assert (run / "model.zip").read_bytes() == model and sorted(p.name for p in (run / "checkpoints").iterdir()) == [
        "model_4_steps.zip"]  # nothing trained, nothing written


# --------------------------------------------------------------------------- model zips


@pytest.fixture(scope="module")
def saved_model(tmp_path_factory):
    """The members of a small PPO model as SB3 saves them, and its run's configuration."""
    import gymnasium as gym
    from stable_baselines3 import PPO

    folder = tmp_path_factory.mktemp("model")
    PPO("MultiInputPolicy", gym.make("emmi_gym/LoopCorridor-v1", particles=3), n_steps=16, batch_size=16,
        policy_kwargs={"net_arch": [8]}).save(folder / "model.zip")
    with zipfile.ZipFile(folder / "model.zip") as archive:
        return {name: archive.read(name) for name in archive.namelist()}


def write_zip(path, members: dict):
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return path


def test_a_model_whose_data_nests_200000_deep_is_refused_before_json_reads_it(tmp_path, saved_model):
    data = json.loads(saved_model["data"])
    data["deep"] = "x"
    text = json.dumps(data).replace('"x"', "[" * 200_000 + "]" * 200_000)
    model = write_zip(tmp_path / "model.zip", dict(saved_model, data=text))
    with pytest.raises(ModelFileError, match=rf"{model}: expected a 'data' member of JSON, as Stable-Baselines3 "
                                             r"writes it, nested at most 100 deep, got '200,00\d deep'"):
        check_model_file(model, "PPO")


@pytest.mark.parametrize("weights", [b"garbage" * 1000, b"\x80\x04" + b"(" * 100_000])
def test_a_model_whose_weights_are_not_torchs_names_the_member(tmp_path, saved_model, weights):
    model = write_zip(tmp_path / "model.zip", dict(saved_model, **{"policy.pth": weights}))
    with pytest.raises(ModelFileError, match=rf"{model}: field 'policy\.pth': expected PyTorch weights as torch\.save"):
        check_model_file(model, "PPO")


def test_weights_in_torchs_format_that_torch_cannot_load_name_the_file(tmp_path, saved_model):
    import pickle

    from emmi_gym.tools.training.run_folders.model_files import load_model_file

    weights = io.BytesIO()
    with zipfile.ZipFile(weights, "w") as archive:  # torch.save's layout, a pickle torch's weights-only loader refuses
        archive.writestr("archive/data.pkl", pickle.dumps(print, protocol=2))
        archive.writestr("archive/version", "3\n")
    model = write_zip(tmp_path / "model.zip", dict(saved_model, **{"policy.pth": weights.getvalue()}))
    with pytest.raises(ModelFileError, match=rf"{model}: expected a PPO model that Stable-Baselines3 can load "
                                             r"\((UnpicklingError|RuntimeError): "):
        load_model_file(model, "PPO")


def test_a_model_with_a_bad_crc_is_named_damaged(tmp_path, saved_model, capsys):
    model = write_zip(tmp_path / "model.zip", {name: data for name, data in saved_model.items()})
    raw = bytearray(model.read_bytes())
    with zipfile.ZipFile(model) as archive:
        info = archive.getinfo("policy.pth")
    crc_at = info.header_offset + 14  # the local header's CRC-32
    raw[crc_at:crc_at + 4] = bytes(4)
    central = raw.rfind(info.filename.encode(), 0, len(raw)) - 46 + 16  # the central directory's CRC-32
    raw[central:central + 4] = bytes(4)
    model.write_bytes(bytes(raw))
    with pytest.raises(ModelFileError, match=rf"{model}: field 'policy\.pth': expected an undamaged member \(its "
                                             r"CRC-32 does not match its data: the file is damaged\)"):
        check_model_file(model, "PPO")
    (tmp_path / "config.yaml").write_text(yaml.safe_dump({"env": {"id": "emmi_gym/LoopCorridor-v1"},
                                                          "algorithm": "PPO", "policy": "MultiInputPolicy"}))
    err = one_line_error(capsys, emmi_gym, ["evaluate", str(model), "--episodes", "1"])
    assert "CRC-32 does not match" in err and "wasn't a zip-file" not in err


# --------------------------------------------------------------------------- demonstrations


def demonstrations(n=4, slots=8, **changes):
    arrays = {"masks": np.ones((n, slots), bool), "actions": np.arange(n, dtype=np.int64) % slots,
              "episodes": np.int64(1), "obs_map": np.zeros((n, 2, 8, 8), np.uint8),
              "obs_pose": np.zeros((n, 3), np.float32)}
    arrays.update(changes)
    return {name: value for name, value in arrays.items() if value is not None}


@pytest.mark.parametrize("changes, expected", [
    ({"masks": np.ones((4, 8), np.float32)}, r"field 'masks': expected a 2-D array of booleans \(decisions x actions\)"
                                             r", got 'shape \(4, 8\), float32'"),
    ({"masks": np.ones(4, bool)}, r"field 'masks': expected a 2-D array of booleans"),
    ({"actions": np.int64(3)}, r"field 'actions': expected a 1-D array of integers"),
    ({"actions": np.array(["a", "b", "c", "d"])}, r"field 'actions': expected an array of numbers or booleans, "
                                                  r"got 'dtype <U1'"),
    ({"actions": np.arange(4.0)}, r"field 'actions': expected a 1-D array of integers .*float64"),
    ({"episodes": np.zeros(2, np.int64)}, r"field 'episodes': expected an integer \(0-D array\)"),
    ({"episodes": np.int64(0)}, r"field 'episodes': expected at least one episode played, got 0"),
    ({"obs_pose": np.zeros((4, 3), object)}, r"field 'obs_pose': expected an array of numbers or booleans, got "
                                             r"'dtype object'"),
    ({"obs_pose": np.zeros((3, 3), np.float32)}, r"field 'obs_pose': expected a row per decision, 4 as there are"),
    ({"obs_pose": np.full((4, 3), np.inf, np.float32)}, r"field 'obs_pose': expected finite observations, got 'NaN "
                                                        r"or infinity in decision 0'"),
    ({"obs_map": None, "obs_pose": None}, r"field 'obs_\*': expected at least one array of observations"),
    ({"actions": np.full(4, 9)}, r"field 'actions': expected every action to be a slot its mask allows"),
    ({"weights": np.zeros(3)}, r"field 'weights': expected only the arrays masks, actions, episodes and obs_\*"),
])
def test_bad_demonstrations_name_the_file_and_member(tmp_path, changes, expected):
    np.savez(tmp_path / "demos.npz", **demonstrations(**changes))
    with pytest.raises(DemonstrationsError, match=rf"demos\.npz: {expected}"):
        Demonstrations.load(tmp_path / "demos.npz")


def test_zero_decisions_are_refused(tmp_path):
    np.savez(tmp_path / "demos.npz", **demonstrations(n=0))
    with pytest.raises(DemonstrationsError, match=r"demos\.npz: field 'actions': expected at least one decision"):
        Demonstrations.load(tmp_path / "demos.npz")


def npy_with_header(shape, dtype="|u1", data=b"") -> bytes:
    """A .npy member whose header declares ``shape`` (whatever data follows)."""
    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, {"descr": dtype, "fortran_order": False, "shape": shape})
    return buffer.getvalue() + data


def test_a_header_declaring_a_trillion_rows_is_refused_before_anything_is_allocated(tmp_path):
    members = {f"{name}.npy": buffer for name, buffer in _npy_members(demonstrations()).items()}
    members["obs_map.npy"] = npy_with_header((10**12, 2, 8, 8), data=bytes(512))
    write_zip(tmp_path / "huge.npz", members)
    tracemalloc.start()
    with pytest.raises(DemonstrationsError, match=r"huge\.npz: field 'obs_map': expected an array of the "
                                                  r"128,000,000,000,\d+ bytes its header declares"):
        Demonstrations.load(tmp_path / "huge.npz")
    assert tracemalloc.get_traced_memory()[1] < 10e6
    tracemalloc.stop()


def _npy_members(arrays: dict) -> dict:
    members = {}
    for name, value in arrays.items():
        buffer = io.BytesIO()
        np.save(buffer, value)
        members[name] = buffer.getvalue()
    return members


def test_files_that_do_not_match_name_the_file_and_member(tmp_path):
    np.savez(tmp_path / "a.npz", **demonstrations())
    np.savez(tmp_path / "b.npz", **demonstrations(obs_map=np.zeros((4, 2, 16, 16), np.uint8)))
    with pytest.raises(DemonstrationsError, match=r"b\.npz: field 'obs_map': expected the members and shapes of "
                                                  r".*a\.npz"):
        Demonstrations.load(tmp_path / "a.npz", tmp_path / "b.npz")
    np.savez(tmp_path / "c.npz", **demonstrations(masks=np.ones((4, 9), bool)))
    with pytest.raises(DemonstrationsError, match=r"c\.npz: field 'masks': expected the members and shapes of"):
        Demonstrations.load(tmp_path / "a.npz", tmp_path / "c.npz")


def test_demonstration_files_are_read_once_into_one_set_of_arrays(tmp_path):
    big = demonstrations(n=2000, obs_map=np.zeros((2000, 2, 64, 64), np.uint8))  # 16 MB of observations
    np.savez_compressed(tmp_path / "a.npz", **big)
    np.savez_compressed(tmp_path / "b.npz", **demonstrations(n=3, obs_map=np.ones((3, 2, 64, 64), np.uint8)))
    tracemalloc.start()
    one = Demonstrations.load(tmp_path / "a.npz")
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 1.5 * big["obs_map"].nbytes  # np.load, then a join, took twice that
    assert Demonstrations.joined([one]) is one
    both = Demonstrations.load(tmp_path / "a.npz", tmp_path / "b.npz")
    assert len(both) == 2003 and both.episodes == 2 and both.observations["map"][2000:].all()
    assert np.array_equal(both.actions, np.concatenate([big["actions"], np.arange(3) % 8]))
    assert len(Demonstrations.load(tmp_path / "b.npz", tmp_path / "b.npz")) == 6  # given twice, fitted twice


def test_a_damaged_demonstrations_member_is_named(tmp_path):
    noise = np.random.default_rng(0).integers(0, 255, (500, 2, 8, 8), dtype=np.uint8)  # compresses to about itself
    np.savez_compressed(tmp_path / "demos.npz", **demonstrations(n=500, obs_map=noise))
    raw = bytearray((tmp_path / "demos.npz").read_bytes())
    with zipfile.ZipFile(tmp_path / "demos.npz") as archive:
        info = archive.getinfo("obs_map.npy")
    middle = info.header_offset + 30 + len(info.filename) + info.compress_size // 2
    raw[middle] ^= 0xFF
    (tmp_path / "demos.npz").write_bytes(bytes(raw))
    with pytest.raises(DemonstrationsError, match=r"demos\.npz: field 'obs_map': expected an undamaged member \(its "
                                                  r"CRC-32 does not match its data: the file is damaged\)"):
        Demonstrations.load(tmp_path / "demos.npz")


# --------------------------------------------------------------------------- episode counts


@pytest.mark.parametrize("argv", [["clone", "agent.yaml", "--out", "x", "--episodes", str(10**9)],
                                  ["evaluate", "model.zip", "--episodes", str(10**9), "--baselines", "frontier"]])
def test_a_billion_episodes_is_refused_at_parse_time(capsys, argv):
    with pytest.raises(SystemExit) as exit_info:
        emmi_gym(argv)
    assert exit_info.value.code == 2
    assert "argument --episodes: expected an integer in [1, 100000], got '1000000000'" in capsys.readouterr().err


def test_episodes_are_made_when_asked_for():
    from emmi_gym.tools.evaluation.comparison import episodes_on

    tracemalloc.start()
    episodes = episodes_on(None, 10**9, 7)
    assert len(episodes) == 10**9 and episodes[10**9 - 1] == (None, 10**9 + 6)
    assert tracemalloc.get_traced_memory()[1] < 1e6
    tracemalloc.stop()
    on_set = episodes_on("dungeon_maps/test", 3, 5)
    assert [seed for _, seed in on_set] == [5, 5, 5] and len({world for world, _ in on_set}) == 3


@pytest.mark.slow
def test_jobs_from_a_generator_run_in_worker_processes():
    from emmi_gym.concurrency.parallel import run_in_processes

    jobs = (-k for k in range(40))  # a generator: taken a few jobs per worker at a time
    assert sorted(run_in_processes(abs, jobs, total=40, workers=2, progress=False)) == list(range(40))


class _MakesAFolder:
    """A pickle that, unpickled, makes the folder ``path``: code a model file runs."""

    def __init__(self, path):
        self.path = str(path)

    def __reduce__(self):
        import os

        return os.mkdir, (self.path,)


def test_a_model_whose_pickles_name_other_code_is_refused_unless_trusted(tmp_path, saved_model, monkeypatch):
    import base64
    import pickle

    from emmi_gym.tools.training.run_folders.model_files import TRUST_VARIABLE, load_model_file, trust_model_files

    monkeypatch.delenv(TRUST_VARIABLE, raising=False)
    ran = tmp_path / "ran"
    data = json.loads(saved_model["data"])
    data["lr_schedule"] = {":type:": "<class 'function'>",
                           ":serialized:": base64.b64encode(pickle.dumps(_MakesAFolder(ran), protocol=4)).decode()}
    model = write_zip(tmp_path / "model.zip", dict(saved_model, data=json.dumps(data)))
    with pytest.raises(ModelFileError, match=rf"{model}: field 'data\.lr_schedule': expected a pickle naming only "
                                             r"classes of stable_baselines3, .*pass --trust-model.*got "
                                             r"'(posix|os)\.mkdir'"):
        load_model_file(model, "PPO")
    assert not ran.exists()
    trust_model_files([tmp_path])  # what --trust-model does: SB3 unpickles it, and the pickle runs
    load_model_file(model, "PPO")
    assert ran.is_dir()


def test_the_shipped_agents_load_with_nothing_trusted_and_sb3_unpickles_none(monkeypatch):
    from stable_baselines3.common import save_util

    from emmi_gym import pretrained
    from emmi_gym.tools.training.run_folders.model_files import TRUST_VARIABLE

    monkeypatch.delenv(TRUST_VARIABLE, raising=False)
    monkeypatch.setattr(save_util.cloudpickle, "loads", lambda *_: pytest.fail("SB3 unpickled a member itself"))
    for name in pretrained.names():
        assert pretrained.load(name).policy is not None

