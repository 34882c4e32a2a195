"""``measurements/suite_memory.py``: the peak memory of a command's process tree, and for pytest the test that held
it (named by its plugin, ``measurements/_current_test.py``)."""

import re
import sys
import textwrap

from helpers import MEASUREMENTS, run_script

HOLDER = textwrap.dedent("""\
    import time


    def test_small():
        assert True


    def test_holds_300_mib():
        block = bytearray(b"x") * (300 << 20)  # written, so resident
        time.sleep(0.5)
        assert len(block) == 300 << 20
""")


def test_suite_memory_finds_the_peak_of_a_pytest_run_and_the_test_that_held_it(tmp_path, monkeypatch):
    (tmp_path / "test_holder.py").write_text(HOLDER)
    monkeypatch.setenv("PYTEST_DISABLE_PLUGIN_AUTOLOAD", "1")  # the installed plugins' imports: seconds
    done = run_script(MEASUREMENTS / "suite_memory.py", "--every", "0.05", "--top", "2", "--", sys.executable, "-m",
                      "pytest", tmp_path / "test_holder.py", "-q", "-p", "no:cacheprovider", cwd=tmp_path)
    assert done.code == 0, done.err
    summary = re.match(r"peak memory of the process tree: ([\d.]+) GiB \(summed PSS of (\d+) processes, \d+ s in\); "
                       r"exit 0 after \d+ s\n", done.out)
    assert summary and float(summary[1]) >= 0.29, done.out
    top = done.out.splitlines()[1:]
    assert len(top) == 2 and top[0].endswith("test_holder.py::test_holds_300_mib") and float(top[0].split()[0]) >= 0.29


def test_suite_memory_measures_any_command_and_gives_back_its_exit_status(tmp_path):
    done = run_script(MEASUREMENTS / "suite_memory.py", "--every", "0.05", "--", sys.executable, "-c",
                      "import time; block = bytearray(b'x') * (100 << 20); time.sleep(0.5); raise SystemExit(3)",
                      cwd=tmp_path)
    assert done.code == 3
    peak = re.match(r"peak memory of the process tree: ([\d.]+) GiB .* exit 3 after", done.out)
    assert peak and float(peak[1]) >= 0.09
    assert done.out.splitlines()[1].endswith("(collecting)")  # no test runs in a command that is not pytest
