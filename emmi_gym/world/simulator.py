"""The pymunk simulation: static walls, a round differential-drive robot, laser and odometry.

This is "the real robot": the RBPF never reads it, it only gets odometry and scans.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pymunk

from ..geometry.motion import compose_motion, relative_motion, wrap_angle
from .laser import Laser, LaserConfig
from .odometry import OdometryNoise, noisy_motion
from .spec import ROBOT_RADIUS, WorldSpec


@dataclass(frozen=True)
class RobotConfig:
    """A differential-drive robot with a round body, driven by (v, omega) at a fixed control period."""

    radius: float = ROBOT_RADIUS
    max_speed: float = 0.6          # m/s
    max_turn_rate: float = 1.5      # rad/s
    control_period: float = 0.1     # s: one env step, one odometry reading, one scan
    physics_substeps: int = 5

    def __post_init__(self):
        for name in ("radius", "max_speed", "max_turn_rate", "control_period"):
            if not getattr(self, name) > 0:
                raise ValueError(f"robot {name} must be positive, got {getattr(self, name)!r}")
        if int(self.physics_substeps) != self.physics_substeps or self.physics_substeps < 1:
            raise ValueError(f"robot physics_substeps must be a positive integer, got {self.physics_substeps!r}")


def _clipped(value: float, limit: float) -> float:
    """``value`` clipped to [-limit, limit] as a float (NaN stays NaN, as with ``np.clip``)."""
    return min(max(float(value), -limit), limit)


@dataclass
class StepResult:
    """What one control period produced."""

    true_pose: np.ndarray
    odometry_pose: np.ndarray
    collided: bool


class Simulator:
    """A world in pymunk with one robot. All randomness comes from the ``rng`` handed to ``reset``."""

    def __init__(self, world: WorldSpec, robot: RobotConfig = RobotConfig(),
                 laser: LaserConfig = LaserConfig(), odometry: OdometryNoise = OdometryNoise()):
        self.world, self.robot_config, self.odometry_noise = world, robot, odometry
        self._build_space()
        self.laser = Laser(laser, self.wall_capsules(), world.bounds)
        self.rng = np.random.default_rng(0)
        self.odometry_pose = np.zeros(3)
        self.time = 0.0

    def _build_space(self) -> None:
        """A fresh pymunk space: walls, the robot and its drive joints.

        Built anew at every reset, because pymunk carries solver state (warm-start
        impulses of contacts and joints) from step to step: an old space would make the
        same seed give a slightly different episode.
        """
        robot = self.robot_config
        self.space = pymunk.Space()
        self.space.gravity = (0.0, 0.0)
        # pymunk's defaults suit pixels; in metres allow 1 mm of overlap, not 10 cm
        self.space.collision_slop = 0.001
        for ax, ay, bx, by, thickness in self.world.walls:
            shape = pymunk.Segment(self.space.static_body, (ax, ay), (bx, by), thickness / 2)
            shape.friction, shape.elasticity = 0.0, 0.0
            self.space.add(shape)
        # The robot is a dynamic body that follows a kinematic "control" body through a
        # pivot and a gear joint of bounded force (pymunk's tank example): commands set
        # the control body's velocity, and pymunk's contact solver keeps the robot out of
        # the walls (setting the robot's own velocity each step would override it).
        self.body = pymunk.Body(mass=10.0, moment=pymunk.moment_for_circle(10.0, 0.0, robot.radius))
        self.shape = pymunk.Circle(self.body, robot.radius)
        self.shape.friction, self.shape.elasticity = 0.0, 0.0
        self.control_body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        pivot = pymunk.PivotJoint(self.control_body, self.body, (0, 0), (0, 0))
        pivot.max_bias, pivot.max_force = 0.0, 2000.0
        gear = pymunk.GearJoint(self.control_body, self.body, 0.0, 1.0)
        gear.error_bias, gear.max_bias, gear.max_force = 0.0, 3.0 * robot.max_turn_rate, 2000.0
        self.space.add(self.body, self.shape, self.control_body, pivot, gear)

    def wall_capsules(self) -> np.ndarray:
        """(K, 5) ax, ay, bx, by, radius of the pymunk wall shapes, for the laser kernel."""
        rows = [(*s.a, *s.b, s.radius) for s in self.space.shapes if isinstance(s, pymunk.Segment)]
        return np.array(rows, dtype=np.float64)

    @property
    def true_pose(self) -> np.ndarray:
        x, y = self.body.position
        return np.array([x, y, float(wrap_angle(self.body.angle))])

    def reset(self, rng: np.random.Generator, pose=None) -> None:
        """Put the robot at ``pose`` (default: the world's start), zero odometry there, take ``rng``."""
        self.rng = rng
        pose = self.world.start_pose if pose is None else np.asarray(pose, dtype=np.float64)
        self._build_space()
        for body in (self.body, self.control_body):
            body.position = (float(pose[0]), float(pose[1]))
            body.angle = float(pose[2])
            body.velocity, body.angular_velocity = (0.0, 0.0), 0.0
        self.space.reindex_shapes_for_body(self.body)
        self.odometry_pose = self.true_pose
        self.time = 0.0

    def step(self, v: float, omega: float) -> StepResult:
        """Drive at (v, omega), clipped to the robot's limits, for one control period."""
        cfg = self.robot_config
        v = _clipped(v, cfg.max_speed)
        omega = _clipped(omega, cfg.max_turn_rate)
        body, control = self.body, self.control_body
        before = self.true_pose
        dt = cfg.control_period / cfg.physics_substeps
        collided = False
        for _ in range(cfg.physics_substeps):
            heading = body.angle
            cos, sin = math.cos(heading), math.sin(heading)
            # re-anchor the control body on the robot: the pivot then acts on the commanded
            # velocity only, not on how far the control body got ahead into a wall
            control.position = body.position
            control.velocity = (v * cos, v * sin)
            control.angular_velocity = omega
            self.space.step(dt)
            # a collision is driving into a wall, not resting beside it or driving away (standing
            # still, or once a collision is known, the contacts need not be read)
            if v != 0.0 and not collided:
                collided = any(n.x * v * cos + n.y * v * sin > 1e-6 for n in self._contact_normals())
        after = self.true_pose
        reading = noisy_motion(*relative_motion(before, after), self.odometry_noise, self.rng)
        self.odometry_pose = compose_motion(self.odometry_pose, *reading)
        self.time += cfg.control_period
        return StepResult(after, self.odometry_pose.copy(), collided)

    def _contact_normals(self) -> list:
        """Unit normals from the robot into each wall it touches (pymunk passes the body's shape first)."""
        normals: list = []
        self.body.each_arbiter(lambda arbiter: normals.append(arbiter.normal))
        return normals

    def scan(self) -> np.ndarray:
        """A noisy laser scan from the robot's true pose."""
        return self.laser.scan(self.true_pose, self.rng)
