"""One meaning per option name across the ``emmi-gym`` subcommands."""

import pytest

from emmi_gym.cli import build_parser
from emmi_gym.inputs import arguments

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
