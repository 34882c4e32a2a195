"""The scripts outside the package (measurements/, scripts/ and the hardening audit of tests/hardening/): each one
shows its help in the quick lane (so that a broken import or a name that moved fails at once, even where only a
slow test runs the script), each is run by a test that names it, and each shared helper serves a script."""

import re
from pathlib import Path

import pytest
from helpers import MEASUREMENTS, ROOT, SCRIPTS, run_script

HARDENING = ROOT / "tests" / "hardening"
#: Every script a user or a maintainer runs, by its path from the repository's root.
RUNNABLE = sorted(p for folder in (MEASUREMENTS, SCRIPTS) for p in folder.glob("*.py") if not p.name.startswith("_"))
RUNNABLE.append(HARDENING / "hardening_audit.py")
#: The modules that serve them: the measurements' shared helpers, the audit's training side.
HELPERS = sorted(MEASUREMENTS.glob("_*.py")) + [HARDENING / "training_probes.py"]


@pytest.mark.parametrize("path", RUNNABLE, ids=lambda path: path.name)
def test_every_script_shows_its_help(path):
    done = run_script(path, "--help")
    assert done.code == 0, done.err
    assert done.out.startswith("usage: ") and len(done.out.splitlines()) > 2


def test_every_script_is_run_by_a_test_that_names_it():
    tests = "\n".join(p.read_text() for p in (ROOT / "tests").rglob("test_*.py") if p != Path(__file__))
    named = set(re.findall(r'\b(?:MEASUREMENTS|SCRIPTS) / "(\w+\.py)"', tests))
    missing = sorted(p.name for p in RUNNABLE if p.parent != HARDENING and p.name not in named)
    assert not missing, f"no test runs {missing} (run_script(MEASUREMENTS / NAME, ...) on a tiny input)"
    assert "from hardening_audit import" in (HARDENING / "test_hardening_audit.py").read_text()


@pytest.mark.parametrize("helper", HELPERS, ids=lambda path: path.name)
def test_every_shared_helper_serves_a_script_of_its_folder(helper):
    module = helper.stem
    users = [p.name for p in helper.parent.glob("*.py") if p != helper
             and re.search(rf"^\s*(?:from {module} import|import {module}\b)|\"{module}\"", p.read_text(), re.M)]
    assert users, f"{helper.relative_to(ROOT)} serves no script"
