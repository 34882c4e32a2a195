"""Every module of the package imports, in the quick lane (``pytest -m "not slow"``): a module that only the
slow tests reach (a training module, a command) still fails there at once on a broken import, a syntax error
or a name that moved. Only a module whose optional extra is not installed is skipped, saying which."""

import importlib
import pkgutil
import warnings
from pathlib import Path

import pytest

import emmi_gym
from emmi_gym.inputs.extras import extra_of


def package_modules() -> list[str]:
    """Every module and package of emmi_gym, found on disk (pkgutil, as ``walk_packages`` does, but without
    importing the packages to find their submodules: a package whose extra is missing still lists them)."""
    names = ["emmi_gym"]

    def walk(folder: Path, prefix: str) -> None:
        for info in pkgutil.iter_modules([str(folder)], prefix):
            names.append(info.name)
            if info.ispkg:
                walk(folder / info.name.rpartition(".")[2], info.name + ".")

    walk(Path(emmi_gym.__file__).parent, "emmi_gym.")
    return sorted(names)


MODULES = package_modules()


def test_the_walk_finds_every_file_of_the_package():
    root = Path(emmi_gym.__file__).parent
    on_disk = {".".join(("emmi_gym", *p.relative_to(root).with_suffix("").parts)).removesuffix(".__init__")
               for p in root.rglob("*.py")}
    assert on_disk == set(MODULES)


@pytest.mark.parametrize("name", MODULES)
def test_every_module_imports(name):
    try:
        with warnings.catch_warnings():  # an old name's warning is test_public_api's to check
            warnings.filterwarnings("ignore", f"{name} is now ", FutureWarning)
            importlib.import_module(name)
    except ModuleNotFoundError as error:
        extra = extra_of(error.name)
        if extra is None:
            raise
        pytest.skip(f"{name} needs the '{extra}' extra (no module named {error.name!r} here)")
