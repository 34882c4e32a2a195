"""The simulated world ("the real robot"): world files, generator, pymunk physics, laser, odometry, ground truth.

The SLAM layer never imports this package: it sees only odometry and scans.
"""

from .generator import GeneratorConfig, generate_world
from .ground_truth import FREE, OCCUPIED, UNKNOWN, GroundTruth, is_reachable, rasterise
from .laser import Laser, LaserConfig
from .loader import builtin_worlds, load_world, parse_world
from .odometry import OdometryNoise
from .recording import Recording, drive_route, write_carmen
from .simulator import RobotConfig, Simulator, StepResult
from .spec import ROBOT_RADIUS, Place, WorldFileError, WorldSpec

__all__ = [
    "FREE", "OCCUPIED", "ROBOT_RADIUS", "UNKNOWN", "GeneratorConfig", "GroundTruth", "Laser", "LaserConfig",
    "OdometryNoise", "Place", "Recording", "RobotConfig", "Simulator", "StepResult", "WorldFileError",
    "WorldSpec", "builtin_worlds", "drive_route", "generate_world", "is_reachable", "load_world",
    "parse_world", "rasterise", "write_carmen",
]
