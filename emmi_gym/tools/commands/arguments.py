"""Command-line arguments, checked when they are parsed: bounded argparse types (argparse names the option
in its error), and the one-line message a command prints for bad input instead of a traceback."""

from __future__ import annotations

import argparse
import math
import re

from ...inputs.validation import MAX_EPISODES


def integer(lo: int = 0, hi: int | None = None):
    """An argparse type: a whole number in [lo, hi]."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < lo or (hi is not None and value > hi):
            bounds = f"in [{lo}, {hi}]" if hi is not None else f">= {lo}"
            raise argparse.ArgumentTypeError(f"expected an integer {bounds}, got {text!r}")
        return value
    return parse


def number(lo: float = 0.0, hi: float | None = None, unit: str = ""):
    """An argparse type: a finite number above ``lo`` and at most ``hi``, in ``unit``."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and value > lo and (hi is None or value <= hi)):
            bounds = f"in ({lo:g}, {hi:g}]" if hi is not None else f"above {lo:g}"
            raise argparse.ArgumentTypeError(f"expected a finite number {bounds}{f' ({unit})' if unit else ''}, "
                                             f"got {text!r}")
        return value
    return parse


#: What a label of rows and table columns may be: it names a policy in CSV files and Markdown tables.
_LABEL = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")


def label(text: str) -> str:
    """An argparse type: a policy's label, 1-64 letters, digits, ``_``, ``-`` or ``.``, starting with a letter or
    digit (it names rows in CSV files and columns in Markdown tables, where a ``|`` or a blank would break them)."""
    if not _LABEL.fullmatch(text):
        raise argparse.ArgumentTypeError(f"expected 1-64 letters, digits, '_', '-' or '.', starting with a letter or "
                                         f"digit, got {text!r}")
    return text


#: Seeds of numpy's generators, as the configurations bound them.
SEED = integer(0, 2**32 - 1)
#: A count of episodes.
EPISODES = integer(1, MAX_EPISODES)


def run_command(parser: argparse.ArgumentParser, command, argv=None) -> int:
    """Parse ``argv`` with ``parser`` and return ``command(args)``; bad input (a ``ValueError``, such as the
    package's :class:`~emmi_gym.inputs.errors.FieldError`, or an ``OSError``: a missing file, a folder that cannot be
    written) ends the program with its one-line message and exit status 2, not a traceback."""
    args = parser.parse_args(argv)
    try:
        return command(args)
    except (ValueError, OSError) as exc:
        parser.exit(2, f"{parser.prog}: error: {exc}\n")


def add_workers(parser: argparse.ArgumentParser) -> None:
    """``--workers N``, in every command the number of local worker processes (default one per core)."""
    parser.add_argument("--workers", type=integer(1), default=None, metavar="N",
                        help="worker processes (default one per core)")


def add_quiet(parser: argparse.ArgumentParser) -> None:
    """``--quiet``, in every command with a progress bar: no progress bar."""
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


#: What the help of a command that loads model files says of them.
MODEL_FILES_RUN_CODE = ("model files are zips of pickles (Stable-Baselines3's format), which can run code: "
                        "one whose pickles name anything but classes of SB3, torch, numpy, gymnasium and "
                        "emmi_gym is refused unless --trust-model")


def add_trust_model(parser: argparse.ArgumentParser, what: str) -> None:
    """``--trust-model``, in every command that loads model files (``what``: which): load them as SB3 does,
    whatever their pickles name (:func:`trust_models`)."""
    parser.add_argument("--trust-model", action="store_true",
                        help=f"trust {what}: load it even if its pickles name code outside SB3, torch, numpy, "
                             "gymnasium and emmi_gym (a model file can run code: give it only files you trust)")


def trust_models(args: argparse.Namespace, paths) -> None:
    """With ``--trust-model``, trust the model files at ``paths`` (folders: those under them; None left out), in this
    process and those it starts."""
    if args.trust_model:
        from ..training.run_folders.model_files import trust_model_files

        trust_model_files([path for path in paths if path is not None])


def add_seed_range(parser: argparse.ArgumentParser, seeds: int, first_seed: int = 0, least: int = 1) -> None:
    """``--seeds N`` and ``--first-seed S``, in every command the seeds S, S + 1, ..., S + N - 1 (``--seeds``
    is a count everywhere; ``least`` the fewest the command takes)."""
    parser.add_argument("--seeds", type=integer(least, MAX_EPISODES), default=seeds, metavar="N",
                        help=f"number of seeds (default {seeds})")
    parser.add_argument("--first-seed", type=SEED, default=first_seed, metavar="S",
                        help=f"the first seed (default {first_seed})")


def seed_range(args: argparse.Namespace) -> range:
    """The seeds of :func:`add_seed_range`'s options."""
    return range(args.first_seed, args.first_seed + args.seeds)


#: What ``--ray`` given without an address means: Ray's own choice, the cluster named by the
#: ``RAY_ADDRESS`` environment variable, else a Ray instance started on this machine.
RAY_DEFAULT_ADDRESS = "env"


def add_ray(parser: argparse.ArgumentParser, what: str) -> None:
    """``--ray [ADDRESS]``, in every command: run on Ray, at ADDRESS (see :func:`ray_address`)."""
    parser.add_argument("--ray", nargs="?", const=RAY_DEFAULT_ADDRESS, default=None, metavar="ADDRESS",
                        help=f"{what}, on the cluster at ADDRESS ('local': a Ray instance on this machine; no "
                             "ADDRESS: the cluster of RAY_ADDRESS, else a local instance)")


def ray_address(args: argparse.Namespace) -> str | None:
    """The cluster address :func:`add_ray`'s option asks for (``emmi_gym.concurrency.connect_ray``'s argument):
    ``None`` without ``--ray`` or without an address, which ``connect_ray`` reads as Ray's default."""
    return None if args.ray in (None, RAY_DEFAULT_ADDRESS) else args.ray


def add_seeds_per_plan(parser: argparse.ArgumentParser) -> None:
    """``--seeds-per-plan K``, in ``evaluate`` and ``benchmark``: each plan of a map set played with K seeds."""
    parser.add_argument("--seeds-per-plan", type=integer(1, MAX_EPISODES), default=1, metavar="K",
                        help="play each plan of the map set with K episode seeds (from the first seed on), paired "
                             "per plan and seed across the policies; the intervals then resample plans, each with "
                             "its K seeds, and the tables state the smallest difference they detect (default 1)")


def add_torch_threads(parser: argparse.ArgumentParser, default: str) -> None:
    """``--torch-threads N``: the learner's torch threads (``default`` says what it is without the option)."""
    parser.add_argument("--torch-threads", type=integer(1), default=None, metavar="N",
                        help=f"torch threads of the learner (default {default})")


def baseline_policies(names, option: str = "--baselines") -> list:
    """The policies ``names`` stand for, to play beside trained agents: a scripted policy's name as it is, a shipped
    agent's name (``emmi_gym.pretrained``) as a :class:`~emmi_gym.tools.training.evaluate.TrainedAgent` of its
    model; a ``ValueError`` naming ``option``, what is unknown and the choices."""
    from .. import pretrained
    from ..policies import POLICY_NAMES
    from ..training.evaluate import TrainedAgent

    shipped = pretrained.names()
    unknown = sorted(set(names) - set(POLICY_NAMES) - set(shipped))
    if unknown:
        raise ValueError(f"{option}: unknown {unknown}; choose scripted policies from {list(POLICY_NAMES)} or "
                         f"shipped agents from {shipped}")
    return [TrainedAgent(str(pretrained.model_path(name)), name) if name in shipped else name for name in names]
