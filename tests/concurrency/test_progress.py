"""Progress where a person waits (emmi_gym.concurrency.progress): tqdm's bar on a terminal, whole lines at
least every interval in a log, even while one item takes longer than that."""

import io
import time

from tqdm import std

from emmi_gym.concurrency.progress import Heartbeat, LineTqdm, progress_bar


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_bar_written_to_a_file_is_lines_even_while_nothing_advances():
    log = io.StringIO()
    with progress_bar(total=2, desc="runs", unit="run", file=log, interval=0.2) as bar:
        time.sleep(1.0)  # one item that takes five intervals: the heartbeat still writes
        bar.update(2)
    text = log.getvalue()
    lines = text.splitlines()
    assert "\r" not in text and text.endswith("\n")
    assert sum(line.startswith("runs:   0%") for line in lines) >= 3
    assert lines[-1].startswith("runs: 100%") and "2/2" in lines[-1]


def test_a_log_gets_no_more_than_a_line_per_interval_from_a_fast_loop():
    log = io.StringIO()
    for _ in progress_bar(range(10_000), desc="scans", file=log, interval=60.0):
        pass
    assert len(log.getvalue().splitlines()) <= 3  # the start, the end (and tqdm's final redraw)


def test_a_terminal_gets_tqdm_s_own_bar_and_a_disabled_bar_writes_nothing():
    bar = progress_bar(total=3, file=Terminal())
    assert isinstance(bar, std.tqdm) and not isinstance(bar, LineTqdm)
    bar.close()
    log = io.StringIO()
    with progress_bar(total=3, file=log, disable=True, interval=0.05) as quiet:
        time.sleep(0.2)
        quiet.update(3)
    assert log.getvalue() == ""


def test_a_stopped_heartbeat_has_finished_the_beat_under_way():
    # a slow beat (a file count on a busy machine) must not write after stop() returned
    started, finished = [], []

    def beat():
        started.append(time.monotonic())
        time.sleep(0.3)
        finished.append(time.monotonic())

    heartbeat = Heartbeat(beat, 0.01)
    heartbeat.start()
    deadline = time.monotonic() + 60
    while not started and time.monotonic() < deadline:
        time.sleep(0.001)
    assert started
    heartbeat.stop()
    assert len(finished) == len(started) and not heartbeat.is_alive()

    def stops_itself():
        heartbeat.stop()

    heartbeat = Heartbeat(stops_itself, 0.01)
    heartbeat.start()
    heartbeat.join(60.0)  # returns as soon as the thread ends; long only for a busy machine
    assert not heartbeat.is_alive()  # stop() from its own beat ends the loop instead of waiting on itself
