"""Runs that are never lost: a run folder is not overwritten by accident, a resumed or warm-started run is
checked against its configuration before anything is written, no NaN reaches a saved model, every file is
written whole or not at all, and a run killed at any moment resumes to a model whose record adds up."""

import itertools
import os
import random
import shutil
import signal
import subprocess
import sys
import time
import zipfile
from dataclasses import replace

import gymnasium as gym
import numpy as np
import pytest
import torch
import yaml
from stable_baselines3 import PPO
from test_imitation import CONFIG as CLONE_CONFIG
from test_training import config_dict

from emmi_gym.formats.atomic_files import write_atomically
from emmi_gym.tools.cli import main
from emmi_gym.tools.training.callbacks import NonFiniteError
from emmi_gym.tools.training.config import parse_agent_config
from emmi_gym.tools.training.imitation import Demonstrations, clone_run
from emmi_gym.tools.training.run_folders import RunFolder
from emmi_gym.tools.training.train import model_of, train

PPO_SMALL = {"n_steps": 16, "batch_size": 16, "n_epochs": 1}


def agent_file(path, **changes):
    """An agent configuration file: the small PPO of the training tests, with ``changes`` to config_dict."""
    path.write_text(yaml.safe_dump(config_dict(changes.pop("algorithm", "PPO"), hyper=PPO_SMALL, **changes)))
    return path


