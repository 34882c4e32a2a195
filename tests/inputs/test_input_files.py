"""The YAML files users hand in (world files, agent configurations): hostile or broken input gets a
short, clear error naming the file, never a hang, a memory blow-up or another file's contents."""

import tracemalloc

import pytest
import yaml

from emmi_gym.inputs.yaml_files import MAX_YAML_BYTES
from emmi_gym.tools.training.config import AgentConfigError, load_agent_config
from emmi_gym.world import load_world
from emmi_gym.world.spec import WorldFileError

WORLD = """name: box
bounds: {xmin: -3, ymin: -3, xmax: 3, ymax: 3}
walls:
  - rectangle: {min: [-2, -2], max: [2, 2]}
start: {x: 0, y: 0, theta: 0}
"""

# the "billion laughs": nine levels of nine aliases, 10^9 leaves from under 1 kB
BOMB = "a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n" + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join(['*' + chr(97 + i)] * 9)}]\n" for i in range(8))


@pytest.mark.parametrize("load, error", [(load_world, WorldFileError), (load_agent_config, AgentConfigError)])
def test_alias_bombs_are_refused_at_once_with_little_memory(load, error, tmp_path):
    path = tmp_path / "bomb.yaml"
    path.write_text(WORLD + BOMB)
    assert path.stat().st_size < 1024
    tracemalloc.start()
    with pytest.raises(error, match=r"bomb\.yaml:7:8: expected valid YAML: aliases \(\*name\) are not allowed"):
        load(path)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 10e6


