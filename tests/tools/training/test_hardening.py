"""Agent configurations that SB3 would only break on when it builds the network, model files that are not
what their run says, and output folders that cannot be written: each a clear error naming the file, field
or option, before any work and in little memory."""

import json
import struct
import zipfile
import zlib

import pytest
import yaml

from emmi_gym.tools.cli import main
from emmi_gym.tools.training.config import AgentConfigError, load_agent_config

AGENT = {"env": {"id": "emmi_gym/LoopCorridor-v1", "kwargs": {"particles": 3}}, "algorithm": "PPO",
         "policy": "MultiInputPolicy", "hyperparameters": {"n_steps": 16, "batch_size": 16}, "n_envs": 1,
         "vec_env": "dummy"}


def agent_file(folder, **changes):
    path = folder / "agent.yaml"
    path.write_text(yaml.safe_dump(dict(AGENT, **changes)))
    return path


@pytest.mark.parametrize("policy_kwargs, expected", [
    ({"net_arch": [-5]}, r"field 'hyperparameters\.policy_kwargs\.net_arch\[0\]': expected an integer in \[1, 1024\]"),
    ({"net_arch": {"pi": [64], "qf": [64]}}, r"field 'hyperparameters\.policy_kwargs\.net_arch\.qf': expected one of "
                                             r"the networks \['pi', 'vf'\]"),
    ({"activation_fn": "os.system"}, r"field 'hyperparameters\.policy_kwargs\.activation_fn': expected one of "
                                     r"\['ReLU', 'Tanh', .*\], got 'os\.system'"),
    ({"use_sde": True}, r"field 'hyperparameters\.policy_kwargs\.use_sde': expected one of the keys"),
    ({"features_extractor_kwargs": {"features_dim": 0}},
     r"field 'hyperparameters\.policy_kwargs\.features_extractor_kwargs\.features_dim': expected an integer"),
])
def test_policy_kwargs_sb3_would_break_on_are_refused_naming_the_field(tmp_path, policy_kwargs, expected):
    path = agent_file(tmp_path, hyperparameters={"n_steps": 16, "policy_kwargs": policy_kwargs})
    with pytest.raises(AgentConfigError, match=rf"agent\.yaml: {expected}"):
        load_agent_config(path)


def test_policy_kwargs_name_their_classes_by_a_word(tmp_path):
    import gymnasium as gym
    import torch
    from stable_baselines3 import PPO

    from emmi_gym.tools.training.config import sb3_policy_kwargs

    path = agent_file(tmp_path, hyperparameters={"n_steps": 16, "policy_kwargs": {
        "net_arch": {"pi": [32], "vf": [16]}, "activation_fn": "Tanh", "optimizer_class": "AdamW"}})
    config = load_agent_config(path)
    kwargs = sb3_policy_kwargs(config.hyperparameters["policy_kwargs"])
    assert kwargs["activation_fn"] is torch.nn.Tanh and kwargs["optimizer_class"] is torch.optim.AdamW
    model = PPO("MultiInputPolicy", gym.make("emmi_gym/LoopCorridor-v1", particles=3), n_steps=16, batch_size=16,
                policy_kwargs=kwargs)
    assert isinstance(model.policy.optimizer, torch.optim.AdamW)
    assert yaml.safe_load(yaml.safe_dump(config.as_yaml_dict()))["hyperparameters"]["policy_kwargs"][
        "activation_fn"] == "Tanh"  # written beside the model as it was read


