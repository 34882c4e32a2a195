"""Runs never lost under faults and mistakes: an overwrite never removes its own input, the benchmark never
reports a partial agent nor relabels a budget, a resumed run is checked against its model before anything is
written, a rollout worker that stops or dies is a one-line error naming it with the run saved, SIGTERM stops
a run as Ctrl-C does, and readers stay within their memory bounds."""

import csv
import multiprocessing as mp
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
import zipfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import test_run_safety
import yaml
from helpers import start_as_a_terminal_would
from test_imitation import CONFIG as CLONE_CONFIG
from test_rollout_workers import MASKED, agent
from test_run_safety import PPO_SMALL, cli
from test_training import config_dict, interrupt_training_at

from emmi_gym.concurrency.interrupts import RunStopped
from emmi_gym.concurrency.parallel import ActorStalled
from emmi_gym.tools.training.config import parse_agent_config
from emmi_gym.tools.training.run_folders import RunFolder
from emmi_gym.tools.training.train import make_vec_env, model_of, train

finished, run = test_run_safety.finished, test_run_safety.run  # fixtures: a finished run, and a copy of it


def files_of(folder) -> dict:
    return {path: path.read_bytes() for path in sorted(folder.rglob("*")) if path.is_file()}


# ---------------------------------------------------------------- overwrite and its inputs
@pytest.mark.slow
def test_overwrite_refuses_an_input_among_the_files_it_would_remove(run, tmp_path, capsys):
    folder, config = run
    before = files_of(folder)
    for model in (folder / "model.zip", folder / "checkpoints" / "model_16_steps.zip"):
        code, _, err = cli(["train", config, "--init-from", model, "--out", folder, "--overwrite",
                            "--timesteps", "48", "--quiet"], capsys)
        assert code == 2 and f"--init-from {model} is a file of the run in {folder}" in err
        assert files_of(folder) == before
    clone = tmp_path / "clone"
    clone.mkdir()
    (clone / "demonstrations.npz").write_bytes(b"the demonstrations")
    (tmp_path / "clone.yaml").write_text(yaml.safe_dump(CLONE_CONFIG))
    code, _, err = cli(["clone", tmp_path / "clone.yaml", "--demos", clone / "demonstrations.npz", "--out", clone,
                        "--overwrite", "--quiet"], capsys)
    assert code == 2 and "--demos" in err and "--overwrite would remove" in err
    assert (clone / "demonstrations.npz").read_bytes() == b"the demonstrations"


# ---------------------------------------------------------------- resuming
@pytest.mark.slow
def test_resume_below_what_is_trained_is_refused_and_the_folder_kept(run, capsys):
    folder, config = run
    before = files_of(folder)
    code, _, err = cli(["train", config, "--resume", "--timesteps", "16", "--out", folder, "--quiet"], capsys)
    assert code == 2 and "holds 32 decisions" in err and "--timesteps 32 or more" in err
    assert files_of(folder) == before


@pytest.mark.slow
def test_resuming_a_finished_run_says_there_is_nothing_to_do_and_writes_nothing(run, capsys):
    folder, config = run
    before = files_of(folder)
    code, out, _ = cli(["train", config, "--resume", "--timesteps", "32", "--out", folder, "--quiet"], capsys)
    assert code == 0 and f"{folder}: already trained to 32 decisions; nothing to do" in out and "trained 32" not in out
    assert files_of(folder) == before


@pytest.mark.slow
def test_resume_skips_a_damaged_model_for_the_newest_whole_checkpoint(run, capsys):
    folder, config = run
    with zipfile.ZipFile(folder / "model.zip") as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    with zipfile.ZipFile(folder / "model.zip", "w") as archive:  # a whole zip whose weights are not torch's
        for name, data in members.items():
            archive.writestr(name, b"garbage" if name == "policy.pth" else data)
    (folder / "checkpoints" / "model_32_steps.zip").unlink()
    with pytest.warns(UserWarning, match="skipping the damaged checkpoint .*model.zip"):
        code, out, _ = cli(["train", config, "--resume", "--timesteps", "48", "--out", folder, "--quiet"], capsys)
    assert code == 0 and f"continuing from {folder / 'checkpoints' / 'model_16_steps.zip'} (16 decisions)" in out


