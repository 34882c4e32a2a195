"""``emmi_gym.cli``: the name :mod:`emmi_gym.tools.cli` had before 0.3.0 (deprecated; it goes in 0.4.0)."""

from ._moved import alias_moved
from .tools import cli

alias_moved(__name__, cli)
