"""A run folder's ``training.yaml``: how its model was trained (decisions, wall time over every resumed part,
date, machine, versions, the model it started from), read through the bounded YAML reader
(:mod:`emmi_gym.inputs.yaml_files`) with its fields checked, so that a damaged or hand-edited record is a
clear error naming the file and field, not a wrong total carried into the next part of a run."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from ..inputs.errors import FieldError
from ..inputs.validation import Check, Integer, Invalid, Maybe, Real, Text, build, check_fields, option
from ..inputs.yaml_files import read_yaml_file


class TrainingRecordError(FieldError):
    """A run folder's ``training.yaml`` is not what ``emmi-gym train`` writes; names the file and field."""


#: The most parts a record may list (a run resumed that many times).
MAX_PARTS = 10_000
_DECISIONS = Integer(0, 2**62)
_SECONDS = Real(0.0, math.inf)


@dataclass(frozen=True)
class Parts(Check):
    """The ``parts`` of a record (:mod:`~emmi_gym.training.run_record`): a list of at most :data:`MAX_PARTS`
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
