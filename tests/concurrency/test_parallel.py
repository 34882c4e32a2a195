"""Jobs run by :func:`emmi_gym.concurrency.parallel.run_in_processes` in this process (one worker): the quick
lane's check of its contract; its pools of worker processes are tested in tests/tools/training (slow)."""

import os

from emmi_gym.concurrency.parallel import run_in_processes


def test_one_worker_runs_every_job_of_a_generator_in_this_process_in_order():
    jobs = (-k for k in range(40))  # a generator, its length given as total
    assert run_in_processes(abs, jobs, total=40, workers=1, progress=False) == list(range(40))
    assert run_in_processes(lambda _: os.getpid(), range(3), workers=1, progress=False) == [os.getpid()] * 3


def test_a_single_job_runs_in_this_process_whatever_the_workers_asked():
    assert run_in_processes(lambda _: os.getpid(), [7], workers=8, progress=False) == [os.getpid()]
