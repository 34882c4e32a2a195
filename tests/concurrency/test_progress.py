"""Progress where a person waits (emmi_gym.concurrency.progress): tqdm's bar on a terminal, whole lines at
least every interval in a log, even while one item takes longer than that."""

import io
import time

from tqdm import std

from emmi_gym.concurrency.progress import LineTqdm, progress_bar


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
