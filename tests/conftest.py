"""Shared test settings.

Hypothesis deadlines are off: tests never assert wall-clock time (numba compiles on
first call and CI machines are shared). The number of examples stays modest so that
the suite runs in minutes.
"""

import os

import pytest
from hypothesis import HealthCheck, settings

settings.register_profile("default", deadline=None, max_examples=60,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("thorough", deadline=None, max_examples=1000,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))


@pytest.fixture(autouse=True, scope="session")
def sb3_logs_in_pytest_tmp(tmp_path_factory):
    """Stable-Baselines3 makes a folder for its logger on every ``learn`` not given one ($SB3_LOGDIR, else a
    new ``SB3-<time>`` folder in the system's temporary directory): keep the tests' in pytest's own."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("SB3_LOGDIR", str(tmp_path_factory.mktemp("sb3_logs")))
        yield


@pytest.fixture(autouse=True)
def signal_handlers_left_as_found(request):
    """A test that leaves SIGINT or SIGTERM handled otherwise than it found them (ignored, say, by code meant for
    a worker process run in this one) would change every later test that interrupts training: the handlers are
    put back, with a warning naming the test and what it left."""
    import signal
    import warnings

    found = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    yield
    changed = {signal.Signals(sig).name: signal.getsignal(sig) for sig in found if signal.getsignal(sig) != found[sig]}
    for sig, handler in found.items():
        signal.signal(sig, handler)
    if changed:
        warnings.warn(f"{request.node.nodeid} left signal handlers changed: {changed}", stacklevel=1)


@pytest.fixture(autouse=True, scope="module")
def memory_given_back_after_each_file():
    """What a test file's objects held goes back to the system once the file is done (a garbage collection,
    then glibc's ``malloc_trim``): freed heap pages otherwise stay with the pytest process, whose size then
    adds to every worker process and Ray instance the later files start."""
    import ctypes
    import ctypes.util
    import gc

    yield
    gc.collect()
    name = ctypes.util.find_library("c")
    trim = getattr(ctypes.CDLL(name), "malloc_trim", None) if name else None  # glibc's; other C libraries lack it
    if trim is not None:
        trim(0)


#: The agent of :func:`small_corridor_run`: MaskablePPO on LoopCorridor-v1, 16 decisions in two updates.
SMALL_CORRIDOR_AGENT = {
    "env": {"id": "emmi_gym/LoopCorridor-v1", "kwargs": {"particles": 3, "max_decisions": 3}},
    "algorithm": "MaskablePPO", "policy": "MultiInputPolicy",
    "hyperparameters": {"n_steps": 8, "batch_size": 8, "n_epochs": 1, "policy_kwargs": {"net_arch": [8]}},
    "n_envs": 1, "vec_env": "dummy", "total_timesteps": 16, "seed": 3, "eval": {"freq": 0}, "checkpoint_freq": 8}


@pytest.fixture(scope="session")
def small_corridor_run(tmp_path_factory):
    """The folder of a run of ``emmi-gym train`` small enough for a test (:data:`SMALL_CORRIDOR_AGENT`: a model,
    checkpoints at 8 and 16 decisions, its configuration and record), for the slow tests of the scripts that read
    trained runs; read it, do not change it."""
    from emmi_gym.tools.training.config import parse_agent_config
    from emmi_gym.tools.training.train import train

    run = tmp_path_factory.mktemp("small_corridor_run")
    train(parse_agent_config(SMALL_CORRIDOR_AGENT), run, progress=False)
    return run


@pytest.fixture(scope="session")
def small_corridor_evaluation(small_corridor_run, tmp_path_factory):
    """The ``--out`` folder of ``emmi-gym evaluate`` of :func:`small_corridor_run`'s model beside the frontier
    policy (its rows named ``agent``): two held-out episodes each, from seed 7."""
    from emmi_gym.tools.cli import main

    out = tmp_path_factory.mktemp("small_corridor_evaluation")
    assert main(["evaluate", str(small_corridor_run / "model.zip"), "--episodes", "2", "--seed", "7", "--baselines",
                 "frontier", "--workers", "1", "--quiet", "--out", str(out)]) == 0
    return out
