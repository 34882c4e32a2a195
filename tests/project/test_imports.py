"""Every module of the package imports, in the quick lane (``pytest -m "not slow"``): a module that only the
slow tests reach (a training module, a command) still fails there at once on a broken import, a syntax error
or a name that moved. Only a module whose optional extra is not installed is skipped, saying which."""

import ast
import importlib
import inspect
import pkgutil
import textwrap
import warnings
from pathlib import Path

import pytest
from test_layout import is_private, private_names_defined, privates_of_self

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


#: The underscore methods of other libraries' classes that those libraries document as the ones to override:
#: SB3's callback hooks (its guide's "Custom Callback"), and a policy's network builder and the constructor
#: arguments it saves (its "Custom Policy" guide). Any other private a class of the package shares with a base
#: class of another library is that library's to rename.
HOOKS = {
    "stable_baselines3.common.callbacks": {"_init_callback", "_on_training_start", "_on_rollout_start", "_on_step",
                                           "_on_rollout_end", "_on_training_end"},
    "stable_baselines3.common.policies": {"_build", "_get_constructor_parameters"},
    "sb3_contrib.common.maskable.policies": {"_build", "_get_constructor_parameters"},
}


def private_names_of(cls: type) -> set[str]:
    """The underscore names a class of another library defines or sets on ``self`` (by its source, where it has
    one; compiled classes by their attributes)."""
    names = {name for name in vars(cls) if is_private(name)}
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    except (OSError, TypeError):
        return names
    return names | {node.attr for node in ast.walk(tree) if isinstance(node, ast.Attribute)
                    and isinstance(node.value, ast.Name) and node.value.id == "self" and is_private(node.attr)}


def shared_privates(cls: type) -> dict[str, list[str]]:
    """The underscore names the class ``cls`` defines or assigns on ``self`` that a base class of another library
    has too (but the hooks that library documents, :data:`HOOKS`): for each such base, those names."""
    try:
        node = ast.parse(textwrap.dedent(inspect.getsource(cls))).body[0]
    except OSError:  # made by a factory (a namedtuple): no class statement of its own
        return {}
    own = private_names_defined(node) | privates_of_self(node, stored=True)
    found = {}
    for base in cls.__mro__[1:]:
        if base.__module__.partition(".")[0] in ("emmi_gym", "builtins"):
            continue
        if shared := own & private_names_of(base) - HOOKS.get(base.__module__, set()):
            found[f"{base.__module__}.{base.__qualname__}"] = sorted(shared)
    return found


def test_a_private_shared_with_another_librarys_base_class_is_found():
    from gymnasium import Wrapper

    class Overrides(Wrapper):
        def __init__(self, env):
            super().__init__(env)
            self._mine, self._action_space = 1, None  # gymnasium's Wrapper keeps its action space there

        def _own(self):
            pass

    assert shared_privates(Overrides) == {"gymnasium.core.Wrapper": ["_action_space"]}


def test_no_class_shares_a_private_with_another_librarys_base_class():
    """A class of the package that extends another library's class (an SB3 callback, policy or ``VecEnv``, a
    gymnasium wrapper) neither overwrites that class's private state nor overrides its private methods, but for
    the hooks the library documents: what such a class declares is its own."""
    found = {}
    for name in MODULES:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", FutureWarning)
                module = importlib.import_module(name)
        except ModuleNotFoundError as error:
            if extra_of(error.name) is None:
                raise
            continue
        for cls in vars(module).values():
            if inspect.isclass(cls) and cls.__module__ == name and (shared := shared_privates(cls)):
                found[f"{name}.{cls.__qualname__}"] = shared
    assert found == {}