@pytest.mark.parametrize("content, expected", [
    ("name: [box\nbounds: 1\n", r"bad\.yaml:2:\d+: expected valid YAML: expected ',' or ']'"),
    (WORLD + "name: other\n", r"bad\.yaml:6:1: expected valid YAML: duplicate key 'name'"),
    (b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR", r"bad\.yaml: expected a text file \(byte 8 is NUL"),
    (b"name: caf\xe9\n", r"bad\.yaml: expected UTF-8 text \(byte 9 is not UTF-8\)"),
    (WORLD.encode("utf-16"), r"bad\.yaml: expected UTF-8 text \(the file is UTF-16: save it as UTF-8\)"),
    ("just a sentence\n", r"bad\.yaml: expected a mapping of world file fields at the top level, not a str$"),
    ("!!python/object/apply:os.system ['echo hi']\n", r"bad\.yaml:1:1: expected valid YAML: could not determine"),
])
def test_broken_world_files_name_the_file_line_and_column(content, expected, tmp_path):
    path = tmp_path / "bad.yaml"
    (path.write_bytes if isinstance(content, bytes) else path.write_text)(content)
    with pytest.raises(WorldFileError, match=expected):
        load_world(path)


def test_other_files_are_never_echoed(tmp_path):
    secret = tmp_path / "passwd"
    secret.write_text("root:x:0:0:SECRET-LINE:/root:/bin/bash\n")
    with pytest.raises(WorldFileError) as error:
        load_world(secret)
    assert "SECRET" not in str(error.value) and "a world file in YAML, named *.yaml or *.yml" in str(error.value)
    (tmp_path / "secret.yaml").write_text("SECRET-LINE\n")
    with pytest.raises(WorldFileError) as error:
        load_world(tmp_path / "secret.yaml")
    assert "SECRET" not in str(error.value)
    agent = tmp_path / "agent.yaml"
    for base in ("passwd", "secret.yaml", "."):
        agent.write_text(yaml.safe_dump({"base": base}))
        with pytest.raises(AgentConfigError) as error:
            load_agent_config(agent)
        assert "SECRET" not in str(error.value)
        assert "a .yaml file" in str(error.value) or "not a str" in str(error.value)


def test_yaml_12_exponents_read_as_numbers_and_size_is_capped(tmp_path):
    path = tmp_path / "world.yaml"
    path.write_text(WORLD.replace("xmax: 3", "xmax: 3.0e0").replace("ymax: 3", "ymax: 3e0"))
    assert load_world(path).bounds == (-3.0, -3.0, 3.0, 3.0)
    path.write_text(WORLD + "#" * MAX_YAML_BYTES)
    with pytest.raises(WorldFileError, match=r"world\.yaml: expected a world file of at most 1,000,000 bytes"):
        load_world(path)
    with pytest.raises(WorldFileError, match="not a folder"):
        load_world(tmp_path)


NESTED = "[" * 50_000 + "]" * 50_000  # 100 kB: PyYAML's composer would recurse 50,000 deep


def test_deep_nesting_is_refused_naming_the_file_line_and_column(tmp_path):
    import gymnasium as gym

    import emmi_gym  # noqa: F401  (registers the ids)

    world = tmp_path / "deep.yaml"
    world.write_text(WORLD + f"places: {NESTED}\n")
    deep = r"deep\.yaml:6:\d+: expected valid YAML: lists and mappings nested at most 32 deep"
    with pytest.raises(WorldFileError, match=deep):
        load_world(world)
    world.write_text(f"image: map.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nstart: {NESTED}\n")
    with pytest.raises(WorldFileError, match=deep.replace(":6:", ":4:")):
        load_world(world)  # a map_server file
    (tmp_path / "set").mkdir()
    world.rename(tmp_path / "set" / "deep.yaml")
    env = gym.make("emmi_gym/Explore-v1", world=str(tmp_path / "set"))
    with pytest.raises(WorldFileError, match=r"set/" + deep.replace(":6:", ":4:")):
        env.reset(seed=0)  # a map set draws it at the reset
    agent = tmp_path / "deep.yaml"
    agent.write_text(f"seed: {NESTED}\n")
    with pytest.raises(AgentConfigError, match=deep.replace(":6:", ":1:")):
        load_agent_config(agent)
    agent.write_text("seed: " + "{a: " * 31 + "1" + "}" * 31 + "\n")  # 32 deep with the file's own mapping
    with pytest.raises(AgentConfigError) as error:
        load_agent_config(agent)
    assert "nested" not in str(error.value)  # read; refused for what it says, not for its depth


def test_a_chain_of_base_files_is_bounded(tmp_path):
    for k in range(3000):
        (tmp_path / f"c{k}.yaml").write_text(f"base: c{k + 1}.yaml\n" if k < 2999 else "algorithm: PPO\n")
    with pytest.raises(AgentConfigError, match=r"c0\.yaml: field 'base': expected a chain of at most 16 configuration "
                                               r"files linked by base"):
        load_agent_config(tmp_path / "c0.yaml")


def test_a_broken_file_named_by_an_env_option_names_the_option_and_the_file(tmp_path):
    (tmp_path / "text.png").write_text("not an image\n")
    agent = tmp_path / "agent.yaml"
    agent.write_text(yaml.safe_dump({"env": {"id": "emmi_gym/LoopCorridor-v1", "kwargs": {"particles": 3}},
                                     "algorithm": "PPO", "n_envs": 1, "vec_env": "dummy",
                                     "eval": {"env_kwargs": {"world": str(tmp_path / "text.png")}}}))
    with pytest.raises(AgentConfigError, match=r"agent\.yaml: field 'eval\.env_kwargs\.world': expected an option "
                                               r"naming a valid file \(.*text\.png: expected a PNG or PGM image"):
        load_agent_config(agent)


def test_input_errors_pickle_whole():
    """Errors cross process boundaries (worker pools, Ray) as they were: class, fields and message."""
    import pickle

    from emmi_gym.inputs.errors import FieldError
    from emmi_gym.inputs.validation import OptionError

    for error in (OptionError("gym.make", "particles", "an integer >= 1", -1), FieldError("a.yaml", "", "a mapping")):
        copy = pickle.loads(pickle.dumps(error))
        assert type(copy) is type(error) and str(copy) == str(error)
        assert (copy.source, copy.field, copy.expected) == (error.source, error.field, error.expected)
