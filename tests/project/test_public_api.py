"""What users and their saved work name stays usable across the package's move into two halves (0.3.0):
``gymnasium.make`` ids, ``emmi_gym.pretrained``, the ``emmi-gym`` command (also ``python -m emmi_gym``), the
tools' old module names (deprecated, with a FutureWarning naming the new one) and models saved under them."""

import json
import subprocess
import sys
import warnings

import gymnasium as gym
import pytest
from helpers import ROOT

import emmi_gym
from emmi_gym._moved import MOVED


def run_python(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT)


def test_the_shipped_agents_and_env_ids_are_where_users_find_them():
    with warnings.catch_warnings():
        warnings.simplefilter("error", FutureWarning)
        import emmi_gym.pretrained as pretrained
    assert pretrained is emmi_gym.pretrained
    assert "explore_plans_emmi" in pretrained.names()
    gym.register_envs(emmi_gym)
    assert "emmi_gym/ExplorePlans-v1" in gym.registry


@pytest.mark.slow  # a fresh interpreter importing the tools: over 2 s
def test_an_old_module_name_is_the_new_module_with_a_warning_naming_it():
    done = run_python("import warnings; warnings.simplefilter('always')\n"
                      "import emmi_gym.training.train as old\nimport emmi_gym.tools.training.train as new\n"
                      "from emmi_gym.experiments.ab import run_ab\n"
                      "print(old is new, run_ab.__module__)")
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True", "emmi_gym.tools.experiments.ab"]
    warned = [line for line in done.stderr.splitlines() if "FutureWarning" in line]
    assert len(warned) == 2  # once per old package, not per module
    assert "emmi_gym.training is now emmi_gym.tools.training; the old name goes in emmi-gym 0.4.0" in warned[0]


def test_importing_the_package_registers_the_ids_and_nothing_else():
    """No import hook, no module of the tools and no old name comes with ``import emmi_gym``; the shipped agents
    come on first use of ``emmi_gym.pretrained``."""
    done = run_python("import sys\nhooks = (list(sys.meta_path), list(sys.path_hooks))\nimport emmi_gym, gymnasium\n"
                      "print((list(sys.meta_path), list(sys.path_hooks)) == hooks)\n"
                      "print(sorted(m for m in sys.modules if m.startswith(('emmi_gym.tools', 'emmi_gym._moved'))))\n"
                      "print('emmi_gym/LoopCorridor-v1' in gymnasium.registry, emmi_gym.pretrained.__name__)")
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["True", "[]", "True emmi_gym.tools.pretrained"]


@pytest.mark.slow  # a fresh interpreter importing the tools: over 2 s
def test_every_moved_module_and_name_is_the_new_one_with_a_warning_naming_it():
    """Each old name of :data:`emmi_gym._moved.MOVED` (and the loop-order functions that left the A/B module)
    imports the very module (function) it moved to, with one FutureWarning naming the new name and the release
    the old one goes in (none for ``emmi_gym.pretrained``, which stays)."""
    done = run_python("import importlib, json, warnings\nfrom emmi_gym._moved import MOVED\nfound = {}\n"
                      "for old, (new, _) in MOVED.items():\n"
                      "    with warnings.catch_warnings(record=True) as caught:\n"
                      "        warnings.simplefilter('always')\n"
                      "        same = importlib.import_module(old) is importlib.import_module(new)\n"
                      "    found[old] = [same, [str(w.message) for w in caught if w.category is FutureWarning]]\n"
                      "from emmi_gym.tools.evaluation import loop_order\n"
                      "with warnings.catch_warnings(record=True) as caught:\n"
                      "    warnings.simplefilter('always')\n"
                      "    from emmi_gym.tools.experiments.ab import closed_loop_first\n"
                      "found['ab'] = [closed_loop_first is loop_order.closed_loop_first,\n"
                      "               [str(w.message) for w in caught]]\n"
                      "print(json.dumps(found))")
    assert done.returncode == 0, done.stderr
    found = json.loads(done.stdout)
    for old, (new, gone_in) in MOVED.items():
        expected = [] if gone_in is None else [f"{old} is now {new}; the old name goes in emmi-gym {gone_in}"]
        assert found[old] == [True, expected], old
    assert found["ab"] == [True, ["emmi_gym.tools.experiments.ab.closed_loop_first is now "
                                  "emmi_gym.tools.evaluation.loop_order.closed_loop_first; the old name goes in "
                                  "emmi-gym 0.5.0"]]


def test_a_name_that_never_was_is_still_an_import_error():
    with warnings.catch_warnings(), pytest.raises(ModuleNotFoundError, match="emmi_gym.training.no_such_module"):
        warnings.simplefilter("ignore", FutureWarning)
        __import__("emmi_gym.training.no_such_module")


def test_a_model_saved_under_the_old_module_names_loads_without_the_aliases():
    """The shipped agents' model.zip name their classes ``emmi_gym.training.*`` (saved before 0.3.0): they load
    from the classes' current modules, with no deprecation warning."""
    pytest.importorskip("sb3_contrib")
    import zipfile

    from emmi_gym.tools.training.target_policy import TargetScoringPolicy

    assert b"emmi_gym.training.target_policy" in zipfile.ZipFile(emmi_gym.pretrained.model_path("loop_order_emmi"))\
        .read("data")
    with warnings.catch_warnings():
        warnings.simplefilter("error", FutureWarning)
        model = emmi_gym.pretrained.load("loop_order_emmi")
    assert type(model.policy) is TargetScoringPolicy


@pytest.mark.slow  # three fresh interpreters
def test_the_command_runs_as_a_module_and_under_its_old_subcommand_name():
    done = subprocess.run([sys.executable, "-m", "emmi_gym", "--version"], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == f"emmi-gym {emmi_gym.__version__}"
    old = subprocess.run([sys.executable, "-m", "emmi_gym", "metrics"], capture_output=True, text=True, timeout=120)
    new = subprocess.run([sys.executable, "-m", "emmi_gym", "paper-example"], capture_output=True, text=True,
                         timeout=120)
    assert old.returncode == new.returncode == 0 and old.stdout == new.stdout and "Fig. 5" in new.stdout
    assert "`emmi-gym metrics` is now `emmi-gym paper-example`" in old.stderr
