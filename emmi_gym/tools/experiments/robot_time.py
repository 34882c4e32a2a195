"""``emmi_gym.tools.experiments.robot_time``: the name :mod:`emmi_gym.tools.evaluation.robot_time` had before it moved
under training and the experiments (deprecated; it goes in 0.5.0)."""

from ..._moved import alias_moved
from ..evaluation import robot_time

alias_moved(__name__, robot_time)
