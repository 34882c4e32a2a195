"""Shared helper of the scripts that read the datasets of ``shared/datasets``: stop with a clear message
when a file is missing, before any work (not a traceback from a worker process half-way through)."""

from __future__ import annotations

import argparse
from pathlib import Path


def require_files(parser: argparse.ArgumentParser, folder: Path, names, dataset: str) -> None:
    """``parser.error`` naming the files of ``names`` that ``folder`` (the ``--data`` option) lacks."""
    missing = sorted({name for name in names if not (Path(folder) / name).is_file()})
    if missing:
        parser.error(f"--data {folder}: no {', '.join(missing)} there (the {dataset} files, "
                     f"shared/datasets/{dataset})")
