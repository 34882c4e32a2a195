"""Grid SLAM: a Rao-Blackwellized particle filter (replayed on CARMEN logs by
:mod:`emmi_gym.tools.experiments.replay`).

Imports nothing from :mod:`emmi_gym.world`: the filter sees odometry and ranges only.
"""

from .config import RBPFConfig
from .occupancy import ParticleMaps
from .rbpf import RBPF, UpdateMetrics
from .sensor_model import CellCodes

__all__ = ["RBPF", "CellCodes", "ParticleMaps", "RBPFConfig", "UpdateMetrics"]
