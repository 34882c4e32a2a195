"""emmi-gym: active-SLAM environments with the EMMI certainty reward (Blanco et al., IROS 2006).

The package has two halves. The environment library (``world``, ``slam``, ``certainty``, ``navigation``,
``env``, ``scoring`` over ``geometry``, ``formats``, ``inputs`` and ``concurrency``) is what
``gymnasium.make`` needs; :mod:`emmi_gym.tools` holds what is built over it: training and evaluating
agents, the experiments, the scripted policies, the shipped agents and the ``emmi-gym`` command. The
library never imports the tools.

Importing the package registers the environments and does nothing else::

    import gymnasium as gym, emmi_gym
    gym.register_envs(emmi_gym)
    env = gym.make("emmi_gym/LoopCorridor-v1")

The shipped agents, ``emmi_gym.pretrained``, are imported on first use.
"""

import importlib

__version__ = "0.3.0"

#: The tools' packages by the names they had before 0.3.0 (``emmi_gym.training.train``, ...), which code and
#: saved models (an SB3 ``model.zip`` names its policy's classes by module) still use: each old name is an alias
#: module at its old path (``emmi_gym/training/``, :mod:`emmi_gym._moved`). ``emmi_gym.pretrained`` stays a public
#: name; the others warn and go in 0.4.0.
MOVED_TO_TOOLS = ("training", "experiments", "policies", "commands", "cli", "pretrained")


def _register() -> None:
    from .env.registration import register_envs

    register_envs()


_register()


def __getattr__(name: str):
    """``emmi_gym.pretrained`` without importing it first (PEP 562): the shipped agents' module, imported on
    first use through its alias (``emmi_gym/pretrained.py``), the one name by which the package's root reaches
    the tools."""
    if name == "pretrained":
        return importlib.import_module(f"{__name__}.pretrained")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
