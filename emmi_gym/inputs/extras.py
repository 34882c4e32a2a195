"""The optional extras (pyproject's ``[project.optional-dependencies]``) and what to tell a user who lacks one.

The environments, the demo, the A/B experiment and the log replay need only the first install
(``pip install emmi-gym``); training, evaluating and the shipped agents need the ``train`` extra
(PyTorch and Stable-Baselines3), Ray clusters the ``ray`` extra, the pygame window the ``viz`` extra.
A missing one is an :class:`MissingExtraError` (an ``ImportError``, as pandas' optional dependencies
are) naming the extra and the one line that installs it, never the raw ``ModuleNotFoundError`` of a
module the user never asked for.
"""

from __future__ import annotations

#: The top-level modules each extra brings, and what the extra is for.
EXTRAS = {
    "train": (("stable_baselines3", "sb3_contrib", "torch", "tensorboard"), "PyTorch and Stable-Baselines3"),
    "ray": (("ray",), "Ray"),
    "viz": (("pygame", "moviepy"), "pygame and moviepy"),
}

#: PyTorch's CPU build: without this index pip installs the CUDA build (several GB of ``nvidia-*`` packages).
CPU_TORCH = "pip install torch --index-url https://download.pytorch.org/whl/cpu"


class MissingExtraError(ImportError):
    """A feature needs an optional extra that is not installed; the message names it and its install line."""


def extra_of(module: str | None) -> str | None:
    """The extra that brings the module ``module`` (or a submodule of it), or ``None``."""
    top = (module or "").partition(".")[0]
    return next((extra for extra, (modules, _) in EXTRAS.items() if top in modules), None)


def install_command(extra: str) -> str:
    """The line that installs ``extra`` beside the package (the CPU build of PyTorch first for ``train``)."""
    command = f'pip install "emmi-gym[{extra}]"'
    return f"{CPU_TORCH} && {command}" if extra == "train" else command


def missing_extra(error: ModuleNotFoundError, use: str) -> MissingExtraError | None:
    """``error`` said again for a user: ``use`` (e.g. "evaluate") needs the extra that brings the missing
    module, and the line that installs it; ``None`` when no extra brings that module (a broken install)."""
    extra = extra_of(error.name)
    if extra is None:
        return None
    what = EXTRAS[extra][1]
    return MissingExtraError(f"{use} needs the '{extra}' extra ({what}; no module named {error.name!r} here): "
                             f"{install_command(extra)}  (in a clone: pip install -e \".[{extra}]\")")