def cli(argv, capsys) -> tuple[int, str, str]:
    """``emmi-gym ARGV``: its exit code, stdout and stderr."""
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exit_:
        code = exit_.code
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished run of 32 decisions (checkpoints at 16 and 32) and its configuration file."""
    folder = tmp_path_factory.mktemp("finished")
    config = agent_file(folder / "agent.yaml", timesteps=32, checkpoint_freq=16)
    assert main(["train", str(config), "--out", str(folder / "run"), "--quiet"]) == 0
    return folder / "run", config


@pytest.fixture
def run(finished, tmp_path):
    """A copy of the finished run, and its configuration file."""
    shutil.copytree(finished[0], tmp_path / "run")
    return tmp_path / "run", finished[1]


@pytest.mark.slow
def test_resume_with_another_configuration_is_refused_before_anything_is_written(run, tmp_path, capsys):
    folder, _ = run
    before = {path: path.read_bytes() for path in folder.rglob("*") if path.is_file()}
    for changes, fields in (
        ({"algorithm": "A2C", "hyper": {"n_steps": 8}}, ["algorithm"]),
        ({"env_id": "emmi_gym/Explore-v1"}, ["env.id"]),
        ({"env_extra": {"reward": "coverage"}}, ["env.kwargs.reward"]),
    ):
        other = tmp_path / "other.yaml"
        other.write_text(
            yaml.safe_dump(
                config_dict(
                    changes.pop("algorithm", "PPO"), hyper=changes.pop("hyper", PPO_SMALL), timesteps=64, **changes
                )
            )
        )
        code, _, err = cli(["train", other, "--resume", "--out", folder, "--quiet"], capsys)
        assert (
            code == 2 and f"{other} is not the configuration of the run in {folder} ({folder / 'config.yaml'})" in err
        ), err
        assert all(f"{field}: " in err for field in fields), err
        assert {path: path.read_bytes() for path in folder.rglob("*") if path.is_file()} == before
    code, out, _ = cli(["evaluate", folder / "model.zip", "--episodes", "1"], capsys)
    assert code == 0, out


@pytest.mark.slow
def test_a_new_run_into_a_folder_holding_one_is_refused_and_overwrite_starts_afresh(run, capsys):
    folder, config = run
    (folder / "model.zip").unlink()  # an interrupted run: checkpoints and a record of its wall time
    record = yaml.safe_load((folder / "training.yaml").read_text())
    record.update(wall_seconds=99999.0, parts=[dict(record["parts"][0], wall_seconds=99999.0)])
    (folder / "training.yaml").write_text(yaml.safe_dump(record))
    before = {path: path.read_bytes() for path in folder.rglob("*") if path.is_file()}
    code, _, err = cli(["train", config, "--out", folder, "--quiet"], capsys)
    assert code == 2 and f"{folder} is not empty" in err and "--resume" in err and "--overwrite" in err
    assert {path: path.read_bytes() for path in folder.rglob("*") if path.is_file()} == before
    (folder / "notes.txt").write_text("mine")
    assert cli(["train", config, "--out", folder, "--overwrite", "--timesteps", "16", "--quiet"], capsys)[0] == 0
    record = yaml.safe_load((folder / "training.yaml").read_text())
    assert record["timesteps"] == 16 and record["wall_seconds"] < 99999 and len(record["parts"]) == 1
    assert [decisions for decisions, _ in RunFolder(folder).checkpoints()] == [16]  # the old run's checkpoints are gone
    assert (folder / "notes.txt").read_text() == "mine"  # what a run does not write stays


@pytest.mark.slow
def test_clone_into_a_folder_that_is_not_empty_is_refused_unless_overwrite(tmp_path, capsys):
    (tmp_path / "agent.yaml").write_text(yaml.safe_dump(CLONE_CONFIG))
    out = tmp_path / "bc"
    out.mkdir()
    (out / "model.zip").write_bytes(b"an earlier clone")
    argv = [
        "clone",
        tmp_path / "agent.yaml",
        "--policy",
        "frontier",
        "--episodes",
        "1",
        "--workers",
        "1",
        "--epochs",
        "1",
        "--out",
        out,
        "--quiet",
    ]
    code, _, err = cli(argv, capsys)
    assert code == 2 and f"{out} is not empty (it holds model.zip)" in err and "--overwrite" in err
    assert (out / "model.zip").read_bytes() == b"an earlier clone"
    assert cli([*argv, "--overwrite"], capsys)[0] == 0
    assert zipfile.is_zipfile(out / "model.zip") and (out / "clone.yaml").is_file()


@pytest.mark.slow
def test_init_from_is_checked_against_the_configuration_and_says_what_will_train(finished, tmp_path, capsys):
    folder, _ = finished
    model = folder / "model.zip"
    config = agent_file(tmp_path / "agent.yaml", timesteps=32)
    code, _, err = cli(["train", config, "--init-from", model, "--out", tmp_path / "none"], capsys)
    assert code == 2 and f"--init-from {model}: the model holds 32 decisions" in err and "--allow-no-training" in err
    assert not (tmp_path / "none").exists() or not os.listdir(tmp_path / "none")
    code, out, _ = cli(
        ["train", config, "--init-from", model, "--timesteps", "48", "--out", tmp_path / "more", "--quiet"], capsys
    )
    assert code == 0 and f"starting from {model} (32 decisions): 16 decisions to train, to 48" in out
    assert (
        cli(
            ["train", config, "--init-from", model, "--allow-no-training", "--out", tmp_path / "copy", "--quiet"],
            capsys,
        )[0]
        == 0
    )

    waypoint = tmp_path / "waypoint.yaml"  # the same algorithm and policy, another env id
    agent_file(waypoint, timesteps=16, env_id="emmi_gym/Explore-v1", env_extra={"max_decisions": 4})
    assert cli(["train", waypoint, "--out", tmp_path / "plans", "--quiet"], capsys)[0] == 0
    code, _, err = cli(
        [
            "train",
            config,
            "--init-from",
            tmp_path / "plans" / "model.zip",
            "--timesteps",
            "64",
            "--out",
            tmp_path / "mixed",
        ],
        capsys,
    )
    assert (
        code == 2
        and (
            f"a model of emmi_gym/Explore-v1 (its configuration {tmp_path / 'plans' / 'config.yaml'}),"
            f" but {config} trains on emmi_gym/ExploreVelocity-v0"
        )
        in err
    ), err
    larger = agent_file(tmp_path / "larger.yaml", timesteps=64, env_extra={"obs_size": 48})
    code, _, err = cli(["train", larger, "--init-from", model, "--out", tmp_path / "larger"], capsys)
    assert code == 2 and f"--init-from {model}: the model's observation space is Dict(" in err, err


def poison_the_third_update(monkeypatch):
    """Make the third optimiser step leave a NaN in the first weight it updates (as a diverging run would)."""
    step, calls = torch.optim.Adam.step, []

    def poisoned(self, *args, **kwargs):
        result = step(self, *args, **kwargs)
        calls.append(True)
        if len(calls) == 3:
            with torch.no_grad():
                self.param_groups[0]["params"][0].view(-1)[0] = float("nan")
        return result

    monkeypatch.setattr(torch.optim.Adam, "step", poisoned)


@pytest.mark.slow
def test_training_stops_at_the_first_non_finite_weight_and_keeps_the_last_good_checkpoint(tmp_path, monkeypatch):
    config = parse_agent_config(
        config_dict(
            "PPO", hyper=PPO_SMALL, timesteps=96, checkpoint_freq=32, eval={"freq": 0, "episodes": 1, "seed": 500}
        )
    )
    poison_the_third_update(monkeypatch)  # the update after decision 48
    with pytest.raises(NonFiniteError) as error:
        train(config, tmp_path, progress=False)
    message = str(error.value)
    assert message.startswith(f"{tmp_path}: training stopped at decision 48: after the update, the weight ")
    assert f"the newest checkpoint, of finite weights, is {tmp_path / 'checkpoints' / 'model_32_steps.zip'}" in message
    assert not (tmp_path / "model.zip").exists() and [n for n, _ in RunFolder(tmp_path).checkpoints()] == [32]
    saved = PPO.load(RunFolder(tmp_path).latest_checkpoint()).policy
    assert all(torch.isfinite(p).all() for p in saved.parameters())
    assert yaml.safe_load((tmp_path / "training.yaml").read_text())["timesteps"] == 32


@pytest.mark.slow
def test_a_model_with_non_finite_weights_is_refused_as_a_start(finished, tmp_path, capsys):
    model = PPO.load(finished[0] / "model.zip")
    with torch.no_grad():
        next(model.policy.parameters()).view(-1)[0] = float("inf")
    model.save(tmp_path / "diverged.zip")
    config = agent_file(tmp_path / "agent.yaml", timesteps=64)
    code, _, err = cli(["train", config, "--init-from", tmp_path / "diverged.zip", "--out", tmp_path / "run"], capsys)
    assert code == 2 and f"{tmp_path / 'diverged.zip'}: expected a model whose weights are all finite" in err, err


@pytest.mark.slow
def test_cloning_stops_at_a_non_finite_loss_and_writes_no_model(tmp_path):
    config = parse_agent_config(CLONE_CONFIG)
    space = gym.make(config.env_id, **config.env_kwargs).observation_space
    observations = {key: np.zeros((4, *sub.shape), sub.dtype) for key, sub in space.spaces.items()}
    observations["pose"][2, 1] = np.inf
    demonstrations = Demonstrations(observations, np.ones((4, 8), bool), np.zeros(4, np.int64), 1)
    with pytest.raises(
        NonFiniteError,
        match=r"cloning stopped in epoch 1: the observations of the demonstrated "
        r"decisions \[2\] are not finite",
    ):
        clone_run(config, demonstrations, tmp_path, epochs=2)
    assert not (tmp_path / "model.zip").exists()


@pytest.mark.slow
@pytest.mark.parametrize("obs_size", [36, 256])
@pytest.mark.parametrize(
    "algorithm, policy, env_id, env_kwargs",
    [
        ("PPO", "MultiInputPolicy", "emmi_gym/ExploreVelocity-v0", {}),
        ("PPO", "CnnPolicy", "emmi_gym/ExploreVelocity-v0", {"observation": "image"}),
        ("MaskablePPO", "TargetScoringPolicy", "emmi_gym/LoopCorridor-v1", {}),
    ],
)
def test_every_policy_builds_and_acts_at_the_bounds_of_obs_size(algorithm, policy, env_id, env_kwargs, obs_size):
    config = parse_agent_config(
        {
            "env": {"id": env_id, "kwargs": {"particles": 1, "obs_size": obs_size, **env_kwargs}},
            "algorithm": algorithm,
            "policy": policy,
            "n_envs": 1,
            "vec_env": "dummy",
        }
    )
    env = gym.make(config.env_id, **config.env_kwargs)
    model = model_of(config, env)
    observation, _ = env.reset(seed=0)
    assert env.action_space.contains(model.predict(observation, deterministic=True)[0])
    env.close()


def test_obs_size_below_what_the_cnn_takes_is_refused():
    with pytest.raises(ValueError, match=r"field 'obs_size': expected an integer in \[36, 256\]"):
        gym.make("emmi_gym/LoopCorridor-v1", obs_size=35)


def test_an_interrupted_write_leaves_the_old_file(tmp_path):
    path = tmp_path / "training.yaml"
    path.write_text("old")

    def half_then_fail(tmp):
        tmp.write_text("ne")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_atomically(path, half_then_fail)
    assert path.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["training.yaml"]


def assert_record_adds_up(record: dict, decisions: int) -> None:
    """``training.yaml``'s totals: the decisions of its parts, each starting where the one before ended, sum to
    the model's beyond its start, and its wall time is theirs."""
    parts = record["parts"]
    assert record["timesteps"] == decisions
    assert parts[0]["start"] == record.get("init_decisions", 0) and parts[-1]["end"] == decisions
    assert all(a["end"] == b["start"] for a, b in itertools.pairwise(parts)), parts
    assert record["wall_seconds"] == pytest.approx(sum(p["wall_seconds"] for p in parts), abs=1e-6)


