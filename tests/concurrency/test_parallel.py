"""Jobs run by :func:`emmi_gym.concurrency.parallel.run_in_processes` in this process (one worker): the quick
lane's check of its contract; its pools of worker processes are tested in tests/tools/training (slow)."""

import os
import signal

import pytest

from emmi_gym.concurrency.parallel import run_in_processes


def test_one_worker_runs_every_job_of_a_generator_in_this_process_in_order():
    jobs = (-k for k in range(40))  # a generator, its length given as total
    assert run_in_processes(abs, jobs, total=40, workers=1, progress=False) == list(range(40))
    assert run_in_processes(lambda _: os.getpid(), range(3), workers=1, progress=False) == [os.getpid()] * 3


def test_a_single_job_runs_in_this_process_whatever_the_workers_asked():
    assert run_in_processes(lambda _: os.getpid(), [7], workers=8, progress=False) == [os.getpid()]


class Sleeper:
    """An actor's object whose call makes no progress (it never beats) while it sleeps."""

    def sleep(self, seconds: float) -> float:
        import time

        time.sleep(seconds)
        return seconds


@pytest.mark.slow
def test_a_call_silent_past_the_notice_says_what_is_waited_for_and_then_ends(monkeypatch):
    from emmi_gym.concurrency import parallel

    monkeypatch.setattr(parallel, "SILENCE_NOTICE", 0.5)  # 60 s by default, below worker_timeout's 600 s
    actor = parallel.ProcessActor("rollout worker 0", Sleeper)
    try:
        actor.submit("sleep", 0.0)
        assert actor.result(heartbeat_timeout=30.0) == 0.0
        actor.submit("sleep", 2.0)
        with pytest.warns(UserWarning, match=r"rollout worker 0 \(process \d+\) has made no progress for 0\.5 s: "
                                             r"waiting for its reply to sleep, up to 30 s without progress "
                                             r"\(worker_timeout\) before the run stops"):
            assert actor.result(heartbeat_timeout=30.0) == 2.0
    finally:
        actor.close(1.0)


def _check_particles(particles: int) -> int:
    from emmi_gym.env.config import make_config

    return make_config(particles=particles).particles


@pytest.mark.slow
def test_an_input_error_in_a_worker_process_reaches_the_caller_whole():
    """A bad option found in a worker process is raised here as itself, with its message (the pool is not
    broken by an error it cannot unpickle)."""
    from emmi_gym.inputs.validation import OptionError

    with pytest.raises(OptionError, match="field 'particles': expected"):
        run_in_processes(_check_particles, [3, -1], workers=2, progress=False)


#: Actors started while Ctrl-C is sent to this process's group every few milliseconds (a person pressing it as
#: the workers start), run in a process group of their own; this process only counts the Ctrl-Cs it takes.
CTRL_C_WHILE_ACTORS_START = """
import os, signal, threading, time
from emmi_gym.concurrency.parallel import ProcessActor

taken = []
signal.signal(signal.SIGINT, lambda signum, frame: taken.append(signum))
pressing = threading.Event()

def press():
    while not pressing.is_set():
        os.killpg(0, signal.SIGINT)
        time.sleep(0.002)

threading.Thread(target=press, daemon=True).start()
actors = [ProcessActor(f"rollout worker {rank}", dict) for rank in range(3)]
results = [actor.result(heartbeat_timeout=60.0) for actor in actors]
pressing.set()
for actor in actors:
    actor.close(5.0)
print(results, bool(taken))
"""


@pytest.mark.slow
def test_ctrl_c_while_actors_start_reaches_only_the_process_that_started_them():
    import subprocess
    import sys

    from helpers import start_as_a_terminal_would

    process = start_as_a_terminal_would([sys.executable, "-c", CTRL_C_WHILE_ACTORS_START], stdout=subprocess.PIPE,
                                        stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        out, err = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
    assert "Fatal Python error" not in err and "Traceback" not in err, err[-3000:]
    assert (process.returncode, out.strip()) == (0, "[None, None, None] True")
