"""The modules that moved, importable under their old names: each old name is a small module at its old path
that calls :func:`alias_moved`, so nothing is installed in the import system when ``emmi_gym`` is imported and
an old name costs something only when it is imported.

An alias puts the module it stands for in ``sys.modules`` under its own name, which the import system then
returns for it (a module may replace itself there while it is imported): ``emmi_gym.training.train`` *is*
``emmi_gym.tools.training.train``, one module with one set of classes, so what pickles name by their old module
(the policy classes of a model saved before 0.3.0) loads as the current classes.
"""

from __future__ import annotations

import importlib
import pkgutil
import sys
import warnings
from types import ModuleType

from . import MOVED_TO_TOOLS
from .inputs.extras import extra_of

#: Old name -> (its module now, the release the old name goes in; None for a name that stays).
MOVED = {
    **{f"emmi_gym.{name}": (f"emmi_gym.tools.{name}", None if name == "pretrained" else "0.4.0")
       for name in MOVED_TO_TOOLS},
    **{f"emmi_gym.tools.experiments.{name}": (f"emmi_gym.tools.evaluation.{name}", "0.5.0")
       for name in ("comparison", "directions", "episodes", "intervals", "loop_order", "robot_time")},
}


def alias_moved(old: str, module: ModuleType) -> None:
    """Make the module being imported as ``old`` (a key of :data:`MOVED`) the ``module`` it moved to, warning (a
    ``FutureWarning`` naming the new name and the release the old one goes in) unless the old name stays. For a
    package, every module under the new one is imported now and named by its old name too (a module that needs
    an optional extra not installed is left out: importing it by either name says what is missing)."""
    new, gone_in = MOVED[old]
    if module.__name__ != new:
        raise ValueError(f"{old} moved to {new}, not {module.__name__}")
    if gone_in is not None:
        warnings.warn(f"{old} is now {new}; the old name goes in emmi-gym {gone_in}", FutureWarning, stacklevel=3)
    sys.modules[old] = module
    for info in pkgutil.walk_packages(getattr(module, "__path__", []), f"{new}."):
        try:
            # a module that moved again is named by where it is now, without its own alias's warning
            inner = importlib.import_module(MOVED.get(info.name, (info.name,))[0])
        except ModuleNotFoundError as error:
            if extra_of(error.name) is None:
                raise
            continue
        sys.modules[old + info.name[len(new):]] = inner


def moved_names(old: str, module: ModuleType, names: tuple[str, ...], gone_in: str):
    """A module ``__getattr__`` (PEP 562) for the module ``old``, whose ``names`` moved to ``module``: each gives
    ``module``'s, with a ``FutureWarning`` naming where it is now and the release the old name goes in."""

    def __getattr__(name: str):
        if name not in names:
            raise AttributeError(f"module {old!r} has no attribute {name!r}")
        warnings.warn(f"{old}.{name} is now {module.__name__}.{name}; the old name goes in emmi-gym {gone_in}",
                      FutureWarning, stacklevel=2)
        return getattr(module, name)

    return __getattr__
