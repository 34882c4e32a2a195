"""``emmi_gym.tools.experiments.loop_order``: the name :mod:`emmi_gym.tools.evaluation.loop_order` had before it moved
under training and the experiments (deprecated; it goes in 0.5.0)."""

from ..._moved import alias_moved
from ..evaluation import loop_order

alias_moved(__name__, loop_order)
