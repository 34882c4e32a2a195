"""``emmi_gym.training``: the name :mod:`emmi_gym.tools.training` had before 0.3.0, and the modules under it
(deprecated; they go in 0.4.0)."""

from .._moved import alias_moved
from ..tools import training

alias_moved(__name__, training)
