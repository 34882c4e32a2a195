"""A run folder's record of how its model was trained, ``training.yaml``.

It holds the decisions the model holds (``timesteps``), the model the run started from and its
decisions (``init_from``, ``init_decisions``), each part of the run (``parts``: a run stopped by
Ctrl-C or a kill and resumed has several; ``start`` and ``end`` in decisions, ``wall_seconds``)
and their total wall time, the date, the machine and the versions. The totals add up:
``timesteps = init_decisions + sum(end - start)``, each part starting where the one before ended,
and ``wall_seconds`` is the parts' sum.

Training writes it at every checkpoint, just before the checkpoint is renamed into place, and
at the end; a run resumed from a checkpoint keeps the parts up to that checkpoint's decisions
(a part cut there keeps the wall time it had recorded, at most one checkpoint interval more).
"""

from __future__ import annotations

import os
import platform
import time
from pathlib import Path

#: The run folder's record (see the module docstring).
TRAINING_RECORD = "training.yaml"


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


def record_training(
    run_dir,
    earlier: list[dict],
    start: int,
    decisions: int,
    wall_seconds: float | None,
    init_from=None,
    init_decisions: int = 0,
) -> None:
    """Write :data:`TRAINING_RECORD` into ``run_dir``: the ``earlier`` parts and this one, from ``start`` to
    ``decisions`` in ``wall_seconds`` (None: no part yet, a run that starts from ``init_from``)."""
    import torch
    import yaml

    from .. import __version__
    from ..inputs.paths import write_text_atomically

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
    write_text_atomically(Path(run_dir) / TRAINING_RECORD, yaml.safe_dump(record, sort_keys=False))
