"""A run folder's record of how its model was trained, ``training.yaml``: written as training goes
(:func:`write_training_record`) and read back with its fields checked (:func:`read_training_record`).

It holds the decisions the model holds (``timesteps``), the model the run started from and its
decisions (``init_from``, ``init_decisions``), each part of the run (``parts``: a run stopped by
Ctrl-C or a kill and resumed has several; ``start`` and ``end`` in decisions, ``wall_seconds``)
and their total wall time, the date, the machine and the versions. The totals add up:
``timesteps = init_decisions + sum(end - start)``, each part starting where the one before ended,
and ``wall_seconds`` is the parts' sum.

Training writes it at every checkpoint, just before the checkpoint is renamed into place, and
at the end; a run resumed from a checkpoint keeps the parts up to that checkpoint's decisions
(a part cut there keeps the wall time it had recorded, at most one checkpoint interval more).
It is read through the bounded YAML reader (:mod:`emmi_gym.inputs.yaml_files`) with its fields
checked, so that a damaged or hand-edited record is a clear error naming the file and field, not a
wrong total carried into the next part of a run.
"""

from __future__ import annotations

import math
import os
import platform
import time
from dataclasses import asdict, dataclass

from ....inputs.errors import FieldError
from ....inputs.validation import Check, Integer, Invalid, Maybe, Real, Text, build, check_fields, option
from ....inputs.yaml_files import read_yaml_file

#: The run folder's record (see the module docstring).
TRAINING_RECORD = "training.yaml"


class TrainingRecordError(FieldError):
    """A run folder's ``training.yaml`` is not what ``emmi-gym train`` writes; names the file and field."""


#: The most parts a record may list (a run resumed that many times).
MAX_PARTS = 10_000
_DECISIONS = Integer(0, 2**62)
_SECONDS = Real(0.0, math.inf)


@dataclass(frozen=True)
class Parts(Check):
    """The ``parts`` of a record (see the module docstring): a list of at most :data:`MAX_PARTS`
    mappings of ``start`` and ``end`` (decisions, ``start <= end``) and ``wall_seconds``."""

    def describe(self) -> str:
        return f"a list of at most {MAX_PARTS} parts, each {{start, end, wall_seconds}} with 0 <= start <= end"

    def __call__(self, value):
        if not isinstance(value, list) or len(value) > MAX_PARTS:
            raise Invalid(self.describe())
        parts = []
        for part in value:
            if not isinstance(part, dict) or set(part) != {"start", "end", "wall_seconds"}:
                raise Invalid(self.describe())
            try:
                start, end = _DECISIONS(part["start"]), _DECISIONS(part["end"])
                wall_seconds = _SECONDS(part["wall_seconds"])
            except Invalid:
                raise Invalid(self.describe()) from None
            if end < start:
                raise Invalid(self.describe())
            parts.append({"start": start, "end": end, "wall_seconds": wall_seconds})
        return parts


@dataclass(frozen=True)
class TrainingRecord:
    """The fields of ``training.yaml`` (each optional: a record lacking one reads as its default)."""

    timesteps: int = option(0, _DECISIONS, "decisions the model has trained, its start's included")
    wall_seconds: float = option(0.0, _SECONDS, "wall time of training, summed over the run's parts")
    finished: str | None = option(None, Maybe(Text()), "when the last part ended")
    machine: str | None = option(None, Maybe(Text()), "the machine it trained on")
    emmi_gym: str | None = option(None, Maybe(Text()), "the package's version")
    torch: str | None = option(None, Maybe(Text()), "torch's version")
    init_from: str | None = option(None, Maybe(Text()), "the model whose weights the run started from")
    init_decisions: int = option(0, _DECISIONS, "the decisions of the model the run started from")
    parts: list = option([], Parts(), "each stretch of training: start and end decisions, wall time")

    def __post_init__(self):
        check_fields(self)


