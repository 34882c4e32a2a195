"""``emmi_gym.policies``: the name :mod:`emmi_gym.tools.policies` had before 0.3.0, and the modules under it
(deprecated; they go in 0.4.0)."""

from .._moved import alias_moved
from ..tools import policies

alias_moved(__name__, policies)
