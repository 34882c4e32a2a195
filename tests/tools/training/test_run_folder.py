"""The run-folder type itself (:class:`~emmi_gym.tools.training.run_folders.RunFolder`): a new run into a folder in
use is refused, overwriting removes the run's files and nothing else, a resumed run must bring its own configuration,
and the run goes on from its newest checkpoint that loads, a damaged one skipped."""

from dataclasses import replace
from pathlib import Path

import pytest
from test_training import config_dict

from emmi_gym.tools.training.config import parse_agent_config
from emmi_gym.tools.training.run_folders import RunError, RunFolder
from emmi_gym.tools.training.train import make_vec_env, model_of

PPO_SMALL = {"n_steps": 16, "batch_size": 16, "n_epochs": 1}


@pytest.fixture(scope="module")
def config():
    return parse_agent_config(config_dict("PPO", hyper=PPO_SMALL, timesteps=64, checkpoint_freq=16))


@pytest.fixture(scope="module")
def model(config):
    """A fresh (untrained) model of ``config``, saved as a run's checkpoints are."""
    env = make_vec_env(config, 1, config.seed, "dummy")
    try:
        yield model_of(config, env)
    finally:
        env.close()


def save(model, folder: RunFolder, *decisions: int) -> None:
    """``model`` saved as the checkpoints of ``folder`` at ``decisions``."""
    folder.checkpoint_dir.mkdir(parents=True, exist_ok=True)
    for count in decisions:
        model.save(folder.checkpoint_path(count))


def test_a_new_run_is_created_in_an_empty_or_missing_folder(tmp_path, config):
    folder = RunFolder(tmp_path / "run")
    start = folder.plan(config)
    assert start.model is None and not start.overwrite and folder.entries() == []  # nothing written by the checks
    folder.write_config(config)
    assert folder.entries() == ["config.yaml"] and folder.config().as_yaml_dict() == config.as_yaml_dict()
    assert RunFolder.config_of_model(folder.checkpoint_path(16)).source == str(folder.config_path)  # the run above
    assert folder.record() is None and folder.checkpoints() == [] and folder.latest_checkpoint() is None


def test_a_folder_that_holds_anything_is_refused_unless_overwritten(tmp_path, config):
    (tmp_path / "notes.txt").write_text("mine")
    folder = RunFolder(tmp_path)
    with pytest.raises(RunError, match=rf"{tmp_path} is not empty \(it holds notes\.txt\): a new run would overwrite "
                                       r"what is there; continue the run in it with --resume, replace it with "
                                       r"--overwrite, or give another --out"):
        folder.plan(config)
    with pytest.raises(RunError, match=r"--resume: .* holds no run to continue \(no config\.yaml; the folder holds "
                                       r"notes\.txt\)"):
        folder.plan(config, resume=True)
    with pytest.raises(RunError, match="give one of them"):
        folder.plan(config, resume=True, overwrite=True)
    assert folder.plan(config, overwrite=True).overwrite


def test_overwriting_removes_the_run_s_files_and_nothing_else(tmp_path, config, model):
    folder = RunFolder(tmp_path)
    folder.write_config(config)
    save(model, folder, 16)
    (tmp_path / "tb").mkdir()
    (tmp_path / "notes.txt").write_text("mine")
    folder.clear()
    assert folder.entries() == ["notes.txt"]


def test_an_input_among_the_files_overwriting_removes_is_refused(tmp_path, config, model):
    folder = RunFolder(tmp_path)
    save(model, folder, 16)
    with pytest.raises(RunError, match=rf"--init-from {folder.checkpoint_path(16)} is a file of the run in "
                                       rf"{tmp_path}, which --overwrite would remove before it is read"):
        folder.plan(config, overwrite=True, init_from=folder.checkpoint_path(16))
    assert folder.checkpoints() == [(16, folder.checkpoint_path(16))]


def test_resume_needs_the_run_s_own_configuration_but_its_budget_and_schedules(tmp_path, config, model):
    folder = RunFolder(tmp_path)
    folder.write_config(config)
    save(model, folder, 16)
    more = replace(config, total_timesteps=128, checkpoint_freq=32, source="more.yaml")
    start = folder.plan(more, resume=True)
    assert start.model == folder.checkpoint_path(16) and start.init_from is None
    other = replace(config, seed=4, source="other.yaml")
    with pytest.raises(RunError, match=rf"--resume: other\.yaml is not the configuration of the run in {tmp_path} "
                                       rf"\({folder.config_path}\): seed: 3 in the run, 4 in other\.yaml"):
        folder.plan(other, resume=True)
    assert folder.differences(other) == {"seed": (3, 4)}


