"""Demonstrations of a scripted policy (the decisions behaviour cloning fits), and the ``.npz`` files that hold them.

Files are checked before their arrays are allocated (:func:`emmi_gym.inputs.npz_files.npz_arrays`: the
members' headers against their declared sizes): the members, their dtypes and shapes, at least one
decision, the same observations and action count in every file, and the size in all; then the
arrays of every file are streamed into one set of arrays (no copy of a file's arrays is made, nor a
second one to join them), and the actions checked against their masks and the observations for
NaN and infinities. Each problem is a :class:`DemonstrationsError` naming the file and the member.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...formats.atomic_files import write_atomically
from ...inputs.errors import FieldError
from ...inputs.npz_files import NpzArray, npz_arrays, read_array_into

#: The most a demonstrations file (or the files fitted together) may unpack to: 65,000 decisions of the 64 x 64
#: plans observation (a thousand episodes or more), which ``clone`` fits in under 1 GB in all.
MAX_DEMONSTRATION_BYTES = 512 * 2**20
#: Rows of observations checked for NaN and infinities at a time (bounds the check's own memory).
_ROWS_CHECKED = 4096


class DemonstrationsError(FieldError):
    """A demonstrations file is not one ``emmi-gym clone`` wrote, or does not match the others; names the file
    and the member (``masks``, ``actions``, ``episodes``, ``obs_<key>``)."""


@dataclass
class Demonstrations:
    """Decisions of a scripted policy: ``observations`` (a dict of stacked arrays), ``masks`` (bool,
    decisions x actions) and ``actions`` (int64); ``episodes`` played."""

    observations: dict[str, np.ndarray]
    masks: np.ndarray
    actions: np.ndarray
    episodes: int

    def __len__(self) -> int:
        return len(self.actions)

    def save(self, path) -> None:
        """Write to ``path`` (a compressed ``.npz``; under a temporary name, then renamed)."""
        write_atomically(path, lambda tmp: np.savez_compressed(
            tmp, masks=self.masks, actions=self.actions, episodes=self.episodes,
            **{f"obs_{key}": value for key, value in self.observations.items()}))

    @classmethod
    def load(cls, *paths) -> Demonstrations:
        """The decisions of the files :meth:`save` wrote to ``paths``, in order, as one set; a
        :class:`DemonstrationsError` naming the file and member for anything else (see the module)."""
        if not paths:
            raise ValueError("Demonstrations.load: no demonstrations file given")
        files = [(Path(path), _declared(path)) for path in paths]  # a file given twice counts twice
        first, wanted = files[0]
        for path, arrays in files:
            for name in sorted(arrays.keys() | wanted.keys()):
                if name in ("actions", "episodes"):
                    continue
                if name not in arrays or name not in wanted or arrays[name].shape[1:] != wanted[name].shape[1:] \
                        or arrays[name].dtype != wanted[name].dtype:
                    raise DemonstrationsError(str(path), name, f"the members and shapes of {first}: {_rows(wanted)}",
                                              _rows(arrays))
        total = sum(array.nbytes for _, arrays in files for array in arrays.values())
        if total > MAX_DEMONSTRATION_BYTES:
            raise DemonstrationsError(", ".join(str(path) for path, _ in files), "", f"demonstrations of at most "
                                      f"{MAX_DEMONSTRATION_BYTES // 2**20} MiB", f"{total / 2**20:,.0f} MiB in all")
        rows = [arrays["actions"].shape[0] for _, arrays in files]
        joined = {name: np.empty((sum(rows), *array.shape[1:]), array.dtype)
                  for name, array in wanted.items() if name != "episodes"}
        episodes, start = 0, 0
        for (path, arrays), n in zip(files, rows, strict=True):
            part = slice(start, start + n)
            played = int(read_array_into(path, arrays["episodes"], np.empty((), arrays["episodes"].dtype),
                                         DemonstrationsError))
            if played < 1:
                raise DemonstrationsError(str(path), "episodes", "at least one episode played", played)
            episodes += played
            for name in ("actions", "masks"):
                read_array_into(path, arrays[name], joined[name][part], DemonstrationsError)
            _check_actions(path, joined["actions"][part], joined["masks"][part])
            for name, array in arrays.items():
                if name.startswith("obs_"):
                    _check_finite(path, name, read_array_into(path, array, joined[name][part], DemonstrationsError))
            start += n
        return cls({name[4:]: value for name, value in joined.items() if name.startswith("obs_")}, joined["masks"],
                   joined["actions"].astype(np.int64, copy=False), episodes)

    def check_fits(self, observation_space, where: str = "the demonstrations") -> None:
        """A ``ValueError`` unless the observations have the keys and shapes of ``observation_space`` (a Dict)."""
        shapes = {key: value.shape[1:] for key, value in self.observations.items()}
        wanted = {key: space.shape for key, space in observation_space.spaces.items()}
        if shapes != wanted:
            raise ValueError(f"{where}: observations of shapes {shapes}; the configuration's env gives {wanted}")

    @classmethod
    def joined(cls, parts: list[Demonstrations]) -> Demonstrations:
        """The decisions of every part, in order (one part: itself, not a copy)."""
        if len(parts) == 1:
            return parts[0]
        keys = parts[0].observations
        return cls({key: np.concatenate([p.observations[key] for p in parts]) for key in keys},
                   np.concatenate([p.masks for p in parts]), np.concatenate([p.actions for p in parts]),
                   sum(p.episodes for p in parts))


def _declared(path) -> dict[str, NpzArray]:
    """The arrays the demonstrations file ``path`` declares, checked to be the members :meth:`Demonstrations.save`
    writes, of its dtypes and dimensions, with as many rows (at least one) in each as there are actions."""
    arrays = npz_arrays(path, "demonstrations file", MAX_DEMONSTRATION_BYTES, DemonstrationsError)
    source = str(path)
    kinds = {"masks": ("b", 2, "a 2-D array of booleans (decisions x actions)"),
             "actions": ("iu", 1, "a 1-D array of integers (the action of each decision)"),
             "episodes": ("iu", 0, "an integer (0-D array): the episodes played")}
    for name, (kind, ndim, expected) in kinds.items():
        if name not in arrays:
            raise DemonstrationsError(source, name, f"demonstrations written by 'emmi-gym clone' (an .npz with masks, "
                                      f"actions, episodes and obs_* arrays); its arrays are {sorted(arrays)[:8]}")
        if arrays[name].dtype.kind not in kind or len(arrays[name].shape) != ndim:
            raise DemonstrationsError(source, name, expected, f"shape {arrays[name].shape}, {arrays[name].dtype}")
    unknown = sorted(set(arrays) - set(kinds) - {name for name in arrays if name.startswith("obs_")})
    if unknown:
        raise DemonstrationsError(source, unknown[0], "only the arrays masks, actions, episodes and obs_*")
    observations = [name for name in arrays if name.startswith("obs_")]
    if not observations:
        raise DemonstrationsError(source, "obs_*", "at least one array of observations (obs_<key>)")
    n = arrays["actions"].shape[0]
    if n < 1:
        raise DemonstrationsError(source, "actions", "at least one decision", "none")
    if arrays["masks"].shape[1] < 1:
        raise DemonstrationsError(source, "masks", "at least one action slot per decision", "none")
    for name in ("masks", *observations):
        if len(arrays[name].shape) < 1 or arrays[name].shape[0] != n:
            raise DemonstrationsError(source, name, f"a row per decision, {n} as there are actions",
                                      f"shape {arrays[name].shape}")
    return arrays


def _rows(arrays: dict[str, NpzArray]) -> dict:
    """The shape of a decision's row and the dtype of each array but ``actions`` and ``episodes``."""
    return {name: f"{array.shape[1:]} {array.dtype}" for name, array in sorted(arrays.items())
            if name not in ("actions", "episodes")}


def _check_actions(path, actions: np.ndarray, masks: np.ndarray) -> None:
    n, slots = masks.shape
    inside = (actions >= 0) & (actions < slots)
    if not inside.all() or not masks[np.arange(n), np.where(inside, actions, 0)].all():
        raise DemonstrationsError(str(path), "actions", "every action to be a slot its mask allows")


def _check_finite(path, name: str, values: np.ndarray) -> None:
    if values.dtype.kind != "f":
        return
    for start in range(0, len(values), _ROWS_CHECKED):
        finite = np.isfinite(values[start:start + _ROWS_CHECKED])
        if not finite.all():
            row = start + int(np.argmin(finite.reshape(len(finite), -1).all(axis=1)))
            raise DemonstrationsError(str(path), name, "finite observations", f"NaN or infinity in decision {row}")
