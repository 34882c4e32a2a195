"""``emmi_gym.tools.experiments.comparison``: the name :mod:`emmi_gym.tools.evaluation.comparison` had before it moved
under training and the experiments (deprecated; it goes in 0.5.0)."""

from ..._moved import alias_moved
from ..evaluation import comparison

alias_moved(__name__, comparison)