@pytest.mark.slow
def test_a_run_killed_at_random_moments_resumes_to_a_loadable_model_whose_record_adds_up(tmp_path):
    data = config_dict(
        "PPO", hyper=PPO_SMALL, timesteps=10**6, checkpoint_freq=16, eval={"freq": 0, "episodes": 1, "seed": 500}
    )
    (tmp_path / "agent.yaml").write_text(yaml.safe_dump(data))
    folder = tmp_path / "run"
    moments = random.Random(49)
    for part in range(3):
        argv = [
            sys.executable,
            "-m",
            "emmi_gym.tools.cli",
            "train",
            str(tmp_path / "agent.yaml"),
            "--out",
            str(folder),
            "--quiet",
            *(["--resume"] if part else []),
        ]
        earlier = set(RunFolder(folder).checkpoints())
        process = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        try:
            waited = 0.0  # until this part trains (a checkpoint of its own), then a moment within 1.5 s
            while set(RunFolder(folder).checkpoints()) <= earlier and process.poll() is None and waited < 120:
                time.sleep(0.05)
                waited += 0.05
            assert process.poll() is None, process.communicate()[1][-2000:]
            time.sleep(moments.uniform(0.0, 1.5))
        finally:
            process.send_signal(signal.SIGKILL)
            process.communicate()
        for _, checkpoint in RunFolder(folder).checkpoints():  # every file in place is whole
            with zipfile.ZipFile(checkpoint) as archive:
                assert archive.testzip() is None
    newest = RunFolder(folder).latest_checkpoint()
    decisions = 0 if newest is None else RunFolder(folder).checkpoints()[-1][0]
    config = replace(parse_agent_config(data, str(tmp_path / "agent.yaml")), total_timesteps=decisions + 16)
    result = train(config, folder, resume=True, progress=False)
    model = PPO.load(result.model_path)
    assert model.num_timesteps == result.timesteps >= decisions + 16
    assert_record_adds_up(yaml.safe_load((folder / "training.yaml").read_text()), model.num_timesteps)


