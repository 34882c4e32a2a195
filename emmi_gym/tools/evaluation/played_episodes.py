"""Evaluation episodes kept as they are played, :class:`PlayedEpisodes`: an evaluation interrupted, or run again
with one more policy beside the same others, plays only the episodes it does not hold yet.

An evaluation's episodes are kept in one file of a folder (a benchmark's ``played/``), ``<name>-<key>.jsonl``:
JSON Lines whose first line is the evaluation's identity and every further line one episode's row
(:func:`~emmi_gym.tools.evaluation.comparison.play_on_world`, with its trace; NaN as Python's ``json`` writes it),
appended and flushed to disk as the episode ends. The identity is what an episode's row depends on besides its
world and seed: the comparison settings (env id and options), the policy (a scripted policy's name, or a trained
model's SHA-256: :meth:`~emmi_gym.tools.training.evaluate.TrainedAgent.identity`) and the emmi-gym version; the
same seed gives the same episode bit for bit, so a kept row stands for the episode played again. ``key`` is a
digest of the identity: another identity (other settings, a model trained on, another version) writes another
file, and nothing kept is overwritten. A last line cut short by a process killed mid-write is dropped (its
episode is played again); any other line that is not an episode of the file's evaluation is an error that names
the file and the line.
"""

from __future__ import annotations

import copy
import hashlib
import json
import os
from pathlib import Path

from ... import __version__
from ...formats.atomic_files import write_text_atomically
from ...world.map_sets import world_name


class PlayedEpisodesError(ValueError):
    """A file of kept episodes that cannot be read as one: names the file, the line and what is wrong."""


def evaluation_identity(settings, policy) -> dict:
    """What an episode's row depends on besides its world and seed: ``settings`` (a
    :class:`~emmi_gym.tools.evaluation.comparison.ComparisonSettings`), ``policy`` (a scripted policy's name, or an
    object whose ``identity()`` says what it plays: a trained model's digest) and the emmi-gym version."""
    return {"settings": json.loads(_canonical({"env_id": settings.env_id, "env_options": settings.env_options})),
            "policy": {"scripted": policy} if isinstance(policy, str) else policy.identity(),
            "emmi_gym": __version__}


def _canonical(value) -> str:
    """``value`` as JSON with sorted keys; what JSON cannot hold (an object among the env options) by its ``repr``."""
    return json.dumps(value, sort_keys=True, default=repr)


class PlayedEpisodes:
    """The kept episodes of one evaluation (its ``identity``, :func:`evaluation_identity`) in the file ``path``:
    :meth:`get` a kept episode's row, :meth:`add` one just played."""

    def __init__(self, path, identity: dict):
        self.path = Path(path)
        self.identity = identity
        self._rows = self._read() if self.path.exists() else {}

    @classmethod
    def in_folder(cls, folder, name: str, settings, policy) -> PlayedEpisodes:
        """The kept episodes of ``policy`` under ``settings`` in ``folder``, in the file of ``name`` and the
        evaluation's identity."""
        identity = evaluation_identity(settings, policy)
        key = hashlib.sha256(_canonical(identity).encode()).hexdigest()[:16]
        return cls(Path(folder) / f"{name}-{key}.jsonl", identity)

    def __len__(self) -> int:
        return len(self._rows)

    def get(self, world, seed: int) -> dict | None:
        """A copy of the kept row of the episode on ``world`` (a name, a path) with ``seed``; None if not kept."""
        row = self._rows.get((world_name(world), int(seed)))
        return None if row is None else copy.deepcopy(row)

    def add(self, row: dict) -> None:
        """Keep ``row``, an episode just played (its ``world`` and ``seed`` say which), on disk before returning."""
        line = json.dumps(row)
        if not self.path.exists():
            self.path.parent.mkdir(parents=True, exist_ok=True)
            write_text_atomically(self.path, json.dumps({"identity": self.identity}) + "\n")
        with open(self.path, "a", encoding="utf-8") as f:
            f.write(line + "\n")
            f.flush()
            os.fsync(f.fileno())
        self._rows[(world_name(row["world"]), int(row["seed"]))] = json.loads(line)

    def _read(self) -> dict[tuple[str, int], dict]:
        try:
            text = self.path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as error:
            raise PlayedEpisodesError(f"{self.path}: cannot be read as kept episodes ({error}); remove it to play "
                                      "its episodes again") from None
        lines = text.split("\n")
        cut_short = lines.pop()  # "" when the file ends with a whole line
        rows = {}
        for number, line in enumerate(lines, start=1):
            entry = self._parsed(line, number)
            if number == 1:
                if entry.get("identity") != self.identity:
                    raise PlayedEpisodesError(f"{self.path}, line 1: the identity of another evaluation than this "
                                              "one (its name and key are this one's): remove the file to play its "
                                              "episodes again")
                continue
            if not isinstance(entry.get("world"), str) or not isinstance(entry.get("seed"), int):
                raise PlayedEpisodesError(f"{self.path}, line {number}: an episode with its world (a string) and "
                                          f"seed (an integer) expected, found keys {sorted(entry)[:8]}")
            rows[(world_name(entry["world"]), entry["seed"])] = entry
        if not lines:  # killed before its first line was whole: a file to start again
            self.path.unlink()
        elif cut_short:  # killed mid-write: keep the whole lines, play that episode again
            write_text_atomically(self.path, "".join(line + "\n" for line in lines))
        return rows

    def _parsed(self, line: str, number: int) -> dict:
        try:
            entry = json.loads(line)
        except json.JSONDecodeError as error:
            raise PlayedEpisodesError(f"{self.path}, line {number}: not JSON ({error.msg} at column {error.colno}); "
                                      "remove the file to play its episodes again") from None
        if not isinstance(entry, dict):
            raise PlayedEpisodesError(f"{self.path}, line {number}: a JSON object expected, found "
                                      f"{type(entry).__name__}")
        return entry
