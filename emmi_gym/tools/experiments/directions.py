"""``emmi_gym.tools.experiments.directions``: the name :mod:`emmi_gym.tools.evaluation.directions` had before it moved
under training and the experiments (deprecated; it goes in 0.5.0)."""

from ..._moved import alias_moved
from ..evaluation import directions

alias_moved(__name__, directions)
