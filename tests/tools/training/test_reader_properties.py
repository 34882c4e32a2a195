"""Random bytes and random small structures given to the readers of the files a user hands the training side
(demonstrations, agent configurations, training.yaml, model zips, CSVs): whatever they are given, only the
package's own input errors (:data:`emmi_gym.inputs.errors.INPUT_ERRORS`) come out, never numpy's, zipfile's,
PyYAML's, json's or csv's."""

import csv
import io
import json
import tempfile
import zipfile
from pathlib import Path

import numpy as np
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from emmi_gym.inputs.csv_files import read_csv_file
from emmi_gym.inputs.errors import INPUT_ERRORS
from emmi_gym.tools.training.config import load_agent_config
from emmi_gym.tools.training.demonstrations import Demonstrations
from emmi_gym.tools.training.run_folders import RunFolder
from emmi_gym.tools.training.run_folders.model_files import check_model_file

EXAMPLES = settings(max_examples=40, deadline=None)

scalars = st.none() | st.booleans() | st.integers(-2**70, 2**70) | st.floats() | st.text(max_size=12)


def structures(keys):
    """Nested lists and mappings of scalars, the mappings' keys drawn from ``keys`` or any short text."""
    return st.recursive(scalars, lambda inner: st.lists(inner, max_size=4) |
                        st.dictionaries(keys | st.text(max_size=8), inner, max_size=5), max_leaves=12)


def only_input_errors(read, path: Path) -> None:
    """``read(path)`` returns or raises one of the package's input errors."""
    try:
        read(path)
    except INPUT_ERRORS:
        pass


def in_a_folder(name: str, content: bytes, read) -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / name
        path.write_bytes(content)
        only_input_errors(read, path)


READERS = {
    "demos.npz": lambda path: Demonstrations.load(path),
    "agent.yaml": load_agent_config,
    "training.yaml": lambda path: RunFolder(path.parent).record(),
    "model.zip": lambda path: check_model_file(path, "MaskablePPO"),
    "curve.csv": lambda path: read_csv_file(path, "curve", required=["timesteps"], numeric=["ate"]),
}


@EXAMPLES
@given(st.sampled_from(sorted(READERS)), st.binary(max_size=2000))
def test_random_bytes(name, content):
    in_a_folder(name, content, READERS[name])


AGENT_KEYS = st.sampled_from(["env", "id", "kwargs", "algorithm", "policy", "hyperparameters", "n_envs", "vec_env",
                              "seed", "total_timesteps", "eval", "freq", "episodes", "checkpoint_freq", "n_steps",
                              "policy_kwargs", "net_arch", "particles", "world"])


@EXAMPLES
@given(structures(AGENT_KEYS))
def test_random_agent_configurations(data):
    in_a_folder("agent.yaml", yaml.safe_dump(data).encode(), load_agent_config)


@EXAMPLES
@given(structures(st.sampled_from(["timesteps", "wall_seconds", "machine", "init_from", "finished", "torch"])))
def test_random_training_records(data):
    in_a_folder("training.yaml", yaml.safe_dump(data).encode(), READERS["training.yaml"])


ARRAY_NAMES = st.sampled_from(["masks", "actions", "episodes", "obs_map", "obs_pose"]) | st.text("abc_", max_size=5)
ARRAYS = hnp.arrays(st.sampled_from([np.bool_, np.int8, np.int64, np.uint8, np.float32, np.float64, np.complex64,
                                     np.dtype("<U2"), np.dtype(">f4")]),
                    hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=3))


@EXAMPLES
@given(st.dictionaries(ARRAY_NAMES, ARRAYS, max_size=6), st.booleans())
def test_random_demonstrations(arrays, compressed):
    buffer = io.BytesIO()
    (np.savez_compressed if compressed else np.savez)(buffer, **{name or "x": value for name, value in arrays.items()})
    in_a_folder("demos.npz", buffer.getvalue(), READERS["demos.npz"])


MEMBERS = st.sampled_from(["data", "policy.pth", "pytorch_variables.pth", "policy.optimizer.pth", "_stable_baselines3"
                           "_version"]) | st.text("abc.", min_size=1, max_size=6)
CONTENTS = st.binary(max_size=300) | structures(st.sampled_from(["policy_class", "__module__", ":type:"])).map(
    lambda value: json.dumps(value).encode())


@EXAMPLES
@given(st.dictionaries(MEMBERS, CONTENTS, max_size=4))
def test_random_model_zips(members):
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, content in members.items():
            archive.writestr(name, content)
    in_a_folder("model.zip", buffer.getvalue(), READERS["model.zip"])


@EXAMPLES
@given(st.lists(st.lists(st.sampled_from(["timesteps", "ate", "", "nan", "1", "-2.5e3", "inf"]) | st.text(max_size=6),
                         max_size=4), max_size=5))
def test_random_csvs(lines):
    text = io.StringIO()
    csv.writer(text).writerows(lines)
    in_a_folder("curve.csv", text.getvalue().encode(), READERS["curve.csv"])