def test_the_latest_loadable_checkpoint_skips_a_damaged_one(tmp_path, config, model):
    folder = RunFolder(tmp_path)
    folder.write_config(config)
    save(model, folder, 16, 32)
    folder.checkpoint_path(48).write_bytes(folder.checkpoint_path(32).read_bytes()[:-200])  # cut short by a kill
    assert [decisions for decisions, _ in folder.checkpoints()] == [16, 32, 48]
    with pytest.warns(UserWarning, match=r"skipping the damaged checkpoint .*model_48_steps\.zip"):
        assert folder.latest_checkpoint(config.algorithm) == folder.checkpoint_path(32)
    with pytest.warns(UserWarning, match="skipping the damaged checkpoint"):
        assert folder.plan(config, resume=True).model == folder.checkpoint_path(32)


def files_of(folder: RunFolder) -> dict:
    return {path: path.read_bytes() for path in sorted(folder.path.rglob("*")) if path.is_file()}


def test_resume_refuses_a_run_whose_models_are_of_another_algorithm_than_its_config(tmp_path, model):
    dqn = parse_agent_config(config_dict("DQN", env_extra={"velocity_actions": "discrete"},
                                         hyper={"buffer_size": 500, "learning_starts": 32}, timesteps=64,
                                         checkpoint_freq=16))
    folder = RunFolder(tmp_path)
    folder.write_config(dqn)  # a PPO run whose config.yaml was replaced by a DQN one
    save(model, folder, 16, 32)
    model.save(folder.model_path)
    before = files_of(folder)
    with pytest.warns(UserWarning, match="skipping the damaged checkpoint"), \
            pytest.raises(RunError, match=rf"--resume: none of the 3 model files of the run in {tmp_path} is a whole "
                                          rf"DQN model, as its config\.yaml names \(the last: {folder.model_path}: "
                                          r"expected a DQN model.*a PPO or A2C policy\).*--overwrite"):
        folder.plan(dqn, resume=True)
    assert files_of(folder) == before


def test_resume_refuses_a_run_whose_every_model_file_is_damaged(tmp_path, config, model):
    folder = RunFolder(tmp_path)
    folder.write_config(config)
    save(model, folder, 16, 32)
    model.save(folder.model_path)
    for path in [folder.checkpoint_path(16), folder.checkpoint_path(32), folder.model_path]:
        path.write_bytes(path.read_bytes()[:5000])
    before = files_of(folder)
    with pytest.warns(UserWarning, match="skipping the damaged checkpoint"), \
            pytest.raises(RunError, match=rf"none of the 3 model files of the run in {tmp_path} is a whole PPO model.*"
                                          rf"{folder.model_path} \(not a whole zip archive\).*Start the run over with "
                                          r"--overwrite"):
        folder.plan(config, resume=True)
    assert files_of(folder) == before


def test_resume_of_a_run_stopped_before_its_first_checkpoint_starts_a_fresh_model(tmp_path, config):
    folder = RunFolder(tmp_path)
    folder.write_config(config)  # nothing saved yet: nothing of the run would be lost
    assert folder.plan(config, resume=True).model is None


def test_a_finished_run_is_already_trained_to_its_budget_and_not_to_a_larger_one(tmp_path, config, model):
    folder = RunFolder(tmp_path)
    folder.write_config(config)
    save(model, folder, 16)
    model.num_timesteps = config.total_timesteps
    try:
        model.save(folder.model_path)
    finally:
        model.num_timesteps = 0
    assert folder.already_trained(config) == config.total_timesteps
    assert folder.already_trained(replace(config, total_timesteps=128)) is None  # decisions to train
    with pytest.raises(RunError, match="is not the configuration of the run"):
        folder.already_trained(replace(config, seed=4))
    save(model, folder, 96)  # a checkpoint past the budget: plan says what is wrong
    assert folder.already_trained(config) is None


def test_a_run_whose_only_checkpoint_is_damaged_is_named_damaged_not_without_checkpoints(tmp_path, config, model):
    from emmi_gym.tools.training.run_folders.model_files import ModelFileError

    folder = RunFolder(tmp_path)
    save(model, folder, 16)
    folder.checkpoint_path(16).write_bytes(folder.checkpoint_path(16).read_bytes()[:-200])
    with pytest.warns(UserWarning, match="skipping the damaged checkpoint"), \
            pytest.raises(ModelFileError, match=rf"{tmp_path}: expected a run with a whole checkpoint or model; its 1 "
                                                rf"model file\(s\) are all damaged, the last: "
                                                rf"{folder.checkpoint_path(16)}: expected a Stable-Baselines3 model"):
        folder.whole_checkpoints()


@pytest.mark.parametrize("kind, extension", [("", "zip"), ("replay_buffer_", "pkl")])
def test_checkpoints_are_named_as_sb3_names_them(tmp_path, kind, extension):
    """The run folder finds checkpoints by SB3's names; the callback that writes them builds those names from
    SB3's public settings (compared here with SB3's own private helper)."""
    from emmi_gym.tools.training.train import AtomicCheckpointCallback

    callback = AtomicCheckpointCallback(save_freq=4, save_path=str(tmp_path), name_prefix="model")
    callback.num_timesteps = 96
    assert callback.checkpoint_path(kind, extension) == Path(callback._checkpoint_path(kind, extension))
    assert callback.checkpoint_path(kind, extension).name == f"model_{kind}96_steps.{extension}"
