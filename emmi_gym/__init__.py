"""emmi-gym: active-SLAM environments with the EMMI certainty reward (Blanco et al., IROS 2006).

The package has two halves. The environment library (``world``, ``slam``, ``certainty``, ``navigation``,
``env``, ``scoring`` over ``geometry``, ``formats``, ``inputs`` and ``concurrency``) is what
``gymnasium.make`` needs; :mod:`emmi_gym.tools` holds what is built over it: training and evaluating
agents, the experiments, the scripted policies, the shipped agents and the ``emmi-gym`` command. The
library never imports the tools.

Importing the package registers the environments and makes the shipped agents available
(``emmi_gym.pretrained``)::

    import gymnasium as gym, emmi_gym
    gym.register_envs(emmi_gym)
    env = gym.make("emmi_gym/LoopCorridor-v1")
"""

import importlib
import importlib.abc
import importlib.util
import sys
import warnings

__version__ = "0.3.0"

#: Modules of the tools half by the names they had before 0.3.0 (``emmi_gym.training.train``, ...), which
#: code and saved models (an SB3 ``model.zip`` names its policy's classes by module) still use.
#: ``emmi_gym.pretrained`` stays a public name; the others warn and go in 0.4.0.
MOVED_TO_TOOLS = ("training", "experiments", "policies", "commands", "cli", "pretrained")


class _ToolsAlias(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Imports ``emmi_gym.<old>[.rest]`` as the module ``emmi_gym.tools.<old>[.rest]`` itself (the same object,
    so classes unpickle and compare equal), warning where the old name is deprecated."""

    def find_spec(self, fullname, path=None, target=None):
        parts = fullname.split(".")
        if len(parts) < 2 or parts[0] != __name__ or parts[1] not in MOVED_TO_TOOLS:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        new = f"{__name__}.tools.{spec.name[len(__name__) + 1:]}"
        if spec.name.count(".") == 1 and spec.name != f"{__name__}.pretrained":
            warnings.warn(f"{spec.name} is now {new}; the old name goes in emmi-gym 0.4.0", FutureWarning,
                          stacklevel=2)
        return importlib.import_module(new)

    def exec_module(self, module):
        """The module was executed under its new name."""


sys.meta_path.insert(0, _ToolsAlias())


def _register() -> None:
    from .env.registration import register_envs

    register_envs()


_register()


def __getattr__(name: str):
    """``emmi_gym.pretrained`` without importing it first (PEP 562): the shipped agents' module, loaded on
    first use (the training code it reaches imports this package back)."""
    if name == "pretrained":
        return importlib.import_module(f"{__name__}.tools.pretrained")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
