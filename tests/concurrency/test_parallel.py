"""Jobs run by :func:`emmi_gym.concurrency.parallel.run_in_processes` in this process (one worker): the quick
lane's check of its contract; its pools of worker processes are tested in tests/tools/training (slow)."""

import os

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
