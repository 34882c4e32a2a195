"""The maintainers' scripts of scripts/ (CONTRIBUTING.md, "Maintainer tools"): the episode hashes are the same
run after run and change with what they hash, a shipped agent's card says what its run and its evaluation hold,
and repeated training with rollout workers is counted clean."""

import re

import gymnasium as gym
import pytest
import yaml
from helpers import SCRIPTS, run_script

import emmi_gym

HASHED = ["ExploreVelocity-v0", "Explore-v1"]


def hashes(*args) -> dict[str, str]:
    done = run_script(SCRIPTS / "episode_hashes.py", "--ids", *HASHED, "--decisions", "2", "--velocity-steps", "20",
                      "--no-replay", *args)
    assert done.code == 0, done.err
    found = dict(line.rsplit(" ", 1) for line in done.out.splitlines())
    assert all(re.fullmatch(r"[0-9a-f]{64}", digest) for digest in found.values())
    return found


def test_episode_hashes_are_the_same_run_after_run_and_differ_by_seed_and_by_what_they_hash():
    first = hashes("--seeds", "2")
    assert list(first) == [f"emmi_gym/{name} seed={seed}" for name in sorted(HASHED) for seed in (0, 1)]
    assert hashes("--seeds", "2") == first
    assert len(set(first.values())) == 4
    without_info = hashes("--seeds", "1", "--no-info")
    assert set(without_info) < set(first) and not set(without_info.values()) & set(first.values())


def test_episode_hashes_name_an_id_that_is_not_registered():
    done = run_script(SCRIPTS / "episode_hashes.py", "--ids", "Explore-v9")
    assert done.code == 2 and "--ids: no id ['Explore-v9'] is registered" in done.err


def test_episode_hashes_hash_every_registered_id_by_default():
    gym.register_envs(emmi_gym)
    ids = sorted(i.removeprefix("emmi_gym/") for i in gym.registry if i.startswith("emmi_gym/"))
    done = run_script(SCRIPTS / "episode_hashes.py", "--ids", "Explore-v9")
    assert done.code == 2 and f"the ids: {ids}" in done.err  # what it hashes without --ids


@pytest.mark.slow  # a replay of the test log in a process of its own
def test_episode_hashes_hash_the_log_replay_after_the_episodes():
    done = run_script(SCRIPTS / "episode_hashes.py", "--ids", "ExploreVelocity-v0", "--seeds", "1",
                      "--velocity-steps", "2")
    assert done.code == 0, done.err
    lines = [line.rsplit(" ", 1) for line in done.out.splitlines()]
    assert [what for what, _ in lines] == ["emmi_gym/ExploreVelocity-v0 seed=0", "replay intel-first-loop.log.gz"]
    assert all(re.fullmatch(r"[0-9a-f]{64}", digest) for _, digest in lines)


@pytest.mark.slow  # reads a trained run
def test_ship_agent_copies_the_run_and_writes_its_card_from_an_evaluation(small_corridor_run,
                                                                          small_corridor_evaluation, tmp_path):
    done = run_script(SCRIPTS / "ship_agent.py", small_corridor_run, "small_corridor", "--episodes", "2", "--seed",
                      "7", "--baselines", "frontier", "--episodes-csv", small_corridor_evaluation / "episodes.csv",
                      "--evaluated-on", "the test machine", "--into", tmp_path, "--note", "A test's agent.")
    assert done.code == 0, done.err
    shipped = tmp_path / "small_corridor"
    assert sorted(p.name for p in shipped.iterdir()) == ["MODEL_CARD.md", "config.yaml", "model.zip", "training.yaml"]
    assert (shipped / "model.zip").read_bytes() == (small_corridor_run / "model.zip").read_bytes()
    card = (shipped / "MODEL_CARD.md").read_text()
    assert card.startswith("# small_corridor\n\nMaskablePPO (MultiInputPolicy) on `emmi_gym/LoopCorridor-v1` with the "
                           "`emmi` reward.")
    assert "- Budget: 16 decisions, seed 3, 1 envs." in card and "\nA test's agent.\n" in card
    assert "emmi-gym evaluate --pretrained small_corridor --episodes 2 --seed 7 --baselines frontier" in card
    assert "on\nthe test machine. Reproduce:" in card and "small_corridor - frontier: 2 pairs" in card
    assert yaml.safe_load(card.split("```yaml\n")[1].split("```")[0])["total_timesteps"] == 16  # the configuration
    assert done.out.endswith(f"wrote {shipped}\n")


@pytest.mark.slow  # reads a trained run
@pytest.mark.parametrize("change, expected", [
    (["--episodes", "3"], "--episodes-csv: expected 3 episodes of each policy, found {'small_corridor': 2, "),
    (["--evaluated-on", None], "--episodes-csv needs --evaluated-on"),
])
def test_ship_agent_refuses_an_evaluation_that_is_not_the_cards(small_corridor_run, small_corridor_evaluation,
                                                                tmp_path, change, expected):
    args = {"--episodes": "2", "--seed": "7", "--baselines": "frontier", "--evaluated-on": "here",
            "--episodes-csv": small_corridor_evaluation / "episodes.csv", "--into": tmp_path}
    args.update(zip(change[::2], change[1::2], strict=True))
    done = run_script(SCRIPTS / "ship_agent.py", small_corridor_run, "small_corridor",
                      *(word for option, value in args.items() if value is not None for word in (option, value)))
    assert done.code == 2 and expected in done.err, done.err


def test_ship_agent_refuses_a_folder_without_a_model(tmp_path):
    done = run_script(SCRIPTS / "ship_agent.py", tmp_path, "nothing", "--into", tmp_path / "shipped")
    assert done.code == 2 and f"no model.zip in {tmp_path}" in done.err
    assert not (tmp_path / "shipped").exists()


@pytest.mark.slow  # trains with rollout workers, in processes of its own
def test_worker_runs_counts_a_training_run_with_rollout_workers_that_ends_clean():
    done = run_script(SCRIPTS / "worker_runs.py", "--runs", "1")
    assert done.code == 0, done.err
    assert done.out.splitlines() == ["run 1 (policy_lag 0): exit 0, clean", "1 of 1 runs succeeded without a traceback"]
