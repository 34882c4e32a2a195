"""Assertions and paths shared by the test modules (``pythonpath = ["tests"]`` in pyproject.toml makes this
module importable from every folder of tests/)."""

import importlib
import io
import runpy
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager, redirect_stderr, redirect_stdout
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from emmi_gym.world import rasterise

#: The repository's root, and the data files of the tests, wherever a test file sits under tests/.
ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "data"
#: The folders of the measurement scripts and of the maintainers' scripts.
MEASUREMENTS, SCRIPTS = ROOT / "measurements", ROOT / "scripts"


def assert_same(a, b) -> None:
    """``a`` and ``b`` are the same, bit for bit, through nested dicts, lists and arrays (NaN equals NaN)."""
    if isinstance(a, dict):
        assert a.keys() == b.keys()
        for key in a:
            assert_same(a[key], b[key])
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b)
        for x, y in zip(a, b, strict=False):
            assert_same(x, y)
    elif isinstance(a, np.ndarray):
        np.testing.assert_array_equal(a, b)
    else:
        assert a == b or (a != a and b != b)


def independent_loops(world, resolution=0.1, min_span=3.0):
    """Loops worth closing: holes of the reachable free space at least ``min_span`` m across in x and y.

    (A pillar is a hole too, but going round it closes no loop of interest.)
    """
    truth = rasterise(world, resolution)
    labels, _ = ndimage.label(~truth.reachable, structure=np.ones((3, 3)))
    outside = labels[0, 0]
    spans = [((s[0].stop - s[0].start) * resolution, (s[1].stop - s[1].start) * resolution)
             for k, s in enumerate(ndimage.find_objects(labels), start=1) if k != outside]
    return sum(1 for h, w in spans if h >= min_span and w >= min_span)


def start_as_a_terminal_would(args, **kwargs) -> subprocess.Popen:
    """``subprocess.Popen(args, **kwargs)`` with Ctrl-C (SIGINT) raising KeyboardInterrupt in the child, as in a
    terminal's foreground job, however the suite was started: a shell runs background jobs with SIGINT ignored,
    and a child inherits an ignored signal, so the child starts while this process handles SIGINT (a handled
    signal is reset to the default at exec). Not with ``preexec_fn``: Python code between fork and exec can
    deadlock in a process with threads (torch's, the kernel pool's)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        return subprocess.Popen(args, **kwargs)
    finally:
        signal.signal(signal.SIGINT, previous)


def start_local_ray(num_cpus: int = 2):
    """Ray, with a new local instance of ``num_cpus`` CPUs (whatever the machine has) started as
    ``emmi_gym.concurrency.ray_cluster.connect_ray("local")`` starts one: never the cluster a leftover address
    file names, its workers at this process's priority."""
    import ray

    from emmi_gym.concurrency.ray_cluster import ray_init_arguments

    ray.init(**ray_init_arguments("local", {}), num_cpus=num_cpus)
    return ray


@contextmanager
def ray_temp_dir():
    """A new folder for Ray's files (as ``RAY_TMPDIR``: its sessions and the address file ``ray.init()`` joins),
    short enough for Ray's socket paths (107 bytes at most), removed after the block, with what Ray's processes
    still write into it as they end (a single ``rmtree`` can leave their folders)."""
    temp = Path(tempfile.mkdtemp(prefix="ray"))
    try:
        yield temp
    finally:
        for _ in range(50):
            shutil.rmtree(temp, ignore_errors=True)
            if not temp.exists():
                break
            time.sleep(0.2)


def markdown_rows(out: str) -> list[list[str]]:
    """The cells of every row of the Markdown tables in ``out``, their headers and rules left out."""
    lines = out.splitlines()
    rows = []
    for k, line in enumerate(lines):
        ruled = k + 1 < len(lines) and lines[k + 1].startswith("| ---")
        if line.startswith("|") and not line.startswith("| ---") and not ruled:
            rows.append([cell.strip() for cell in line.strip().strip("|").split("|")])
    return rows


@dataclass
class ScriptRun:
    """What a script run by :func:`run_script` did: its exit status and what it wrote to stdout and stderr."""

    code: int
    out: str
    err: str


def run_script(path: Path, *args, cwd: Path | None = None) -> ScriptRun:
    """Run the script ``path`` with ``args`` as ``python path args`` runs it, but in this process (no interpreter
    start and no imports again, which the quick lane could not afford): its exit status, stdout and stderr.
    Its folder is on ``sys.path`` while it runs (a script imports its neighbours, ``_timing``, ``_options``),
    ``sys.argv`` is its own, and the methods a benchmark wraps to time them (``_timing.timed``) are put back
    after it, so that no later test runs through its wrappers."""
    path = Path(path)
    out, err = io.StringIO(), io.StringIO()
    with pytest.MonkeyPatch.context() as patch, redirect_stdout(out), redirect_stderr(err):
        patch.setattr(sys, "argv", [str(path), *map(str, args)])
        patch.syspath_prepend(str(path.parent))
        if cwd is not None:
            patch.chdir(cwd)
        if (path.parent / "_timing.py").is_file():
            _put_back_what_timed_wraps(patch, importlib.import_module("_timing"))
        try:
            runpy.run_path(str(path), run_name="__main__")
            code = 0
        except SystemExit as done:
            code = done.code if isinstance(done.code, int) else 0 if done.code is None else 1
            if isinstance(done.code, str):
                err.write(done.code + "\n")
    return ScriptRun(code, out.getvalue(), err.getvalue())


def _put_back_what_timed_wraps(patch: pytest.MonkeyPatch, timing) -> None:
    """Make ``timing.timed`` record each attribute it is about to wrap with ``patch``, which puts it back."""
    wrap = timing.timed

    def timed(owner, name, *args, **kwargs):
        patch.setattr(owner, name, getattr(owner, name))  # recorded as it is now; undone when the patch ends
        return wrap(owner, name, *args, **kwargs)

    patch.setattr(timing, "timed", timed)
