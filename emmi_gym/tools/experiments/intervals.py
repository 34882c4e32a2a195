"""``emmi_gym.tools.experiments.intervals``: the name :mod:`emmi_gym.tools.evaluation.intervals` had before it moved
under training and the experiments (deprecated; it goes in 0.5.0)."""

from ..._moved import alias_moved
from ..evaluation import intervals

alias_moved(__name__, intervals)
