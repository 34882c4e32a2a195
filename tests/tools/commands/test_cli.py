"""One meaning per option name across the ``emmi-gym`` subcommands."""

import pytest

from emmi_gym.tools.cli import build_parser
from emmi_gym.tools.commands import arguments

SEEDED = (["ab"], ["demo"], ["benchmark"], ["compare-policies"])
WORKERS = (["ab"], ["demo"], ["clone", "c.yaml", "--out", "o"], ["evaluate", "m.zip"], ["benchmark"],
           ["score-checkpoints", "run"], ["compare-policies"])
RAY = (["train", "c.yaml"], ["benchmark"])


@pytest.mark.parametrize("command", SEEDED)
def test_seeds_is_a_count_from_the_first_seed(command):
    args = build_parser().parse_args([*command, "--seeds", "3", "--first-seed", "7"])
    assert arguments.seed_range(args) == range(7, 10)


@pytest.mark.parametrize("command", SEEDED)
def test_seeds_refuses_a_list(command, capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args([*command, "--seeds", "0", "1"])
    assert "error:" in capsys.readouterr().err


@pytest.mark.parametrize("command", WORKERS)
@pytest.mark.parametrize("value", ["0", "-2", "many"])
def test_workers_is_a_bounded_count_of_processes(command, value, capsys):
    assert build_parser().parse_args(command).workers is None  # one per core
    assert build_parser().parse_args([*command, "--workers", "3"]).workers == 3
    with pytest.raises(SystemExit):
        build_parser().parse_args([*command, "--workers", value])
    assert f"argument --workers: expected an integer >= 1, got '{value}'" in capsys.readouterr().err


@pytest.mark.parametrize("command", RAY)
def test_ray_means_the_same_in_train_and_benchmark(command):
    parse = build_parser().parse_args
    assert parse(command).ray is None
    assert arguments.ray_address(parse([*command, "--ray"])) is None  # Ray's default: RAY_ADDRESS, else local
    assert arguments.ray_address(parse([*command, "--ray", "10.0.0.1:6379"])) == "10.0.0.1:6379"
    assert arguments.ray_address(parse([*command, "--ray", "local"])) == "local"


def _subcommands():
    import argparse

    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices


@pytest.mark.parametrize("command", sorted(_subcommands()))
def test_every_option_says_what_it_does_and_its_default(command):
    import argparse

    for action in _subcommands()[command]._actions:
        if isinstance(action, argparse._HelpAction):
            continue
        name = "/".join(action.option_strings) or action.dest
        assert action.help, f"emmi-gym {command} {name}: no help"
        if action.option_strings and action.default not in (None, False, [], argparse.SUPPRESS):
            assert "default" in action.help, f"emmi-gym {command} {name}: help does not give the default"


def test_version_prints_the_package_version(capsys):
    import emmi_gym

    with pytest.raises(SystemExit) as stop:
        build_parser().parse_args(["--version"])
    assert stop.value.code == 0 and capsys.readouterr().out.strip() == f"emmi-gym {emmi_gym.__version__}"


def test_a_first_run_says_that_numba_compiles_and_where_it_caches(tmp_path, monkeypatch):
    from numba.core import config

    from emmi_gym.slam.kernel_cache import first_run_note, kernel_cache_folder, kernels_compiled

    monkeypatch.setattr(config, "CACHE_DIR", str(tmp_path))  # what NUMBA_CACHE_DIR sets: an empty cache
    assert kernel_cache_folder().is_relative_to(tmp_path) and not kernels_compiled()
    assert first_run_note().startswith("first run: numba compiles the kernels") and str(tmp_path) in first_run_note()
    kernel_cache_folder().mkdir(parents=True, exist_ok=True)
    (kernel_cache_folder() / "_kernels.insert_scans-141.py311.nbi").write_bytes(b"")
    assert kernels_compiled() and first_run_note() is None


def test_a_first_compile_says_how_many_kernels_are_compiled_until_the_count_stops(capsys):
    import sys
    import time

    import emmi_gym.env  # noqa: F401  (the modules holding the kernels)
    from emmi_gym.slam.kernel_cache import cached_kernels
    from emmi_gym.tools.commands.dispatch import compile_progress

    with compile_progress(True, interval=0.1):
        time.sleep(0.6)
    lines = capsys.readouterr().err.splitlines()
    cached, total = cached_kernels([module for name, module in sys.modules.items() if name.startswith("emmi_gym.")])
    assert total >= 10 and 0 <= cached <= total
    assert lines and all(line.startswith("numba: ") and " kernels compiled and cached, 0:00 in" in line
                         for line in lines)
    assert len(lines) <= 3  # the count stopped growing (everything is cached here): the heartbeat ends
    with compile_progress(False, interval=0.1):
        time.sleep(0.3)
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("argv", [["evaluate"], ["train", "c.yaml"], ["benchmark"], ["score-checkpoints", "run"]])
def test_the_commands_that_load_models_say_that_model_files_can_run_code(argv, capsys):
    parser = build_parser()
    assert parser.parse_args([*argv, "--trust-model"]).trust_model
    with pytest.raises(SystemExit):
        parser.parse_args([argv[0], "--help"])
    shown = " ".join(capsys.readouterr().out.split())
    assert "zips of pickles (Stable-Baselines3's format), which can run code" in shown and "--trust-model" in shown
