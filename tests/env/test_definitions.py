"""The ids' definition files: what registration reads from envs/, each mistake in a file named with its field,
and an id of your own registered from a copy of one."""

import re
from pathlib import Path

import gymnasium as gym
import pytest
import yaml
from helpers import ROOT

import emmi_gym
from emmi_gym.env.definitions import EnvFileError, read_env_file, shipped_definitions
from emmi_gym.env.registration import ENTRY_POINT, ENV_IDS, register_env_file

gym.register_envs(emmi_gym)
LOOP_CORRIDOR = ROOT / "envs" / "LoopCorridor-v1.yaml"


def test_each_shipped_file_is_its_id_s_registration():
    for definition in shipped_definitions():
        spec = gym.spec(f"emmi_gym/{definition.id}")
        assert spec.entry_point == ENTRY_POINT and spec.kwargs == definition.options == ENV_IDS[definition.id]
        assert spec.version == definition.version == int(next(iter(definition.versions))[1:])
        assert gym.spec(definition.id).kwargs == definition.options  # the bare id, for "emmi_gym:Id"
    plans = ENV_IDS["ExplorePlans-v1"]
    assert plans["laser"] == {"preset": "sick_lms200", "max_range": 8.0} and plans["max_sim_steps"] == 30000
    assert ENV_IDS["Explore-v1"]["world"] is None


def test_only_the_newest_version_is_registered_and_an_older_one_names_it():
    definition = read_env_file(LOOP_CORRIDOR)
    assert list(definition.versions) == ["v1", "v0"] and definition.versions["v1"]["release"] == "0.2.0"
    assert "emmi_gym/LoopCorridor-v0" not in gym.registry
    with pytest.raises(gym.error.DeprecatedEnv, match=re.escape("Please use `emmi_gym/LoopCorridor-v1`")):
        gym.make("emmi_gym/LoopCorridor-v0")


def write(folder: Path, name: str, data: dict) -> Path:
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def loop_corridor() -> dict:
    return yaml.safe_load(LOOP_CORRIDOR.read_text())


@pytest.mark.parametrize("change, field, expected", [
    (lambda d: d.update(colour="red"), "colour", "one of the fields ['id', 'options', 'versions', 'page']"),
    (lambda d: d.update(id="emmi_gym/LoopCorridor-v1"), "id", "an id Name-vN"),
    (lambda d: d.update(id="LoopCorridor"), "id", "an id Name-vN"),
    (lambda d: d.update(id="LoopCorridor-v2"), "id", "the id the file is named after, 'LoopCorridor-v1'"),
    (lambda d: d.pop("options"), "options", "a mapping of options"),
    (lambda d: d["options"].update({"max range": 8.0}), "options", "keywords of gym.make"),
    (lambda d: d.update(versions={}), "versions", "the id's versions, newest first, from v1"),
    (lambda d: d.update(versions={"v0": {"changes": "x"}, "v1": {"changes": "y"}}), "versions",
     "the id's own version, v1, first"),
    (lambda d: d.update(versions={"v1": {"changes": "x"}, "v1.5": {"changes": "y"}}), "versions",
     "versions named vN"),
    (lambda d: d["versions"].update(v3={"changes": "z"}), "versions", "versions newest first, each once"),
    (lambda d: d["versions"]["v0"].pop("changes"), "versions.v0.changes", "a non-empty string"),
    (lambda d: d["versions"]["v0"].update(date="2026"), "versions.v0.date", "one of the fields"),
    (lambda d: d["page"].pop("rewards"), "page.rewards", "a non-empty string"),
    (lambda d: d["page"]["sets"].pop("laser"), "page.sets", "a line for each option"),
    (lambda d: d["page"]["sets"].update(world="two\nlines"), "page.sets.world", "one line"),
    (lambda d: d["page"].update(more={"Notes": 3}), "page.more.Notes", "a non-empty string"),
])
def test_a_mistake_in_a_file_names_the_file_and_the_field(tmp_path, change, field, expected):
    data = loop_corridor()
    change(data)
    path = write(tmp_path, "LoopCorridor-v1", data)
    with pytest.raises(EnvFileError, match=re.escape(expected)) as raised:
        read_env_file(path)
    assert raised.value.source == str(path) and raised.value.field == field


def test_a_file_that_is_not_a_definition_is_named(tmp_path):
    path = tmp_path / "Broken-v0.yaml"
    path.write_text("id: Broken-v0\noptions: {world: [\n")
    with pytest.raises(EnvFileError, match=re.escape(f"{path}:3:1: expected valid YAML")):
        read_env_file(path)
    with pytest.raises(FileNotFoundError, match="environment definition file"):
        read_env_file(tmp_path / "Nothing-v0.yaml")


@pytest.fixture
def restore_registry():
    before = set(gym.registry)
    yield
    for env_id in set(gym.registry) - before:
        del gym.registry[env_id]


def own_file(folder: Path, world: str = "office") -> Path:
    """A copy of LoopCorridor-v1's file as a user makes one: another id and world, its page left out."""
    data = loop_corridor()
    data.update(id="OfficeCorridor-v0", versions={"v0": {"changes": "the first version"}})
    data["options"].update(world=world, start_at="start", max_decisions=5)
    del data["page"]
    return write(folder, "OfficeCorridor-v0", data)


def test_a_copied_file_registers_an_id_of_your_own(tmp_path, restore_registry):
    assert register_env_file(own_file(tmp_path)) == "OfficeCorridor-v0"
    env = gym.make("OfficeCorridor-v0")
    _, info = env.reset(seed=0)
    assert info["world"] == "office" and env.unwrapped.config.max_decisions == 5
    env.close()
    assert register_env_file(own_file(tmp_path, "loop_corridor"), namespace="mine") == "mine/OfficeCorridor-v0"
    assert gym.spec("mine/OfficeCorridor-v0").kwargs["world"] == "loop_corridor"
    register_env_file(own_file(tmp_path, "loop_corridor"))  # again: the id's options replaced
    assert gym.spec("OfficeCorridor-v0").kwargs["world"] == "loop_corridor"


def test_an_id_of_the_package_s_own_name_is_refused(tmp_path, restore_registry):
    data = loop_corridor()
    data.update(id="LoopCorridor-v2", versions={"v2": {"changes": "mine"}, **data["versions"]})
    path = write(tmp_path, "LoopCorridor-v2", data)
    for namespace in (None, "emmi_gym"):
        with pytest.raises(EnvFileError, match="a name of your own"):
            register_env_file(path, namespace=namespace)
    assert "LoopCorridor-v2" not in gym.registry
    assert register_env_file(path, namespace="mine") == "mine/LoopCorridor-v2"
    assert gym.make("emmi_gym/LoopCorridor-v1").spec.kwargs == ENV_IDS["LoopCorridor-v1"]