def read_training_record(path) -> dict:
    """The fields of the ``training.yaml`` at ``path`` that it sets, checked (:class:`TrainingRecord`):
    :class:`TrainingRecordError` naming the file and field for anything else."""
    data = read_yaml_file(path, "training record", TrainingRecordError)
    record = build(TrainingRecord, data, "", str(path), error=TrainingRecordError)
    if "parts" in data:
        _check_totals(str(path), record)
    return {name: value for name, value in asdict(record).items() if name in data}


def _check_totals(where: str, record: TrainingRecord) -> None:
    """:class:`TrainingRecordError` unless the parts of ``record`` add up, as training writes them: each starts
    where the one before ended (the first at ``init_decisions``), the last ends at ``timesteps``, and
    ``wall_seconds`` is their sum (each rounded to a tenth)."""
    starts = [record.init_decisions, *(part["end"] for part in record.parts)]
    chained = all(part["start"] == start for part, start in zip(record.parts, starts, strict=False))
    wall_seconds = sum(part["wall_seconds"] for part in record.parts)
    if not chained or starts[-1] != record.timesteps or \
            abs(wall_seconds - record.wall_seconds) > 0.05 * (len(record.parts) + 1):
        shown = ", ".join(f"{p['start']}-{p['end']}" for p in record.parts[:6])
        raise TrainingRecordError(where, "parts", f"parts that add up: each starting where the one before ended, "
                                  f"the first at init_decisions ({record.init_decisions}), the last ending at "
                                  f"timesteps ({record.timesteps}), their wall_seconds summing to wall_seconds "
                                  f"({record.wall_seconds:g})", f"parts {shown or 'none'} of {wall_seconds:g} s")


def machine_description() -> str:
    """This machine in a few words: its processor's name and core count."""
    name = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            name = next((line.split(":", 1)[1].strip() for line in f if line.startswith("model name")), name)
    except OSError:
        pass
    return f"{name}, {os.cpu_count()} cores"


def earlier_parts(record: dict | None, decisions: int) -> list[dict]:
    """The parts of ``record`` (a run's ``training.yaml`` as read) that the model it continues from, holding
    ``decisions``, was trained in: those before it, the last cut at ``decisions``. A record written
    before parts were recorded counts as one part."""
    if not record or "timesteps" not in record:
        return []
    parts = record.get("parts")
    if parts is None:
        parts = [
            {
                "start": int(record.get("init_decisions", 0)),
                "end": int(record["timesteps"]),
                "wall_seconds": float(record.get("wall_seconds", 0.0)),
            }
        ]
    return [dict(part, end=min(int(part["end"]), decisions)) for part in parts if int(part["start"]) < decisions]


def write_training_record(
    path,
    earlier: list[dict],
    start: int,
    decisions: int,
    wall_seconds: float | None,
    init_from=None,
    init_decisions: int = 0,
) -> None:
    """Write the record to ``path`` (a run folder's :data:`TRAINING_RECORD`): the ``earlier`` parts and this one,
    from ``start`` to ``decisions`` in ``wall_seconds`` (None: no part yet, a run that starts from ``init_from``)."""
    import torch
    import yaml

    from .... import __version__
    from ....formats.atomic_files import write_text_atomically

    parts = [
        *earlier,
        *(
            []
            if wall_seconds is None
            else [{"start": int(start), "end": int(decisions), "wall_seconds": round(wall_seconds, 1)}]
        ),
    ]
    record = {
        "timesteps": int(decisions),
        "wall_seconds": round(sum(p["wall_seconds"] for p in parts), 1),
        "parts": parts,
        "finished": time.strftime("%Y-%m-%d %H:%M %Z"),
        "machine": machine_description(),
        "emmi_gym": __version__,
        "torch": str(torch.__version__),
    }
    if init_from is not None:
        record.update(init_from=str(init_from), init_decisions=int(init_decisions))
    write_text_atomically(path, yaml.safe_dump(record, sort_keys=False))