@pytest.mark.slow
def test_resume_of_a_run_whose_config_names_another_algorithm_is_refused_and_the_folder_kept(run, tmp_path, capsys):
    folder, _ = run
    dqn = tmp_path / "dqn.yaml"
    dqn.write_text(yaml.safe_dump(config_dict("DQN", env_extra={"velocity_actions": "discrete"}, timesteps=24,
                                              hyper={"buffer_size": 500, "learning_starts": 8})))
    (folder / "config.yaml").write_text(dqn.read_text())  # the PPO run's configuration replaced by a DQN one
    before = files_of(folder)
    with pytest.warns(UserWarning, match="skipping the damaged checkpoint"):
        code, out, err = cli(["train", dqn, "--resume", "--timesteps", "24", "--out", folder, "--quiet"], capsys)
    assert code == 2 and f"none of the 3 model files of the run in {folder} is a whole DQN model" in err
    assert "--overwrite" in err and "fresh model" not in out and len(err.strip().splitlines()) == 1
    assert files_of(folder) == before


@pytest.mark.slow
def test_a_configuration_that_does_not_match_the_model_is_refused_before_anything_is_written(run, capsys):
    folder, config = run
    edited = yaml.safe_load((folder / "config.yaml").read_text())
    edited["hyperparameters"]["policy_kwargs"] = {"net_arch": [7]}  # hand-edited, in the run and the file given
    (folder / "config.yaml").write_text(yaml.safe_dump(edited))
    before = files_of(folder)
    code, _, err = cli(["train", folder / "config.yaml", "--resume", "--timesteps", "48", "--out", folder,
                        "--quiet"], capsys)
    assert code == 2 and "the model's network is policy_kwargs" in err and "'net_arch': [7]" in err
    assert files_of(folder) == before


@pytest.mark.slow
def test_a_training_record_whose_parts_do_not_add_up_is_refused(run, capsys):
    folder, config = run
    record = yaml.safe_load((folder / "training.yaml").read_text())
    record["parts"] = [dict(record["parts"][0], end=8)]  # 0-8, but 32 decisions trained
    (folder / "training.yaml").write_text(yaml.safe_dump(record))
    before = files_of(folder)
    code, _, err = cli(["train", config, "--resume", "--timesteps", "48", "--out", folder, "--quiet"], capsys)
    assert code == 2 and "training.yaml: field 'parts': expected parts that add up" in err
    assert files_of(folder) == before


# ---------------------------------------------------------------- --init-from
def test_init_from_another_policy_class_is_refused_and_a_model_without_its_configuration_warned(tmp_path, capsys):
    scoring = parse_agent_config(dict(CLONE_CONFIG, total_timesteps=16))  # TargetScoringPolicy
    plain = replace(scoring, policy="MultiInputPolicy")
    env = make_vec_env(plain, 1, 0, "dummy")
    model_of(plain, env).save(tmp_path / "plain.zip")  # saved without a config.yaml beside it
    env.close()
    (tmp_path / "scoring.yaml").write_text(yaml.safe_dump(dict(CLONE_CONFIG, total_timesteps=16)))
    with pytest.warns(UserWarning, match="no config.yaml beside it"):
        code, _, err = cli(["train", tmp_path / "scoring.yaml", "--init-from", tmp_path / "plain.zip", "--out",
                            tmp_path / "run", "--quiet"], capsys)
    assert code == 2 and "a model of the policy MaskableMultiInputActorCriticPolicy" in err
    assert "names policy TargetScoringPolicy" in err and not files_of(tmp_path / "run")