@pytest.mark.slow
def test_a_run_from_a_model_interrupted_and_resumed_records_each_part(finished, tmp_path, monkeypatch):
    from test_training import interrupt_training_at

    start = finished[0] / "model.zip"  # 32 decisions
    config = parse_agent_config(config_dict("PPO", hyper=PPO_SMALL, timesteps=96))
    run_on = interrupt_training_at(monkeypatch, 64)
    assert train(config, tmp_path, progress=False, init_from=start).interrupted
    run_on()
    resumed = train(config, tmp_path, resume=True, progress=False)
    record = yaml.safe_load((tmp_path / "training.yaml").read_text())
    assert record["init_from"] == str(start) and record["init_decisions"] == 32 and len(record["parts"]) == 2
    assert_record_adds_up(record, resumed.timesteps)


def test_the_benchmark_refuses_a_run_folder_of_something_else_before_any_job(tmp_path):
    from emmi_gym.tools.training.reward_benchmark import run_benchmark
    from emmi_gym.tools.training.run_folders import RunError

    config = parse_agent_config(config_dict("PPO", hyper=PPO_SMALL, timesteps=16))
    taken = tmp_path / "runs" / "emmi_seed0"
    taken.mkdir(parents=True)
    (taken / "notes.txt").write_text("mine")
    with pytest.raises(RunError, match=f"{taken}: not empty, and not a run of this benchmark's configuration"):
        run_benchmark(config, ["emmi"], range(1), 16, 1, [], tmp_path, workers=1, progress=False)
    assert sorted(p.name for p in taken.iterdir()) == ["notes.txt"]


def test_the_benchmark_resumes_its_run_continued_with_rollout_workers_and_refuses_other_hyperparameters(tmp_path):
    """A benchmark's agent trained on by ``train --resume`` with rollout workers (a change a resumed run may make,
    on a machine with cores to spare) is still the benchmark's run, to be resumed; another learning rate is not."""
    from emmi_gym.tools.training.reward_benchmark import make_jobs, run_state
    from emmi_gym.tools.training.run_folders import RunFolder

    config = parse_agent_config(config_dict("PPO", hyper=PPO_SMALL, timesteps=64))
    job = make_jobs(config, ["emmi"], range(1), 64, 1, [], tmp_path)[0]
    folder = RunFolder(job.run_dir)
    job.run_dir.mkdir(parents=True)
    folder.write_config(replace(job.config, vec_env="workers", n_envs=2, checkpoint_freq=8))
    assert run_state(job) == "unfinished"
    hyperparameters = dict(job.config.hyperparameters, learning_rate=1e-3)
    folder.write_config(replace(job.config, vec_env="workers", hyperparameters=hyperparameters))
    assert run_state(job) == "other"
