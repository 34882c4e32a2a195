"""The top-level envs/ folder is the ids: every file in it registered, every id with its file, and the files
shipped inside the wheel (``emmi_gym/envs``), where an install outside the repository reads them."""

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import gymnasium as gym
import pytest
from helpers import ROOT

import emmi_gym
from emmi_gym.env.definitions import definitions_folder
from emmi_gym.env.registration import ENV_IDS
from emmi_gym.inputs.env_ids import NAMESPACE

tomllib = pytest.importorskip("tomllib")  # Python 3.11+

ENVS = ROOT / "envs"
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]

gym.register_envs(emmi_gym)


def test_every_file_of_envs_is_registered_and_every_id_has_its_file():
    files = sorted(path.stem for path in ENVS.glob("*"))
    registered = sorted(env_id.split("/", 1)[1] for env_id in gym.registry if env_id.startswith(f"{NAMESPACE}/"))
    assert files == registered == sorted(ENV_IDS), f"envs/ holds {files}; emmi_gym registers {registered}"
    assert definitions_folder() == ENVS  # a source checkout reads the repository's own


def test_the_wheel_names_every_package_and_maps_envs_into_it():
    """pyproject.toml lists the packages by name (a find would miss ``emmi_gym.envs``): each package of the
    tree must be there, or the wheel lacks it."""
    tree = sorted(".".join(path.parent.relative_to(ROOT).parts) for path in (ROOT / "emmi_gym").rglob("__init__.py"))
    assert sorted(PYPROJECT["packages"]) == sorted([*tree, "emmi_gym.envs"]), \
        "pyproject.toml's [tool.setuptools] packages must name every folder of emmi_gym with an __init__.py"
    assert PYPROJECT["package-dir"] == {"emmi_gym.envs": "envs"}
    assert PYPROJECT["package-data"]["emmi_gym.envs"] == ["*.yaml"]


@pytest.mark.slow
def test_a_wheel_installed_outside_the_repository_makes_every_id(tmp_path):
    """Build the wheel from a copy of what it is built from, install it into a folder of its own and, from
    outside the repository with nothing else of emmi_gym on the path, make every id."""
    source = tmp_path / "source"
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    for name in ("emmi_gym", "envs"):
        shutil.copytree(ROOT / name, source / name, ignore=ignore)
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, source / name)
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    subprocess.run([*pip, "wheel", str(source), "--no-deps", "--no-build-isolation", "-w", str(tmp_path / "wheel")],
                   check=True, capture_output=True, timeout=600)
    (wheel,) = (tmp_path / "wheel").glob("*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    assert {f"emmi_gym/envs/{path.name}" for path in ENVS.glob("*.yaml")} <= names
    assert not any(name.startswith("envs/") for name in names)  # inside the package, not a top-level folder
    site = tmp_path / "site"
    subprocess.run([*pip, "install", "--no-deps", "--target", str(site), str(wheel)], check=True,
                   capture_output=True, timeout=600)
    script = ("import gymnasium as gym, emmi_gym\n"
              "from emmi_gym.env.registration import ENV_IDS\n"
              "for name in ENV_IDS: gym.make('emmi_gym/' + name).close()\n"
              "print(emmi_gym.__file__, sorted(ENV_IDS))\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600,
                          cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(site)})
    assert done.returncode == 0, done.stderr[-2000:]
    where, ids = done.stdout.split(" ", 1)
    assert Path(where).is_relative_to(site)
    assert ids.strip() == str(sorted(ENV_IDS))