# ---------------------------------------------------------------- the benchmark
def test_the_benchmark_checks_every_argument_before_the_first_agent(tmp_path):
    from emmi_gym.tools.training.reward_benchmark import make_jobs

    config = parse_agent_config(dict(CLONE_CONFIG, policy="MultiInputPolicy"))
    with pytest.raises(ValueError, match="--rewards: emmi given more than once"):
        make_jobs(config, ["emmi", "emmi"], range(1), 8, 1, [], tmp_path)
    with pytest.raises(ValueError, match=r"--baselines: unknown \['bogus'\]"):
        make_jobs(config, ["emmi"], range(1), 8, 1, ["frontier", "bogus"], tmp_path)
    assert not list(tmp_path.iterdir())


def test_the_benchmark_refuses_to_report_a_larger_run_under_a_smaller_budget(tmp_path):
    from emmi_gym.tools.training.reward_benchmark import make_jobs, run_benchmark
    from emmi_gym.tools.training.run_folders import RunError

    config = parse_agent_config(config_dict("PPO", hyper=PPO_SMALL, timesteps=16))
    job = make_jobs(config, ["emmi"], range(1), 32, 1, [], tmp_path)[0]
    RunFolder(job.run_dir).write_config(job.config)  # a run of this benchmark to 32 decisions
    before = files_of(tmp_path)
    with pytest.raises(RunError, match=r"emmi_seed0: a run of this benchmark to a larger budget than --timesteps 16"):
        run_benchmark(config, ["emmi"], range(1), 16, 1, [], tmp_path, workers=1, progress=False)
    assert files_of(tmp_path) == before


@pytest.mark.slow
def test_an_interrupted_benchmark_exits_130_and_reports_nothing(tmp_path, monkeypatch, capsys):
    (tmp_path / "agent.yaml").write_text(yaml.safe_dump(config_dict("PPO", hyper=PPO_SMALL, timesteps=48,
                                                                    checkpoint_freq=16)))
    interrupt_training_at(monkeypatch, 24)
    code, _, err = cli(["benchmark", "--config", tmp_path / "agent.yaml", "--rewards", "emmi", "--seeds", "1",
                        "--episodes", "1", "--baselines", "--workers", "1", "--out", tmp_path / "bench",
                        "--quiet"], capsys)
    assert code == 130 and "interrupted: the agents stopped keep their checkpoints" in err
    assert "Traceback" not in err and not (tmp_path / "bench" / "benchmark_summary.md").exists()
    assert RunFolder(tmp_path / "bench" / "runs" / "emmi_seed0").latest_checkpoint() is not None


