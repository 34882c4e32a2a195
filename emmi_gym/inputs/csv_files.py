"""Reading the CSV files the tools hand each other (a run's ``eval_ground_truth.csv``, ``checkpoint_scores.csv``,
``episodes.csv`` of ``emmi-gym evaluate``), bounded and checked.

One reader for all of them: the file is capped in size and must be UTF-8 text (:mod:`.text_files`); a field
is at most the ``csv`` module's limit (:func:`csv.field_size_limit`, 131,072 characters by default); the
header names every column the caller needs, every line has as many fields as the header, there is at
least one row, and the numeric columns hold numbers (an empty cell reads as NaN). Each error names the
file, the line and the column.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable

from .errors import FieldError
from .text_files import read_text_file

#: The largest CSV file read (a run's evaluations and a comparison's episodes take a few MB): its rows, read
#: as dicts of text, take about 25 times its size (16 MiB: 400 MB at the peak of ``learning-curves``).
MAX_CSV_BYTES = 16 * 2**20


class CsvFileError(FieldError):
    """A CSV file is not what the tool reading it needs; names the file, the line or column, and what was expected."""


def read_csv_file(path, what: str, required: Iterable[str] = (), numeric: Iterable[str] = (),
                  optional_numeric: Iterable[str] = ()) -> list[dict]:
    """The rows of the CSV file ``path`` (``what`` names it in messages: "learning curve"), each a dict of
    column -> text, the columns ``numeric`` (and those of ``optional_numeric`` that the header names) as
    floats (NaN for an empty cell): :class:`CsvFileError` naming the file unless it is a bounded UTF-8 CSV
    whose header holds every column of ``required`` and ``numeric``, with at least one row and as many
    fields on every line as the header names."""
    text = read_text_file(path, what, MAX_CSV_BYTES, CsvFileError)
    source = str(path)
    reader = csv.reader(io.StringIO(text, newline=""), strict=True)
    try:
        header = next(reader, None)
        if not header or header == [""]:
            raise CsvFileError(source, "", f"a {what}: a header line naming its columns, then a row per line "
                               "(the file is empty)")
        numeric = tuple(numeric)
        missing = [column for column in dict.fromkeys((*required, *numeric)) if column not in header]
        if missing:
            raise CsvFileError(source, "", f"a {what} with the columns {missing} (its header names "
                               f"{header[:12]}{' ...' if len(header) > 12 else ''})")
        numeric += tuple(column for column in optional_numeric if column in header and column not in numeric)
        rows = []
        for fields in reader:
            if not fields:  # a blank line (csv.DictReader skips them too)
                continue
            if len(fields) != len(header):
                raise CsvFileError(f"{source}:{reader.line_num}", "", f"{len(header)} fields, as the header names",
                                   f"{len(fields)} fields")
            row = dict(zip(header, fields, strict=True))
            for column in numeric:
                row[column] = _number(row[column], f"{source}:{reader.line_num}", column)
            rows.append(row)
    except csv.Error as exc:
        raise CsvFileError(f"{source}:{reader.line_num}", "", f"a {what} in CSV ({exc})") from None
    if not rows:
        raise CsvFileError(source, "", f"a {what} with at least one row below its header (it holds only the header)")
    return rows


def _number(text: str, where: str, column: str) -> float:
    if text.strip() == "":
        return math.nan
    try:
        return float(text)
    except ValueError:
        raise CsvFileError(where, column, "a number (or an empty cell)", text) from None
