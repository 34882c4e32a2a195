"""Paths users hand in: files to read and folders to write.

A file to read must exist and be a regular file (a folder, a device such as ``/dev/zero`` or a
socket is named as what it is, not reported missing); a log may also be a pipe. A folder to
write is created and written to before any work starts, so that a run is not lost at its end
for want of a place to put what it made. Every file a run writes goes through
:func:`write_atomically`: written whole under a temporary name beside it, then renamed into
place, so a run killed mid-write leaves the previous file (or none), never half of one.
"""

from __future__ import annotations

import os
import re
import stat
import tempfile
from pathlib import Path

from .errors import FieldError

_KINDS = ((stat.S_ISDIR, "a folder"), (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISFIFO, "a pipe"), (stat.S_ISSOCK, "a socket"))


def file_kind(mode: int) -> str:
    """What a file of ``st_mode`` ``mode`` is, in words ("a regular file", "a folder", ...)."""
    return next((kind for test, kind in _KINDS if test(mode)), "a regular file")


def input_file(path, what: str, error=FieldError, *, pipes: bool = False) -> Path:
    """``path`` as a :class:`Path`, checked to be a regular file (or, with ``pipes``, a pipe) that can be
    opened: FileNotFoundError if there is nothing there, else ``error`` (a :class:`FieldError`) naming
    the path, ``what`` was expected ("a world file") and what is there instead."""
    path = Path(path)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise FileNotFoundError(f"{what} {path} does not exist") from None
    except OSError as exc:  # a name too long, a loop of links, a folder on the way that cannot be searched
        raise error(str(path), "", f"{with_article(what)} that can be read ({exc.strerror})") from None
    if not (stat.S_ISREG(mode) or (pipes and stat.S_ISFIFO(mode))):
        raise error(str(path), "", f"{with_article(what)}, not {file_kind(mode)}")
    if not os.access(path, os.R_OK):
        raise error(str(path), "", f"{with_article(what)} that can be read (permission denied)")
    return path


def with_article(what: str) -> str:
    """``what`` with "a" or "an" before it, unless it has an article already."""
    return what if what.split(" ", 1)[0] in ("a", "an", "the") else f"{'an' if what[:1] in 'aeiou' else 'a'} {what}"


class OutputFolderError(ValueError):
    """An output folder cannot be made or written to; names the option and the folder."""


def output_folder(path, option: str = "--out") -> Path:
    """Create the folder ``path`` (and its parents) and check that a file can be written in it, before any
    work: :class:`OutputFolderError` naming ``option`` and the folder, and why not, otherwise."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path, prefix=".emmi-gym-write-check-"):
            pass
    except OSError as exc:
        raise OutputFolderError(f"{option} {path}: expected a folder that can be made and written to; "
                                f"{_why_not(path, exc)}") from None
    return path


def output_file(path, option: str = "--out") -> Path:
    """Check that the file ``path`` can be written (its folder made and written to, the path not a folder)."""
    path = Path(path)
    if path.is_dir():
        raise OutputFolderError(f"{option} {path}: expected the name of a file to write, not a folder")
    output_folder(path.parent if str(path.parent) else Path("."), option)
    return path


def check_outputs_apart(outputs: dict, inputs: dict) -> None:
    """Refuse outputs (``{what: path}``: ``{"--out": "run.log", ...}``) of which one is one of the ``inputs`` (``{what:
    path}``) or two are the same file, links and ``..`` resolved, before any work: :class:`OutputFolderError` naming
    both (the input would be overwritten, or one output by the other)."""
    taken = {Path(path).resolve(): (f"{what} {path}", "overwritten") for what, path in inputs.items()}
    for what, path in outputs.items():
        resolved = Path(path).resolve()
        if resolved in taken:
            other, fate = taken[resolved]
            option = re.search(r"--[\w-]+", what)
            raise OutputFolderError(f"{what} {path}: expected a file apart from {other}, which it is (links "
                                    f"resolved) and would be {fate}; give another "
                                    f"{option.group() if option else 'path'}")
        taken[resolved] = (f"{what} {path}", "written over")


def _why_not(path: Path, exc: OSError) -> str:
    for parent in (path, *path.parents):
        if parent.exists():
            if not parent.is_dir():
                return f"{parent} is {file_kind(parent.stat().st_mode)}, not a folder"
            break
    return exc.strerror or type(exc).__name__
