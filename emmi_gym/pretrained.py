"""``emmi_gym.pretrained``: the shipped agents, :mod:`emmi_gym.tools.pretrained`, by the name users load them with."""

from ._moved import alias_moved
from .tools import pretrained

alias_moved(__name__, pretrained)