@pytest.mark.slow
def test_a_benchmark_sitting_with_train_only_trains_and_the_last_evaluates_once(tmp_path, capsys):
    """A budget spread over sittings: --train-only trains (or resumes) the agents and plays no episode, of
    theirs or of the baselines; the sitting without it evaluates the finished agents without training them."""
    (tmp_path / "agent.yaml").write_text(yaml.safe_dump(config_dict("PPO", {"max_decisions": 4}, PPO_SMALL,
                                                                    timesteps=16, env_id="emmi_gym/Explore-v1")))
    argv = ["benchmark", "--config", tmp_path / "agent.yaml", "--rewards", "emmi", "--seeds", "1", "--episodes",
            "1", "--baselines", "frontier", "--workers", "1", "--out", tmp_path / "bench", "--quiet"]
    code, out, _ = cli([*argv, "--train-only"], capsys)
    assert code == 0 and "emmi seed 0: 16 decisions" in out and "trained now" in out
    assert "run again without --train-only" in out
    assert sorted(p.name for p in (tmp_path / "bench" / "runs").iterdir()) == ["emmi_seed0"]
    assert not (tmp_path / "bench" / "benchmark_episodes.csv").exists()
    code, out, _ = cli(argv, capsys)
    assert code == 0 and "1 agent(s) trained by an earlier run" in out
    with open(tmp_path / "bench" / "benchmark_episodes.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert sorted(row["kind"] for row in rows) == ["agent", "baseline"]
    assert {row["episode_seed"] for row in rows} == {"1000000"}  # both played the same held-out episode


@pytest.mark.slow
def test_ctrl_c_in_a_pool_stops_every_job_without_a_traceback(tmp_path):
    script = ("import time\nfrom emmi_gym.concurrency.parallel import run_in_processes\n"
              "try:\n    run_in_processes(time.sleep, [60] * 6, workers=2, progress=False)\n"
              "except KeyboardInterrupt:\n    print('stopped', flush=True)\n")
    process = start_as_a_terminal_would([sys.executable, "-c", script], stdout=subprocess.PIPE,
                                        stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        time.sleep(5)  # the pool's workers started, each in a job
        started = time.monotonic()
        os.kill(process.pid, signal.SIGINT)
        out, err = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
    assert out.strip() == "stopped" and "Traceback" not in err and time.monotonic() - started < 20


# ---------------------------------------------------------------- rollout workers under faults
def _worker_processes(name: str) -> list:
    return [child for child in mp.active_children() if child.name == name]


def _fault_when_checkpointed(folder, fault):
    """A thread that applies ``fault(process of rollout worker 1)`` once ``folder`` holds a checkpoint."""

    def wait_and_fault():
        deadline = time.monotonic() + 120
        while not list((folder / "checkpoints").glob("model_*_steps.zip")) and time.monotonic() < deadline:
            time.sleep(0.05)
        fault(_worker_processes("rollout worker 1")[0])

    thread = threading.Thread(target=wait_and_fault, daemon=True)
    thread.start()
    return thread


@pytest.mark.slow
@pytest.mark.parametrize("fault", ["SIGSTOP", "SIGKILL"])
def test_a_worker_that_stops_or_dies_stops_the_run_naming_it_with_a_checkpoint_to_resume(tmp_path, fault):
    from sb3_contrib import MaskablePPO

    data = agent(MASKED, total_timesteps=10**6, checkpoint_freq=12, worker_timeout=30)  # past any pause of healthy work
    _fault_when_checkpointed(tmp_path, lambda process: os.kill(process.pid, getattr(signal, fault)))
    started = time.monotonic()
    with pytest.raises(RunStopped) as stopped:
        train(parse_agent_config(data), tmp_path, progress=False)
    message = str(stopped.value)
    assert "rollout worker 1" in message and "--resume" in message and "\n" not in message
    assert ("made no progress for 30 s" if fault == "SIGSTOP" else "the process has stopped") in message
    assert time.monotonic() - started < 100  # generous: the bound is the heartbeat's, a few seconds
    saved = RunFolder(tmp_path).latest_checkpoint()
    assert str(saved) in message and MaskablePPO.load(saved).num_timesteps >= 12
    assert not _worker_processes("rollout worker 1")  # stopped or not, every worker was ended


@pytest.mark.slow
def test_a_stalled_worker_is_named_within_its_timeout():
    data = parse_agent_config(agent(MASKED))  # healthy work, however slow on a loaded machine, never times out
    workers = make_vec_env(data, 2, 0, "workers")
    try:
        workers.reset()
        workers.worker_timeout = 2  # only the stall made below has to be seen within it
        os.kill(workers.workers[0].process.pid, signal.SIGSTOP)
        started = time.monotonic()
        with pytest.raises(ActorStalled, match=r"rollout worker 0 \(process \d+\) has made no progress for 2 s"):
            workers.reset()
        assert 2 <= time.monotonic() - started < 30
    finally:
        workers.close()


@pytest.mark.slow
def test_sigterm_saves_a_checkpoint_exits_143_and_the_run_resumes_from_it(tmp_path):
    config = tmp_path / "agent.yaml"
    config.write_text(yaml.safe_dump(agent(MASKED, total_timesteps=10**6, checkpoint_freq=12, policy_lag=1)))
    run_dir = tmp_path / "run"
    process = subprocess.Popen([sys.executable, "-m", "emmi_gym", "train", config, "--out", run_dir, "--quiet"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    deadline = time.monotonic() + 180
    while not list((run_dir / "checkpoints").glob("model_*_steps.zip")) and time.monotonic() < deadline:
        time.sleep(0.1)
    os.killpg(process.pid, signal.SIGTERM)  # as timeout(1) does: the whole group
    try:
        out, err = process.communicate(timeout=60)
    except subprocess.TimeoutExpired:  # a failure, and no process left behind (its workers end with it)
        os.killpg(process.pid, signal.SIGKILL)
        raise
    assert process.returncode == 143 and "Traceback" not in err and "Error" not in err
    saved = RunFolder(run_dir).latest_checkpoint()
    assert f"saved {saved}" in out
    stopped_at = int(saved.stem.split("_")[1])
    resumed = train(parse_agent_config(agent(MASKED, total_timesteps=stopped_at + 12, checkpoint_freq=12,
                                             policy_lag=1)), run_dir, resume=True, progress=False)
    assert resumed.timesteps >= stopped_at + 12
    record = yaml.safe_load((run_dir / "training.yaml").read_text())
    assert record["timesteps"] == resumed.timesteps and record["parts"][0]["end"] == stopped_at


def _forkserver_starting(parent: int) -> bool:
    """Whether a child of ``parent`` is multiprocessing's forkserver (which forks the rollout workers) amid its
    start-up, with Python's handler of Ctrl-C in place (SIGINT caught; it ignores SIGINT once started)."""
    for child in Path(f"/proc/{parent}/task/{parent}/children").read_text().split():
        try:
            command, status = Path(f"/proc/{child}/cmdline").read_bytes(), Path(f"/proc/{child}/status").read_text()
        except OSError:  # ended
            continue
        caught = next(line.split()[1] for line in status.splitlines() if line.startswith("SigCgt:"))
        if b"multiprocessing.forkserver" in command and int(caught, 16) & 1 << (signal.SIGINT - 1):
            return True
    return False


@pytest.mark.slow
def test_ctrl_c_while_the_workers_start_is_one_line_with_no_worker_traceback(tmp_path):
    """Ctrl-C to the terminal's process group while the process that forks the workers starts up."""
    config = tmp_path / "agent.yaml"
    config.write_text(yaml.safe_dump(agent(MASKED, total_timesteps=10**6, checkpoint_freq=10**6)))
    process = start_as_a_terminal_would([sys.executable, "-m", "emmi_gym", "train", config, "--out",
                                         tmp_path / "run", "--quiet"], stdout=subprocess.PIPE,
                                        stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while process.poll() is None and not _forkserver_starting(process.pid) and time.monotonic() < deadline:
            time.sleep(0.001)
        os.killpg(process.pid, signal.SIGINT)
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
    assert "Fatal Python error" not in err and "Traceback" not in err, err[-3000:]
    assert process.returncode == 130 and err.strip() == "emmi-gym train: interrupted"


def test_ctrl_c_before_training_starts_is_one_line(tmp_path, monkeypatch, capsys):
    import emmi_gym.tools.training.config as configs

    def interrupted(path):
        raise KeyboardInterrupt

    monkeypatch.setattr(configs, "load_agent_config", interrupted)
    code, _, err = cli(["train", tmp_path / "agent.yaml", "--out", tmp_path / "run"], capsys)
    assert code == 130 and err.strip() == "emmi-gym train: interrupted"


# ---------------------------------------------------------------- the smaller items
@pytest.mark.slow
def test_a_checkpoint_is_scored_at_its_models_count_and_nan_weights_name_the_file(finished, tmp_path):
    import torch

    from emmi_gym.tools.training.run_folders.model_files import ModelFileError, load_model_file

    folder = tmp_path / "run"
    shutil.copytree(finished[0], folder)
    (folder / "checkpoints" / "model_16_steps.zip").rename(folder / "checkpoints" / f"model_{10**23}_steps.zip")
    assert [decisions for decisions, _ in RunFolder(folder).whole_checkpoints()] == [16, 32]
    model = load_model_file(folder / "model.zip", "PPO")
    with torch.no_grad():
        next(model.policy.parameters()).fill_(float("nan"))
    model.save(tmp_path / "nan.zip")
    with pytest.raises(ModelFileError, match=r"nan\.zip: expected a model whose weights are all finite"):
        load_model_file(tmp_path / "nan.zip", "PPO")


def test_a_curve_with_negative_timesteps_and_a_world_in_options_are_refused(tmp_path, capsys):
    from emmi_gym.inputs.csv_files import CsvFileError
    from emmi_gym.tools.training.learning_curves import read_curve

    (tmp_path / "curve.csv").write_text("timesteps,oracle_accuracy,ate,sim_steps,coverage\n-8,0.5,0.2,100,0.4\n")
    with pytest.raises(CsvFileError, match=r"curve\.csv: field 'timesteps': expected a number of decisions \(0 or"):
        read_curve(tmp_path / "curve.csv")
    code, _, err = cli(["compare-policies", "--options", '{"world": "x.yaml"}', "--out", tmp_path / "cmp"], capsys)
    assert code == 2 and "--options: a world ('x.yaml') is --worlds's to give" in err


def test_readers_refuse_what_would_take_more_than_their_bound(tmp_path):
    from emmi_gym.inputs.csv_files import MAX_CSV_BYTES, CsvFileError, read_csv_file
    from emmi_gym.tools.training.demonstrations import MAX_DEMONSTRATION_BYTES, Demonstrations, DemonstrationsError

    (tmp_path / "big.csv").write_bytes(b"a\n" + b"1\n" * (MAX_CSV_BYTES // 2))
    with pytest.raises(CsvFileError, match="big.csv"):
        read_csv_file(tmp_path / "big.csv", "learning curve")
    with zipfile.ZipFile(tmp_path / "big.npz", "w", zipfile.ZIP_DEFLATED) as archive:
        with archive.open("obs_map.npy", "w", force_zip64=True) as member:
            header = np.lib.format.header_data_from_array_1_0(np.zeros(0, np.uint8))
            np.lib.format.write_array_header_1_0(member, dict(header, shape=(MAX_DEMONSTRATION_BYTES + 1,)))
            for _ in range(MAX_DEMONSTRATION_BYTES // 2**24 + 1):
                member.write(bytes(2**24))
    with pytest.raises(DemonstrationsError, match=r"big\.npz: expected a demonstrations file of at most 0.5 GiB"):
        Demonstrations.load(tmp_path / "big.npz")


def test_a_ray_address_that_is_not_private_is_named():
    from emmi_gym.concurrency.ray_cluster import public_host

    assert [public_host(a) for a in ("127.0.0.1:6379", "10.1.2.3:6379", "ray://192.168.0.9:10001",
                                     "localhost:6379")] == [None] * 4
    assert public_host("8.8.8.8:6379") == "8.8.8.8" and public_host("ray://1.1.1.1:10001") == "1.1.1.1"


@pytest.mark.slow
def test_a_ray_actor_that_overruns_its_call_is_named_within_the_timeout():
    """Ray gives no progress within a call: the worker timeout bounds the whole call (a fragment)."""
    from emmi_gym.concurrency.ray_cluster import RayActor, connect_ray

    class Sleeper:  # defined here, so that Ray sends it to the actor by value
        def sleep(self, seconds: float) -> float:
            time.sleep(seconds)
            return seconds

    ray, started = connect_ray("local")
    try:
        actor = RayActor(ray, "rollout worker 0", Sleeper)
        actor.submit("sleep", 0.1)
        assert actor.result(heartbeat_timeout=30.0) == 0.1
        actor.submit("sleep", 60.0)
        began = time.monotonic()
        with pytest.raises(ActorStalled, match=r"rollout worker 0 \(a Ray actor\) has not ended its call within 2 s"):
            actor.result(heartbeat_timeout=2.0)
        assert time.monotonic() - began < 30.0
        actor.close(0.0)
    finally:
        if started:
            ray.shutdown()