def zip_of_zeros(path, name: str, size: int, block: int = 1 << 20):
    """A zip whose member ``name`` unpacks to ``size`` zero bytes, made in a moment: one deflated block of
    zeros after a full flush, repeated (the copies do not refer to one another)."""
    compressor = zlib.compressobj(9, zlib.DEFLATED, -15)
    copy = compressor.compress(b"\0" * block) + compressor.flush(zlib.Z_FULL_FLUSH)
    data = copy * (size // block) + zlib.compressobj(9, zlib.DEFLATED, -15).flush()
    crc = 0
    for _ in range(size // block):
        crc = zlib.crc32(b"\0" * block, crc)
    header = struct.pack("<4s5H3L2H", b"PK\3\4", 20, 0, 8, 0, 0, crc, len(data), size, len(name), 0)
    central = struct.pack("<4s6H3L5H2L", b"PK\1\2", 20, 20, 0, 8, 0, 0, crc, len(data), size, len(name), 0, 0, 0,
                          0, 0, 0)
    end = struct.pack("<4s4H2LH", b"PK\5\6", 0, 0, 1, 1, len(central) + len(name), len(header) + len(name) + len(data),
                      0)
    path.write_bytes(header + name.encode() + data + central + name.encode() + end)
    return path


@pytest.fixture
def run_folder(tmp_path):
    """A run folder with a PPO configuration beside where its model goes."""
    (tmp_path / "config.yaml").write_text(yaml.safe_dump(AGENT))
    return tmp_path


def _evaluate_error(model, capsys) -> str:
    with pytest.raises(SystemExit) as exit_info:
        main(["evaluate", str(model), "--episodes", "1"])
    assert exit_info.value.code == 2
    return capsys.readouterr().err


def test_a_model_without_data_or_of_another_algorithm_names_the_file(run_folder, capsys):
    model = run_folder / "model.zip"
    with zipfile.ZipFile(model, "w") as archive:
        archive.writestr("policy.pth", b"\0" * 100)
    assert f"{model}: expected a Stable-Baselines3 model, which holds a 'data' member" in _evaluate_error(model, capsys)
    with zipfile.ZipFile(model, "w") as archive:  # what MaskablePPO writes, beside a PPO configuration
        archive.writestr("data", json.dumps({"policy_class": {":type:": "<class 'abc.ABCMeta'>",
                                                              "__module__": "sb3_contrib.common.maskable.policies"}}))
    assert (f"{model}: expected a PPO model, as its run's configuration says (algorithm: PPO); its policy comes from "
            "sb3_contrib.common.maskable.policies, a MaskablePPO policy") in _evaluate_error(model, capsys)
    model.write_text("not a zip")
    assert f"{model}: expected a model .zip written by 'emmi-gym train'" in _evaluate_error(model, capsys)


def test_a_model_whose_members_unpack_to_too_much_is_refused_unread(run_folder, capsys):
    import tracemalloc

    model = zip_of_zeros(run_folder / "model.zip", "data", 20 << 20)  # 20 KB unpacking to 20 MB of NUL bytes
    assert model.stat().st_size < 100_000
    assert zipfile.ZipFile(model).getinfo("data").file_size == 20 << 20  # a valid zip
    assert f"{model}: expected a 'data' member of at most 16 MB, got '20 MB'" in _evaluate_error(model, capsys)
    zip_of_zeros(model, "policy.pth", 300 << 20)
    tracemalloc.start()
    err = _evaluate_error(model, capsys)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert f"{model}: expected a model of at most 256 MB unpacked; its members would unpack to 300 MB" in err
    assert peak < 100e6  # the configuration's env made, nothing unpacked


def test_output_folders_that_cannot_be_written_fail_before_any_work(tmp_path, capsys):
    (tmp_path / "a_file").write_text("x")
    config = agent_file(tmp_path)
    with pytest.raises(SystemExit) as exit_info:
        main(["train", str(config), "--out", str(tmp_path / "a_file" / "sub"), "--quiet"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert f"--out {tmp_path / 'a_file' / 'sub'}: expected a folder that can be made and written to; " \
           f"{tmp_path / 'a_file'} is a regular file, not a folder" in err
    with pytest.raises(SystemExit):
        main(["record", "loop_corridor", "--out", str(tmp_path)])
    assert f"--out {tmp_path}: expected the name of a file to write, not a folder" in capsys.readouterr().err
