"""The peak memory of a command and every process it starts (the test suite by default): the summed
proportional set size (PSS) of the process tree, sampled every ``--every`` seconds from /proc (Linux):
each process's resident pages, a page shared by n processes (a library's code, a forked parent's
memory) counted 1/n in each, so the sum is what the tree took of the machine's memory. For pytest it
also names the tests that held the most (a plugin, ``_current_test.py``, says which test is running).

    python measurements/suite_memory.py                       # python -m pytest -q
    python measurements/suite_memory.py -- python -m pytest tests/env/test_env.py -q
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

PAGE = os.sysconf("SC_PAGE_SIZE")


def _children() -> dict[int, list[int]]:
    """Each process's children, read from /proc."""
    tree: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:  # the process ended while being read
            continue
        tree.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    return tree


def proportional_size(pid: int) -> int:
    """The PSS of process ``pid`` in bytes (its RSS where the kernel gives no ``smaps_rollup``)."""
    try:
        for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
            if line.startswith("Pss:"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    return int(Path(f"/proc/{pid}/statm").read_text().split()[1]) * PAGE


def tree_memory(root: int) -> dict[int, int]:
    """The PSS in bytes of ``root`` and of every process below it."""
    tree, found, stack = _children(), {}, [root]
    while stack:
        pid = stack.pop()
        try:
            found[pid] = proportional_size(pid)
        except OSError:  # the process ended while being read
            continue
        stack += tree.get(pid, [])
    return found


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--every", type=float, default=0.2, help="seconds between samples (default 0.2)")
    parser.add_argument("--top", type=int, default=10, help="tests listed with their peak (default 10)")
    parser.add_argument("command", nargs="*", default=[sys.executable, "-m", "pytest", "-q"],
                        help="the command to run (default: python -m pytest -q)")
    args = parser.parse_args()
    started = time.perf_counter()
    with tempfile.NamedTemporaryFile("w", suffix=".txt") as current:
        environment = dict(os.environ, SUITE_MEMORY_CURRENT=current.name,
                           PYTHONPATH=os.pathsep.join(filter(None, [str(HERE), os.environ.get("PYTHONPATH")])))
        command = args.command + (["-p", "_current_test"] if "pytest" in args.command else [])
        child = subprocess.Popen(command, env=environment)
        peak, peak_processes, peak_at, by_test = 0, 0, 0.0, {}
        while child.poll() is None:
            sizes = tree_memory(child.pid)
            total = sum(sizes.values())
            test = Path(current.name).read_text() or "(collecting)"
            by_test[test] = max(by_test.get(test, 0), total)
            if total > peak:
                peak, peak_processes, peak_at = total, len(sizes), time.perf_counter() - started
            time.sleep(args.every)
    print(f"peak memory of the process tree: {peak / 2**30:.2f} GiB (summed PSS of {peak_processes} processes, "
          f"{peak_at:.0f} s in); exit {child.returncode} after {time.perf_counter() - started:.0f} s", flush=True)
    for test, size in sorted(by_test.items(), key=lambda item: -item[1])[:args.top]:
        print(f"{size / 2**30:6.2f} GiB  {test}")
    return child.returncode


if __name__ == "__main__":
    sys.exit(main())
