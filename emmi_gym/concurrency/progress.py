"""Progress where a person waits: tqdm bars on a terminal, and a plain line at least every
:data:`LINE_INTERVAL` seconds where the output is a file or a pipe (a log, CI, ``nohup``).

On a terminal a tqdm bar redraws itself in place. Written to a file, the same bar would be a run of
carriage returns, and nothing at all while one item takes long (a run of the A/B experiment, a PPO
update, numba compiling the kernels). :func:`progress_bar` therefore gives a tqdm bar that, off a
terminal, writes each refresh as a line of its own, and refreshes by itself (a timer thread) when no
item has finished for :data:`LINE_INTERVAL` seconds, so a log never stays silent for longer.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable

from tqdm import autonotebook, std
from tqdm.auto import tqdm

#: Seconds at most between two lines of a bar written to a file or a pipe.
LINE_INTERVAL = 30.0


def is_terminal(stream) -> bool:
    """Whether ``stream`` is an interactive terminal (a closed or odd stream counts as not one)."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


class _Lines:
    """A text stream for tqdm off a terminal: every redraw (``"\\r" + text``) becomes one line ``text``."""

    def __init__(self, stream):
        self.stream = stream
        self.last_write = time.monotonic()

    def write(self, text: str) -> None:
        for part in text.replace("\r", "\n").split("\n"):
            if part.strip():
                self.stream.write(part.rstrip() + "\n")
                self.last_write = time.monotonic()

    def flush(self) -> None:
        self.stream.flush()


#: Seconds :meth:`Heartbeat.stop` waits for a beat under way (a beat is a line or a count of files: short).
JOIN_TIMEOUT = 10.0


class Heartbeat(threading.Thread):
    """Calls ``beat()`` every ``interval`` seconds until stopped (a daemon: it never holds a process open)."""

    def __init__(self, beat: Callable[[], None], interval: float):
        super().__init__(daemon=True, name="progress-heartbeat")
        self.beat, self.interval = beat, interval
        self.stopped = threading.Event()

    def run(self) -> None:
        while not self.stopped.wait(self.interval):
            self.beat()

    def stop(self) -> None:
        """No beat starts after this; one under way is waited for (up to ``JOIN_TIMEOUT`` s), so that nothing it
        writes lands after the caller's next output. Called from a beat itself, it only ends the loop."""
        self.stopped.set()
        if self.is_alive() and threading.current_thread() is not self:
            self.join(JOIN_TIMEOUT)


class LineTqdm(std.tqdm):
    """A tqdm bar writing whole lines, for output that is not a terminal: one when it starts, one every
    ``interval`` seconds (its heartbeat redraws it, whether or not it advanced) and one when it closes."""

    def __init__(self, *args, file=None, interval: float = LINE_INTERVAL, **kwargs):
        kwargs["mininterval"] = 1e9  # tqdm's own redraws off: the heartbeat writes one line per interval
        kwargs.setdefault("ascii", True)
        kwargs.setdefault("dynamic_ncols", False)
        kwargs.setdefault("ncols", 100)
        self.lines = _Lines(file if file is not None else sys.stderr)
        self.interval = interval
        super().__init__(*args, file=self.lines, **kwargs)
        self._heartbeat = None if self.disable else Heartbeat(self._refresh_if_quiet, interval / 3)
        if self._heartbeat is not None:
            self._heartbeat.start()

    def _refresh_if_quiet(self) -> None:
        """Redraw the bar if it wrote nothing for ``interval`` seconds."""
        if time.monotonic() - self.lines.last_write >= self.interval:
            self.refresh()

    def close(self) -> None:
        if getattr(self, "_heartbeat", None) is not None:
            self._heartbeat.stop()
        super().close()


def progress_bar(iterable=None, *, file=None, interval: float = LINE_INTERVAL, **kwargs) -> tqdm:
    """A tqdm bar over ``iterable`` (or with ``total=``), with tqdm's keywords: tqdm's own on a terminal,
    else a :class:`LineTqdm` (a line at least every ``interval`` seconds). ``file``: default stderr."""
    stream = file if file is not None else sys.stderr
    if is_terminal(stream) or autonotebook.tqdm is not std.tqdm:  # a terminal, or a notebook's widget
        return tqdm(iterable, file=stream, **kwargs)
    return LineTqdm(iterable, file=stream, interval=interval, **kwargs)


def note(text: str) -> None:
    """Print ``text`` on stderr as a line of its own, above any bar on a terminal (``tqdm.write``)."""
    tqdm.write(text, file=sys.stderr)
