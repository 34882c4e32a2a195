"""Files written whole or not at all: under a temporary name beside the target, then renamed into
place, so a run killed mid-write leaves the previous file (or none), never half of one."""

from __future__ import annotations

import csv
import io
import os
from pathlib import Path


def write_atomically(path, write) -> Path:
    """Call ``write(tmp)`` to write the file ``path`` under a temporary name in the same folder, then rename
    it into place (``os.replace``, atomic on POSIX and Windows): a process killed mid-write leaves the old
    file whole (or none) and at most a ``<stem>.tmp<suffix>`` beside it; an exception removes the temporary
    file. The temporary name keeps the suffix, which writers such as SB3's ``save``, ``np.savez`` and
    matplotlib's ``savefig`` read (or append when it is missing)."""
    path = Path(path)
    tmp = path.with_name(f"{path.stem}.tmp{path.suffix}")
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def write_text_atomically(path, text: str) -> Path:
    """:func:`write_atomically` of ``text`` (UTF-8)."""
    return write_atomically(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


def write_csv(path: Path, rows: list[dict]) -> None:
    """``rows`` as a CSV file with a header of every key any row has (an empty cell where a row lacks one),
    written whole (:func:`write_text_atomically`)."""
    columns = list(dict.fromkeys(k for row in rows for k in row))
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=columns)
    writer.writeheader()
    writer.writerows(rows)
    write_text_atomically(path, text.getvalue())
